#ifndef SHAPEID_SERVER_WIRE_POINT_LAYOUT_H_
#define SHAPEID_SERVER_WIRE_POINT_LAYOUT_H_

#include <array>
#include <cstddef>
#include <cstdint>

#include "absl/status/status.h"

namespace shapeid {

// The byte layout of a cloud's point chunks (proto PointLayout, in sensor_msgs/PointCloud2's
// terms). The default is packed little-endian float32 x y z, 12 bytes a point.
struct PointLayout {
  enum class Type { kFloat32, kFloat64 };
  struct Coordinate {
    uint32_t offset = 0;  // bytes from the start of the point
    Type type = Type::kFloat32;
  };
  uint32_t point_step = 12;
  std::array<Coordinate, 3> xyz = {{{0, Type::kFloat32}, {4, Type::kFloat32}, {8, Type::kFloat32}}};
  bool big_endian = false;
  uint32_t width = 0;     // points per row of an organized cloud; 0: rows are not padded
  uint32_t row_step = 0;  // bytes from one row to the next, >= width * point_step
  bool drop_nonfinite = false;

  // The default layout (whatever drop_nonfinite says): chunks are copied as they are.
  bool is_packed_float32() const;
};

// InvalidArgument naming the field when the layout does not hold together: a point_step of 0
// or over 65,536 bytes, a coordinate past its point's end, coordinates that overlap, a row
// shorter than its points, or rows padded by a whole point or more (what a point_step too
// small for the data looks like: the points read at the wrong stride).
absl::Status ValidatePointLayout(const PointLayout& layout);

// What a declared layout's bytes betray about the layout itself: the first points'
// coordinates read as declared and read with the byte order, or (little-endian) FLOAT32 and
// FLOAT64, exchanged. When the declared reading is implausible and an exchanged one
// plausible, the layout is mis-declared (a wrong is_bigendian, float32 data declared FLOAT64
// or the reverse) and every point would be misread. Not thread-safe (one per stream).
class LayoutSurvey {
 public:
  // Starts over for `layout`, which ValidatePointLayout accepted.
  void Reset(const PointLayout& layout);

  // Surveys `count` whole points at `bytes`, point_step apart, until enough are seen.
  void Add(const char* bytes, size_t count);
  bool full() const;

  // OK, or InvalidArgument saying which reading the bytes fit, with the counts.
  absl::Status Verdict() const;

 private:
  // The coordinates finite in both the declared and the exchanged reading, and how many of
  // them are implausible in each.
  struct Tally {
    bool applies = false;
    uint64_t values = 0;
    uint64_t declared_implausible = 0;
    uint64_t implausible = 0;
  };
  enum Reading { kSwapped, kOtherWidth, kReadings };

  PointLayout layout_;
  std::array<Tally, kReadings> tallies_;
  uint64_t points_ = 0;
};

}  // namespace shapeid

#endif  // SHAPEID_SERVER_WIRE_POINT_LAYOUT_H_
