#include "server/security/authorization.h"

#include "absl/strings/ascii.h"
#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/strip.h"

namespace shapeid {
namespace {

constexpr absl::string_view kOpenServicePrefix = "/grpc.health.v1.Health/";

// "Describe" from "/shapeid.v1.ShapeId/Describe", for messages.
absl::string_view ShortName(absl::string_view full_method) {
  const size_t slash = full_method.rfind('/');
  return slash == absl::string_view::npos ? full_method : full_method.substr(slash + 1);
}

}  // namespace

std::optional<Scope> RequiredScope(absl::string_view full_method) {
  if (absl::StartsWith(full_method, kOpenServicePrefix)) return std::nullopt;
  for (const RpcMethod& method : kRpcMethods) {
    if (method.full_name == full_method) return method.scope;
  }
  return Scope::kAdmin;
}

absl::Status Authorize(const ApiKeyStore& keys, absl::string_view full_method,
                       std::optional<absl::string_view> authorization, const ApiKeyEntry** caller) {
  if (keys.empty()) return absl::OkStatus();
  const std::optional<Scope> needed = RequiredScope(full_method);
  if (!needed.has_value()) return absl::OkStatus();
  if (!authorization.has_value()) {
    return absl::UnauthenticatedError(
        "missing API key: this server needs one, sent as metadata 'authorization: Bearer KEY'");
  }
  // "Bearer" is case-insensitive (RFC 6750 follows RFC 7235's auth-scheme).
  absl::string_view value = absl::StripAsciiWhitespace(*authorization);
  constexpr absl::string_view kScheme = "bearer ";
  if (value.size() <= kScheme.size() ||
      !absl::EqualsIgnoreCase(value.substr(0, kScheme.size()), kScheme)) {
    return absl::UnauthenticatedError(
        "unknown API key: the authorization metadata must be 'Bearer KEY'");
  }
  const absl::string_view key = absl::StripLeadingAsciiWhitespace(value.substr(kScheme.size()));
  const ApiKeyEntry* entry = keys.Find(key);
  if (entry == nullptr) return absl::UnauthenticatedError("unknown API key");
  if (caller != nullptr) *caller = entry;
  if (!ScopeAllows(entry->scope, *needed)) {
    return absl::PermissionDeniedError(absl::StrCat(
        "key '", entry->name, "' lacks scope ", ScopeName(*needed), " (", ShortName(full_method),
        " needs ", ScopeName(*needed), "; the key has ", ScopeName(entry->scope), ")"));
  }
  return absl::OkStatus();
}

}  // namespace shapeid
