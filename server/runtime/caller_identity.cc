#include "server/runtime/caller_identity.h"

#include "absl/strings/str_cat.h"
#include "core/request_id.h"
#include "server/runtime/stream_limiter.h"

namespace shapeid {
namespace {

absl::string_view View(const grpc::string_ref& ref) { return {ref.data(), ref.size()}; }

absl::Status MalformedCallerId() {
  return absl::InvalidArgumentError(absl::StrCat(
      "the '", kCallerIdMetadata, "' metadata must be 1-", kMaxCallerIdChars,
      " characters of letters, digits and . _ : - (it names one robot of a fleet that shares a "
      "host)"));
}

}  // namespace

absl::StatusOr<std::string> CallerOf(absl::string_view key_name, absl::string_view certificate_name,
                                     absl::string_view peer, absl::string_view caller_id) {
  if (!caller_id.empty() && !IsValidCallerId(caller_id)) return MalformedCallerId();
  if (!key_name.empty()) return absl::StrCat("key:", key_name);
  if (!certificate_name.empty()) return absl::StrCat("cert:", certificate_name);
  std::string host = ClientOfPeer(peer);
  if (!caller_id.empty()) absl::StrAppend(&host, "/", caller_id);
  return host;
}

absl::StatusOr<std::string> CallerOf(const grpc::ServerContextBase& context,
                                     absl::string_view key_name) {
  absl::string_view caller_id;
  const auto& metadata = context.client_metadata();
  if (const auto it =
          metadata.find(grpc::string_ref(kCallerIdMetadata.data(), kCallerIdMetadata.size()));
      it != metadata.end()) {
    caller_id = View(it->second);
    if (caller_id.empty()) return MalformedCallerId();
  }
  std::string certificate_name;
  if (const std::shared_ptr<const grpc::AuthContext> auth = context.auth_context();
      auth != nullptr && auth->IsPeerAuthenticated()) {
    for (const grpc::string_ref& name : auth->FindPropertyValues("x509_common_name")) {
      certificate_name = std::string(View(name));
      break;
    }
  }
  return CallerOf(key_name, certificate_name, context.peer(), caller_id);
}

}  // namespace shapeid
