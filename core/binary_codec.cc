#include "core/binary_codec.h"

#include <zlib.h>

#include <algorithm>

#include "absl/strings/str_cat.h"

namespace shapeid {

uint32_t Crc32Of(absl::string_view bytes) {
  uLong crc = crc32(0, nullptr, 0);
  while (!bytes.empty()) {  // zlib takes a uInt length
    const uInt chunk = static_cast<uInt>(std::min<size_t>(bytes.size(), 1u << 30));
    crc = crc32(crc, reinterpret_cast<const Bytef*>(bytes.data()), chunk);
    bytes.remove_prefix(chunk);
  }
  return static_cast<uint32_t>(crc);
}

absl::Status OpenVersionedFile(absl::string_view bytes, absl::string_view magic, uint32_t version,
                               absl::string_view what, ByteReader& reader) {
  const auto bad = [what](absl::string_view why) {
    return absl::DataLossError(absl::StrCat("not a shapeid ", what, ": ", why));
  };
  if (bytes.substr(0, magic.size()) != magic) return bad("no magic");
  if (!reader.Open(bytes)) return bad("checksum mismatch (a truncated or altered file)");
  absl::string_view skipped;
  reader.Bytes(magic.size(), skipped);
  uint32_t found = 0;
  if (!reader.U32(found) || found != version) {
    return bad(absl::StrCat("format version ", found, ", this build reads ", version));
  }
  return absl::OkStatus();
}

}  // namespace shapeid
