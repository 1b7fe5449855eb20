#ifndef SHAPEID_CORE_IO_PCD_READER_H_
#define SHAPEID_CORE_IO_PCD_READER_H_

#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "core/io/read_options.h"

namespace shapeid {

// Parses a PCD v0.7 file (Point Cloud Library format) held in memory; `name` is the file name
// that every error message starts with. Reads the x, y and z fields, which must be F4 or F8
// with COUNT 1, and skips every other field (rgb, normals, intensity, `_` padding) whatever
// its SIZE, TYPE and COUNT. DATA ascii, binary and binary_compressed (LZF, through Debian's
// liblzf; the decompressed data is organized by field, as PCL writes it). Binary data is host
// byte order (little-endian in practice), as PCL writes it. Older headers without COUNT (v0.6) or
// HEIGHT and POINTS are accepted. Errors name the header line or the byte offset of the problem:
//  - InvalidArgument: a malformed header (unknown keyword, inconsistent FIELDS / SIZE / TYPE /
//    COUNT, no x, y or z field, POINTS != WIDTH * HEIGHT, an unknown DATA kind), ascii data
//    with a wrong number of values or a non-numeric coordinate, binary data shorter than the
//    header promises (expected and actual bytes in the message), compressed data whose sizes
//    disagree with the header or whose LZF block is truncated or corrupt;
//  - Unimplemented: coordinates that are not floating point.
absl::StatusOr<ReadResult> ParsePcd(absl::string_view contents, absl::string_view name,
                                    const ReadOptions& options = {});

}  // namespace shapeid

#endif  // SHAPEID_CORE_IO_PCD_READER_H_
