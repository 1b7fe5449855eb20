#ifndef SHAPEID_CORE_IO_LAS_READER_H_
#define SHAPEID_CORE_IO_LAS_READER_H_

#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "core/io/read_options.h"

namespace shapeid {

// Parses an uncompressed ASPRS LAS file, versions 1.0 to 1.4, point data record formats 0 to
// 10, held in memory; `name` is the file name that every error message starts with. Only X, Y
// and Z are read (the int32s that open every record), as X * scale + offset in double, so that
// georeferenced coordinates keep their precision until ReadOptions::recenter shifts them.
// Records longer than their format's size (extra bytes) are skipped over; VLRs, EVLRs and
// waveform data are ignored. The point count is the header's legacy 32-bit one, or for LAS 1.4
// the 64-bit one when the legacy count is 0 or the point format is 6 or above. A file of 0
// points gives an empty cloud. Errors name the byte offset of the header field at fault:
//  - InvalidArgument: no "LASF" signature, a file shorter than its header, a header size below
//    227 bytes (375 for LAS 1.4), an offset to point data inside the header or beyond the file,
//    a record length below its format's size, a zero or non-finite scale factor, a non-finite
//    offset, a scale and offset that overflow a double, and point data shorter than count *
//    record length (expected and actual bytes in the message);
//  - Unimplemented: LAS versions other than 1.0-1.4, point formats above 10, and LAZ (the
//    compressor's bits 6 or 7 set in the point format), with the command that decompresses it.
absl::StatusOr<ReadResult> ParseLas(absl::string_view contents, absl::string_view name,
                                    const ReadOptions& options = {});

}  // namespace shapeid

#endif  // SHAPEID_CORE_IO_LAS_READER_H_
