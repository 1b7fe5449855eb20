#ifndef SHAPEID_CORE_REQUEST_ID_H_
#define SHAPEID_CORE_REQUEST_ID_H_

// The rules for request ids (the "x-request-id" metadata, docs/operations.md) and caller ids,
// in one place for the server, which reads them, and the clients, which send them. Characters that
// read the same in any log, URL or shell, and no space, quote or control character.

#include "absl/strings/ascii.h"
#include "absl/strings/string_view.h"

namespace shapeid {

inline constexpr size_t kMaxRequestIdChars = 128;
inline constexpr char kRequestIdPunctuation[] = "._:/+=-";

// One character of a request id.
inline bool IsRequestIdChar(char c) {
  return absl::ascii_isalnum(static_cast<unsigned char>(c)) ||
         absl::string_view(kRequestIdPunctuation).find(c) != absl::string_view::npos;
}

// 1 to 128 of A-Z a-z 0-9 . _ : / + = -
inline bool IsValidRequestId(absl::string_view id) {
  if (id.empty() || id.size() > kMaxRequestIdChars) return false;
  for (const char c : id) {
    if (!IsRequestIdChar(c)) return false;
  }
  return true;
}

// The caller id a client may send as the "shapeid-caller-id" metadata, so that the robots of a
// fleet that share a host (and no key) are callers of their own (server/runtime/caller_identity.h):
// 1 to 64 of A-Z a-z 0-9 . _ : - (no "/", which the server puts between host and id).
inline constexpr absl::string_view kCallerIdMetadata = "shapeid-caller-id";
inline constexpr size_t kMaxCallerIdChars = 64;

inline bool IsValidCallerId(absl::string_view id) {
  if (id.empty() || id.size() > kMaxCallerIdChars) return false;
  for (const char c : id) {
    if (!absl::ascii_isalnum(static_cast<unsigned char>(c)) && c != '.' && c != '_' && c != ':' &&
        c != '-') {
      return false;
    }
  }
  return true;
}

}  // namespace shapeid

#endif  // SHAPEID_CORE_REQUEST_ID_H_
