#ifndef SHAPEID_CORE_IO_GZIP_H_
#define SHAPEID_CORE_IO_GZIP_H_

#include <string>

#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"

namespace shapeid {

// True when `contents` starts with the gzip magic bytes and deflate method (1f 8b 08).
bool IsGzip(absl::string_view contents);

// The decompressed bytes of a gzip stream (RFC 1952; several concatenated members are read as
// one, as gunzip does; zero padding after the last is ignored). Memory grows with the output
// actually produced. InvalidArgument naming `name` (and the byte offset) for a corrupt or
// truncated stream, other data after it, or output past `max_bytes` (a decompression bomb).
absl::StatusOr<std::string> Gunzip(absl::string_view contents, absl::string_view name,
                                   size_t max_bytes);

// Inflates a raw deflate stream (RFC 1951, no header), as zip archives store members, whose
// uncompressed size is stated to be `size`; memory grows with the output actually produced,
// never with the stated size. InvalidArgument naming `name` when the output is not `size` bytes.
absl::StatusOr<std::string> InflateRaw(absl::string_view contents, size_t size,
                                       absl::string_view name);

}  // namespace shapeid

#endif  // SHAPEID_CORE_IO_GZIP_H_
