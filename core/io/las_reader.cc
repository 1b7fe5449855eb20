#include "core/io/las_reader.h"

#include <cmath>
#include <cstdint>
#include <cstring>
#include <string>
#include <utility>

#include "absl/status/status.h"
#include "absl/strings/escaping.h"
#include "absl/strings/str_cat.h"
#include "core/io/cloud_accumulator.h"

// LAS is little-endian and is loaded with memcpy in host order.
#if defined(__BYTE_ORDER__) && __BYTE_ORDER__ != __ORDER_LITTLE_ENDIAN__
#error "core/io/las_reader.cc assumes a little-endian host"
#endif

namespace shapeid {
namespace {

// Byte offsets of the public header block fields read (ASPRS LAS 1.4 R15, table 3).
constexpr size_t kVersionMajorAt = 24;
constexpr size_t kVersionMinorAt = 25;
constexpr size_t kHeaderSizeAt = 94;
constexpr size_t kPointDataOffsetAt = 96;
constexpr size_t kPointFormatAt = 104;
constexpr size_t kRecordLengthAt = 105;
constexpr size_t kLegacyCountAt = 107;
constexpr size_t kScaleAt = 131;
constexpr size_t kOffsetAt = 155;
constexpr size_t kCount64At = 247;

// Header sizes of LAS 1.0-1.3 (1.3 adds 8 bytes this reader does not need) and of LAS 1.4.
constexpr size_t kLegacyHeaderSize = 227;
constexpr size_t kLas14HeaderSize = 375;

// The size of each point data record format, 0 to 10.
constexpr uint16_t kMinRecordLength[11] = {20, 28, 26, 34, 57, 63, 30, 36, 38, 59, 67};

constexpr const char kDecompress[] =
    "decompress it first, e.g. `laszip -i in.laz -o out.las` (LAStools) or `pdal translate "
    "in.laz out.las` (PDAL)";

template <typename T>
T Load(const char* p) {
  T value;
  std::memcpy(&value, p, sizeof(T));
  return value;
}

absl::Status Error(absl::StatusCode code, absl::string_view name, uint64_t at,
                   absl::string_view message) {
  return absl::Status(code, absl::StrCat(name, ": byte offset ", at, ": ", message));
}

absl::Status Invalid(absl::string_view name, uint64_t at, absl::string_view message) {
  return Error(absl::StatusCode::kInvalidArgument, name, at, message);
}

struct Header {
  uint64_t data_offset = 0;
  uint64_t count = 0;
  uint64_t count_at = 0;  // where the count used was read, for messages
  uint16_t record_length = 0;
  double scale[3] = {1, 1, 1};
  double offset[3] = {0, 0, 0};
};

absl::Status ParseHeader(absl::string_view contents, absl::string_view name, Header* h) {
  const char* data = contents.data();
  if (contents.size() < 4 || std::memcmp(data, "LASF", 4) != 0) {
    return Invalid(name, 0,
                   absl::StrCat("not a LAS file: expected the signature \"LASF\", found \"",
                                absl::CHexEscape(contents.substr(0, 4)), "\""));
  }
  if (contents.size() < kLegacyHeaderSize) {
    return Invalid(name, contents.size(),
                   absl::StrCat("the file ends after ", contents.size(), " bytes, inside the ",
                                kLegacyHeaderSize, "-byte LAS header"));
  }

  const uint8_t major = Load<uint8_t>(data + kVersionMajorAt);
  const uint8_t minor = Load<uint8_t>(data + kVersionMinorAt);
  if (major != 1 || minor > 4) {
    return Error(absl::StatusCode::kUnimplemented, name, kVersionMajorAt,
                 absl::StrCat("LAS version ", int{major}, ".", int{minor},
                              " is not supported; shapeid reads LAS 1.0 to 1.4"));
  }

  const uint8_t format = Load<uint8_t>(data + kPointFormatAt);
  if ((format & 0xC0) != 0) {
    return Error(absl::StatusCode::kUnimplemented, name, kPointFormatAt,
                 absl::StrCat("point data format byte 0x", absl::Hex(format), " has bit ",
                              (format & 0x80) != 0 ? 7 : 6,
                              " set: the points are LAZ-compressed, which shapeid does not read; ",
                              kDecompress));
  }
  if (format > 10) {
    return Error(absl::StatusCode::kUnimplemented, name, kPointFormatAt,
                 absl::StrCat("point data format ", int{format},
                              " is not supported; LAS 1.4 defines formats 0 to 10"));
  }

  const uint16_t header_size = Load<uint16_t>(data + kHeaderSizeAt);
  const size_t min_header_size = minor >= 4 ? kLas14HeaderSize : kLegacyHeaderSize;
  if (header_size < min_header_size) {
    return Invalid(name, kHeaderSizeAt,
                   absl::StrCat("header size ", header_size, " is below the ", min_header_size,
                                " bytes of a LAS 1.", int{minor}, " header"));
  }
  if (header_size > contents.size()) {
    return Invalid(name, kHeaderSizeAt,
                   absl::StrCat("header size ", header_size, " exceeds the file's ",
                                contents.size(), " bytes"));
  }

  h->data_offset = Load<uint32_t>(data + kPointDataOffsetAt);
  if (h->data_offset < header_size) {
    return Invalid(name, kPointDataOffsetAt,
                   absl::StrCat("offset to point data ", h->data_offset, " lies inside the ",
                                header_size, "-byte header"));
  }
  if (h->data_offset > contents.size()) {
    return Invalid(name, kPointDataOffsetAt,
                   absl::StrCat("offset to point data ", h->data_offset,
                                " is beyond the end of the file (", contents.size(), " bytes)"));
  }

  h->record_length = Load<uint16_t>(data + kRecordLengthAt);
  if (h->record_length < kMinRecordLength[format]) {
    return Invalid(
        name, kRecordLengthAt,
        absl::StrCat("point record length ", h->record_length, " is below the ",
                     kMinRecordLength[format], " bytes of point data format ", int{format}));
  }

  for (int a = 0; a < 3; ++a) {
    const absl::string_view axis(&"xyz"[a], 1);
    const size_t scale_at = kScaleAt + 8 * a;
    const size_t offset_at = kOffsetAt + 8 * a;
    h->scale[a] = Load<double>(data + scale_at);
    h->offset[a] = Load<double>(data + offset_at);
    if (!std::isfinite(h->scale[a]) || h->scale[a] == 0) {
      return Invalid(
          name, scale_at,
          absl::StrCat(axis, " scale factor is ", h->scale[a], "; it must be finite and non-zero"));
    }
    if (!std::isfinite(h->offset[a])) {
      return Invalid(name, offset_at,
                     absl::StrCat(axis, " offset is ", h->offset[a], "; it must be finite"));
    }
    // The largest |int32| is 2^31: past this bound some record could become infinite.
    if (!std::isfinite(std::fabs(h->scale[a]) * 2147483648.0 + std::fabs(h->offset[a]))) {
      return Invalid(name, scale_at,
                     absl::StrCat(axis, " scale factor ", h->scale[a], " and offset ", h->offset[a],
                                  " take coordinates beyond the range of a double"));
    }
  }

  h->count = Load<uint32_t>(data + kLegacyCountAt);
  h->count_at = kLegacyCountAt;
  if (minor >= 4 && (h->count == 0 || format >= 6)) {
    h->count = Load<uint64_t>(data + kCount64At);
    h->count_at = kCount64At;
  }
  return absl::OkStatus();
}

}  // namespace

absl::StatusOr<ReadResult> ParseLas(absl::string_view contents, absl::string_view name,
                                    const ReadOptions& options) {
  Header h;
  if (absl::Status s = ParseHeader(contents, name, &h); !s.ok()) return s;

  // Checked by division, so that no count (up to 2^64 - 1) can overflow or be allocated for.
  const uint64_t available = contents.size() - h.data_offset;
  if (h.count > available / h.record_length) {
    uint64_t expected = 0;
    const bool overflow = __builtin_mul_overflow(h.count, uint64_t{h.record_length}, &expected);
    return Invalid(
        name, h.data_offset,
        absl::StrCat("point data is truncated: expected ",
                     overflow ? std::string("over 2^64") : absl::StrCat(expected), " bytes (",
                     h.count, " points of ", h.record_length, " bytes, count at byte offset ",
                     h.count_at, "), found ", available));
  }

  const double sx = h.scale[0], sy = h.scale[1], sz = h.scale[2];
  const double ox = h.offset[0], oy = h.offset[1], oz = h.offset[2];
  const char* data = contents.data() + h.data_offset;
  const uint64_t record = h.record_length, first = h.data_offset;
  return ReadPointsTwice(
      h.count,
      [&](size_t i, double* p) {
        int32_t xyz[3];
        std::memcpy(xyz, data + i * record, sizeof(xyz));
        p[0] = xyz[0] * sx + ox;
        p[1] = xyz[1] * sy + oy;
        p[2] = xyz[2] * sz + oz;
      },
      [&](size_t i) { return first + i * record; }, name, "byte offset", options);
}

}  // namespace shapeid
