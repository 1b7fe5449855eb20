#ifndef SHAPEID_CORE_REQUEST_ID_H_
#define SHAPEID_CORE_REQUEST_ID_H_

// The rule for request ids (the "x-request-id" metadata, docs/operations.md), in one place for
// the server, which logs and echoes them, and the client, which sends them. Characters that
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

}  // namespace shapeid

#endif  // SHAPEID_CORE_REQUEST_ID_H_
