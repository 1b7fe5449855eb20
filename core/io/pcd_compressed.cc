// PCD DATA binary_compressed, decompressed with Debian's liblzf.
#include <lzf.h>

#include <cstdint>
#include <cstring>
#include <memory>
#include <string>
#include <utility>

#include "absl/status/status.h"
#include "absl/strings/str_cat.h"
#include "core/io/cloud_accumulator.h"
#include "core/io/pcd_internal.h"

namespace shapeid {
namespace pcd_internal {
namespace {

uint32_t LoadU32(const char* p) {
  uint32_t v;
  std::memcpy(&v, p, sizeof v);
  return v;
}

}  // namespace

// DATA binary_compressed, as PCL writes it: uint32 compressed size, uint32 uncompressed size,
// then one LZF block whose contents are organized by field (all values of the first field,
// then all of the second, ...), each field `SIZE * COUNT * points` bytes.
absl::StatusOr<ReadResult> DecodeCompressed(absl::string_view contents, absl::string_view name,
                                            const Header& h, const Layout& layout,
                                            const ReadOptions& options) {
  const uint64_t available = contents.size() - h.data_offset;
  if (available < 8) {
    if (h.points == 0 && available == 0) {
      return CloudAccumulator(name, "byte offset").Finish(options);
    }
    return absl::InvalidArgumentError(absl::StrCat(
        name, ": byte offset ", h.data_offset,
        ": binary_compressed data is truncated: expected 8 bytes of sizes, found ", available));
  }
  const char* sizes = contents.data() + h.data_offset;
  const uint64_t compressed = LoadU32(sizes), uncompressed = LoadU32(sizes + 4);
  const uint64_t block = h.data_offset + 8;
  uint64_t expected = 0;
  if (MulOverflows(h.points, layout.point_bytes, &expected) || expected != uncompressed) {
    return absl::InvalidArgumentError(absl::StrCat(
        name, ": byte offset ", h.data_offset + 4, ": uncompressed size ", uncompressed,
        " does not match the header (", h.points, " points of ", layout.point_bytes, " bytes)"));
  }
  if (compressed > available - 8) {
    return absl::InvalidArgumentError(absl::StrCat(name, ": byte offset ", block,
                                                   ": compressed data is truncated: expected ",
                                                   compressed, " bytes, found ", available - 8));
  }
  if (uncompressed == 0) return CloudAccumulator(name, "byte offset").Finish(options);
  // LZF expands at most 88 times (a 3-byte back reference copies 264 bytes); a larger claim
  // is corrupt, and refusing it avoids allocating what a forged header asks for.
  if (uncompressed > compressed * 100) {
    return absl::InvalidArgumentError(absl::StrCat(name, ": byte offset ", h.data_offset, ": ",
                                                   compressed, " compressed bytes cannot hold ",
                                                   uncompressed, " bytes; the data is corrupt"));
  }
  // Not zero-filled: lzf_decompress writes every byte or the block is refused below.
  const std::unique_ptr<char[]> data(new char[uncompressed]);
  const unsigned int got = lzf_decompress(sizes + 8, static_cast<unsigned int>(compressed),
                                          data.get(), static_cast<unsigned int>(uncompressed));
  if (got != uncompressed) {
    return absl::InvalidArgumentError(absl::StrCat(name, ": byte offset ", block,
                                                   ": the LZF block is corrupt (decompressed ", got,
                                                   " of ", uncompressed, " bytes)"));
  }
  const char* field[3];
  uint64_t step[3];
  for (int a = 0; a < 3; ++a) {
    // Fields before this one take byte_offset bytes per point; x, y and z have COUNT 1.
    field[a] = data.get() + layout.byte_offset[a] * h.points;
    step[a] = layout.is_double[a] ? 8 : 4;
  }
  if (!layout.is_double[0] && !layout.is_double[1] && !layout.is_double[2]) {
    FloatColumns columns;
    for (int a = 0; a < 3; ++a) {
      columns.axis[a] = field[a];
      columns.stride[a] = 4;
    }
    columns.where = block;  // coordinates have no place of their own in the file
    return ReadFloatColumns(columns, h.points, "byte offset", options);
  }
  return ReadPointsTwice(
      h.points,
      [&](size_t i, double* p) {
        for (int a = 0; a < 3; ++a) {
          p[a] = LoadCoordinate(field[a] + i * step[a], layout.is_double[a]);
        }
      },
      [&](size_t) { return block; }, name, "byte offset", options);
}

}  // namespace pcd_internal
}  // namespace shapeid
