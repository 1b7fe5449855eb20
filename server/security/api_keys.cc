#include "server/security/api_keys.h"

#include <openssl/crypto.h>
#include <openssl/rand.h>
#include <openssl/sha.h>

#include <set>
#include <utility>

#include "absl/strings/ascii.h"
#include "absl/strings/escaping.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_split.h"
#include "core/enum_names.h"

namespace shapeid {
namespace {

constexpr EnumNames<Scope, 3> kScopeNames = {{
    {Scope::kRead, "read"},
    {Scope::kWrite, "write"},
    {Scope::kAdmin, "admin"},
}};

bool ValidKeyName(absl::string_view name) {
  if (name.empty() || name.size() > 64) return false;
  for (char c : name) {
    if (!absl::ascii_isalnum(static_cast<unsigned char>(c)) && c != '_' && c != '.' && c != '@' &&
        c != '-') {
      return false;
    }
  }
  return true;
}

// The digest in `hex`, or false. Does not say what was wrong with it: the caller's message
// must not quote a digest.
bool ParseDigest(absl::string_view hex, Sha256Digest* digest) {
  if (hex.size() != 2 * kSha256Bytes) return false;
  for (char c : hex) {
    if (!absl::ascii_isxdigit(static_cast<unsigned char>(c))) return false;
  }
  const std::string bytes = absl::HexStringToBytes(hex);
  std::copy(bytes.begin(), bytes.end(), digest->begin());
  return true;
}

}  // namespace

absl::string_view ScopeName(Scope scope) { return NameOf(kScopeNames, scope, "?"); }

absl::StatusOr<Scope> ParseScope(absl::string_view text) {
  for (const EnumName<Scope>& scope : kScopeNames) {
    if (text == scope.name) return scope.value;  // exact: a key file is not case-folded
  }
  return absl::InvalidArgumentError(
      absl::StrCat("unknown scope '", text, "'; use one of ", NameList(kScopeNames)));
}

Sha256Digest Sha256(absl::string_view data) {
  Sha256Digest digest;
  SHA256(reinterpret_cast<const unsigned char*>(data.data()), data.size(), digest.data());
  return digest;
}

std::string Sha256Hex(absl::string_view data) {
  const Sha256Digest digest = Sha256(data);
  return absl::BytesToHexString(
      absl::string_view(reinterpret_cast<const char*>(digest.data()), digest.size()));
}

absl::StatusOr<std::vector<ApiKeyEntry>> ParseApiKeys(absl::string_view text,
                                                      absl::string_view source) {
  std::vector<ApiKeyEntry> keys;
  int line_number = 0;
  for (absl::string_view line : absl::StrSplit(text, '\n')) {
    ++line_number;
    if (const size_t hash = line.find('#'); hash != absl::string_view::npos) {
      line = line.substr(0, hash);
    }
    const std::vector<absl::string_view> entries = absl::StrSplit(line, ';');
    for (size_t e = 0; e < entries.size(); ++e) {
      const std::vector<absl::string_view> fields =
          absl::StrSplit(entries[e], absl::ByAnyChar(" \t\r"), absl::SkipEmpty());
      if (fields.empty()) continue;
      const std::string where = entries.size() > 1
                                    ? absl::StrCat(source, " line ", line_number, " entry ", e + 1)
                                    : absl::StrCat(source, " line ", line_number);
      if (fields.size() != 3) {
        return absl::InvalidArgumentError(
            absl::StrCat(where, ": expected NAME SCOPE SHA256-HEX, found ", fields.size(),
                         fields.size() == 1 ? " field" : " fields"));
      }
      ApiKeyEntry entry;
      if (!ValidKeyName(fields[0])) {
        return absl::InvalidArgumentError(
            absl::StrCat(where, ": the key name must be 1 to 64 of A-Z a-z 0-9 _ . @ -"));
      }
      entry.name = std::string(fields[0]);
      absl::StatusOr<Scope> scope = ParseScope(fields[1]);
      if (!scope.ok()) {
        return absl::InvalidArgumentError(absl::StrCat(where, ": ", scope.status().message()));
      }
      entry.scope = *scope;
      if (!ParseDigest(fields[2], &entry.digest)) {
        return absl::InvalidArgumentError(absl::StrCat(
            where, ": key '", entry.name,
            "' needs the SHA-256 of the key, 64 hex digits (a key itself does not go here: "
            "see shapeid-server --new_api_key)"));
      }
      keys.push_back(std::move(entry));
    }
  }
  // Duplicates are checked here too, so that the message can say where.
  if (absl::StatusOr<ApiKeyStore> store = ApiKeyStore::Create(keys); !store.ok()) {
    return absl::InvalidArgumentError(absl::StrCat(source, ": ", store.status().message()));
  }
  return keys;
}

absl::StatusOr<std::string> NewApiKey() {
  unsigned char random[32];
  if (RAND_bytes(random, sizeof(random)) != 1) {
    return absl::InternalError("OpenSSL's random generator failed");
  }
  std::string key = absl::StrCat("shapeid_", absl::BytesToHexString(absl::string_view(
                                                 reinterpret_cast<const char*>(random), 32)));
  OPENSSL_cleanse(random, sizeof(random));
  return key;
}

absl::StatusOr<ApiKeyStore> ApiKeyStore::Create(std::vector<ApiKeyEntry> keys) {
  std::set<std::string> names;
  std::set<Sha256Digest> digests;
  for (const ApiKeyEntry& key : keys) {
    if (!names.insert(key.name).second) {
      return absl::InvalidArgumentError(absl::StrCat("two keys are named '", key.name, "'"));
    }
    if (!digests.insert(key.digest).second) {
      return absl::InvalidArgumentError(
          absl::StrCat("key '", key.name, "' has the same digest as another key"));
    }
  }
  ApiKeyStore store;
  store.keys_ = std::move(keys);
  return store;
}

size_t ApiKeyStore::CountWithScope(Scope scope) const {
  size_t n = 0;
  for (const ApiKeyEntry& key : keys_) n += key.scope == scope ? 1 : 0;
  return n;
}

const ApiKeyEntry* ApiKeyStore::Find(absl::string_view key) const {
  const Sha256Digest digest = Sha256(key);
  const ApiKeyEntry* found = nullptr;
  for (const ApiKeyEntry& entry : keys_) {  // no early exit
    if (CRYPTO_memcmp(entry.digest.data(), digest.data(), kSha256Bytes) == 0) found = &entry;
  }
  return found;
}

}  // namespace shapeid
