#ifndef SHAPEID_SERVER_SECURITY_API_KEYS_H_
#define SHAPEID_SERVER_SECURITY_API_KEYS_H_

// API keys and their scopes (docs/security.md). gRPC-free.
//
// The server never holds a key, only its SHA-256: a keys file that leaks does not let anyone
// in, since keys are random 256-bit strings (NewApiKey), far beyond any search of SHA-256
// preimages. Nothing here ever puts a key or a digest in a message.

#include <array>
#include <cstddef>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"

namespace shapeid {

// What a key may do. Each scope implies the ones before it: admin > write > read.
enum class Scope { kRead = 0, kWrite = 1, kAdmin = 2 };

absl::string_view ScopeName(Scope scope);  // "read", "write", "admin"
// InvalidArgument unless `text` is read, write or admin.
absl::StatusOr<Scope> ParseScope(absl::string_view text);
// True when a key of scope `held` may call a method that needs `needed`.
inline bool ScopeAllows(Scope held, Scope needed) {
  return static_cast<int>(held) >= static_cast<int>(needed);
}

inline constexpr size_t kSha256Bytes = 32;
using Sha256Digest = std::array<unsigned char, kSha256Bytes>;

Sha256Digest Sha256(absl::string_view data);
std::string Sha256Hex(absl::string_view data);  // 64 lowercase hex digits

// One line of a keys file.
struct ApiKeyEntry {
  std::string name;  // who holds the key; appears in errors and logs instead of the key
  Scope scope = Scope::kRead;
  Sha256Digest digest{};
};

// Parses the text of a keys file: one key per line, "NAME SCOPE SHA256-HEX" separated by
// spaces or tabs; '#' starts a comment; blank lines are skipped; ';' also ends an entry, so
// that an environment variable can hold several on one line. NAME is 1-64 of
// [A-Za-z0-9_.@-]. `source` names the text in errors ("keys.txt line 3: ..."), which never
// quote a digest. InvalidArgument on any malformed entry and on a duplicate name or digest.
absl::StatusOr<std::vector<ApiKeyEntry>> ParseApiKeys(absl::string_view text,
                                                      absl::string_view source);

// A fresh key: "shapeid_" and 64 hex digits of OpenSSL's RAND_bytes (256 bits).
// Internal if the random generator fails.
absl::StatusOr<std::string> NewApiKey();

// Keys shorter than this are refused by the helpers that hash a key (shapeid-server
// --hash_api_key): short keys could be found by trying.
inline constexpr size_t kMinApiKeyChars = 20;

// The keys a server accepts. Immutable; thread-safe.
class ApiKeyStore {
 public:
  ApiKeyStore() = default;  // empty: keys are off
  // InvalidArgument on a duplicate name or digest.
  static absl::StatusOr<ApiKeyStore> Create(std::vector<ApiKeyEntry> keys);

  bool empty() const { return keys_.empty(); }
  size_t size() const { return keys_.size(); }
  size_t CountWithScope(Scope scope) const;

  // The entry whose digest is SHA-256(`key`), or null. Every stored digest is compared, with
  // CRYPTO_memcmp, so the time taken says nothing about which entry matched or how closely.
  const ApiKeyEntry* Find(absl::string_view key) const;

 private:
  std::vector<ApiKeyEntry> keys_;
};

}  // namespace shapeid

#endif  // SHAPEID_SERVER_SECURITY_API_KEYS_H_
