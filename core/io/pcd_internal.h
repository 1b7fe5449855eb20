#ifndef SHAPEID_CORE_IO_PCD_INTERNAL_H_
#define SHAPEID_CORE_IO_PCD_INTERNAL_H_

// Internal to core/io: what pcd_reader.cc and pcd_compressed.cc share.

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <vector>

#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "core/io/read_options.h"

namespace shapeid {
namespace pcd_internal {

enum class DataKind { kAscii, kBinary, kBinaryCompressed };

// The header as written; checked for consistency by MakeLayout().
struct Header {
  std::vector<absl::string_view> fields;
  std::vector<uint64_t> sizes;
  std::vector<char> types;
  std::vector<uint64_t> counts;
  uint64_t width = 0;
  uint64_t height = 1;
  uint64_t points = 0;
  DataKind data = DataKind::kBinary;
  size_t data_offset = 0;  // first byte after the DATA line
  // The line of each keyword; 0 when absent.
  uint64_t version_line = 0, fields_line = 0, size_line = 0, type_line = 0, count_line = 0,
           width_line = 0, height_line = 0, viewpoint_line = 0, points_line = 0, data_line = 0;
};

// Where x, y and z sit in one point; derived from a consistent header.
struct Layout {
  uint64_t point_bytes = 0;   // binary: bytes per point
  uint64_t point_values = 0;  // ascii: values per point
  uint64_t byte_offset[3] = {0, 0, 0};
  uint64_t value_index[3] = {0, 0, 0};
  bool is_double[3] = {false, false, false};
};

inline bool MulOverflows(uint64_t a, uint64_t b, uint64_t* out) {
  return __builtin_mul_overflow(a, b, out);
}

inline double LoadCoordinate(const char* p, bool is_double) {
  if (is_double) {
    double d;
    std::memcpy(&d, p, sizeof d);
    return d;
  }
  float f;
  std::memcpy(&f, p, sizeof f);
  return f;
}

// Decodes DATA binary_compressed (pcd_compressed.cc, through liblzf).
absl::StatusOr<ReadResult> DecodeCompressed(absl::string_view contents, absl::string_view name,
                                            const Header& h, const Layout& layout,
                                            const ReadOptions& options);

}  // namespace pcd_internal
}  // namespace shapeid

#endif  // SHAPEID_CORE_IO_PCD_INTERNAL_H_
