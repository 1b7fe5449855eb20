#ifndef SHAPEID_CORE_IO_CLOUD_ACCUMULATOR_H_
#define SHAPEID_CORE_IO_CLOUD_ACCUMULATOR_H_

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "Eigen/Core"
#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "core/io/read_options.h"

namespace shapeid {

// Internal to core/io: collects the points a reader decodes, in double, together with the
// bounding box of the finite ones and where in the file each extreme came from, then applies
// ReadOptions in Finish. Every reader goes through it (or through ReadFloatColumns, its
// float32 twin), so recentering and dropping behave the same for every format.
class CloudAccumulator {
 public:
  // `name` (the file) and `where_label` ("line", "byte offset") only shape error messages.
  CloudAccumulator(absl::string_view name, absl::string_view where_label);

  void Reserve(size_t points) { xyz_.reserve(3 * points); }
  size_t size() const { return xyz_.size() / 3; }

  // `where` locates the point in the file (its line or byte offset), for messages.
  void Add(double x, double y, double z, uint64_t where) {
    xyz_.push_back(x);
    xyz_.push_back(y);
    xyz_.push_back(z);
    if (std::isfinite(x) && std::isfinite(y) && std::isfinite(z)) {
      AddToBox(x, y, z, where);
    } else if (non_finite_++ == 0) {
      first_non_finite_ = size() - 1;
      first_non_finite_where_ = where;
    }
  }

  // Drops non-finite points if asked, shifts by the box center if asked, converts to float.
  // InvalidArgument, naming the file and the point's location, when a coordinate does not fit
  // in a float after the shift (it would become infinite).
  absl::StatusOr<ReadResult> Finish(const ReadOptions& options) &&;

 private:
  void AddToBox(double x, double y, double z, uint64_t where);

  std::string name_;
  std::string where_label_;
  std::vector<double> xyz_;
  size_t finite_ = 0;
  size_t non_finite_ = 0;
  size_t first_non_finite_ = 0;
  uint64_t first_non_finite_where_ = 0;
  double min_[3] = {0, 0, 0};
  double max_[3] = {0, 0, 0};
  uint64_t min_where_[3] = {0, 0, 0};
  uint64_t max_where_[3] = {0, 0, 0};
};

// A vector of `floats` floats for a cloud about to be overwritten whole. Large ones ask the
// kernel for huge pages, as first touching fresh 4 KiB pages dominates reading a cloud.
std::vector<float> NewCloudBuffer(size_t floats);

namespace cloud_internal {

// What a first pass over the points learns: the box of the finite ones (compared as
// CloudAccumulator::Add does) with the index of each extreme, and the non-finite ones.
struct Box {
  size_t finite = 0;
  double min[3] = {0, 0, 0};
  double max[3] = {0, 0, 0};
  size_t min_index[3] = {0, 0, 0};
  size_t max_index[3] = {0, 0, 0};
  size_t non_finite = 0;
  size_t first_non_finite = 0;

  void Add(const double p[3], size_t i) {
    if (!(std::isfinite(p[0]) && std::isfinite(p[1]) && std::isfinite(p[2]))) {
      if (non_finite++ == 0) first_non_finite = i;
      return;
    }
    for (int a = 0; a < 3; ++a) {
      if (finite == 0) {
        min[a] = max[a] = p[a];
        min_index[a] = max_index[a] = i;
      } else if (p[a] < min[a]) {
        min[a] = p[a];
        min_index[a] = i;
      } else if (p[a] > max[a]) {
        max[a] = p[a];
        max_index[a] = i;
      }
    }
    ++finite;
  }
};

// The shift ReadOptions asks for, or CloudAccumulator::Finish's error when an extreme does not
// fit a float after it; `where(index)` locates a point for the message.
template <typename Where>
absl::StatusOr<Eigen::Vector3d> Offset(const Box& box, const Where& where, absl::string_view name,
                                       absl::string_view where_label, const ReadOptions& options);

absl::Status DoesNotFit(absl::string_view name, absl::string_view where_label, uint64_t where,
                        int axis, double value, const ReadOptions& options);

// Fills the counts of `result` from the box.
void SetCounts(const Box& box, uint64_t first_where, absl::string_view where_label, bool dropped,
               ReadResult* result);

template <typename Where>
absl::StatusOr<Eigen::Vector3d> Offset(const Box& box, const Where& where, absl::string_view name,
                                       absl::string_view where_label, const ReadOptions& options) {
  Eigen::Vector3d offset = Eigen::Vector3d::Zero();
  if (box.finite == 0) return offset;
  if (options.recenter) {
    // Halves first: (min + max) can overflow a double; each half cannot.
    for (int a = 0; a < 3; ++a) offset[a] = box.min[a] / 2 + box.max[a] / 2;
  }
  // Only the extremes can overflow a float, so checking them checks every point.
  constexpr double kFloatMax = std::numeric_limits<float>::max();
  for (int a = 0; a < 3; ++a) {
    if (box.max[a] - offset[a] > kFloatMax) {
      return DoesNotFit(name, where_label, where(box.max_index[a]), a, box.max[a], options);
    }
    if (box.min[a] - offset[a] < -kFloatMax) {
      return DoesNotFit(name, where_label, where(box.min_index[a]), a, box.min[a], options);
    }
  }
  return offset;
}

}  // namespace cloud_internal

// For binary records, which cost little to decode twice: the result of a CloudAccumulator fed
// with the same points, bit for bit, errors included, without its double buffer. `load(i, p)`
// puts point i's coordinates in p[0..2]; `where(i)` is its byte offset, for messages.
template <typename Load, typename Where>
absl::StatusOr<ReadResult> ReadPointsTwice(size_t count, const Load& load, const Where& where,
                                           absl::string_view name, absl::string_view where_label,
                                           const ReadOptions& options) {
  cloud_internal::Box box;
  double p[3];
  for (size_t i = 0; i < count; ++i) {
    load(i, p);
    box.Add(p, i);
  }
  ReadResult result;
  absl::StatusOr<Eigen::Vector3d> offset =
      cloud_internal::Offset(box, where, name, where_label, options);
  if (!offset.ok()) return offset.status();
  result.offset = *offset;
  const bool drop = options.drop_non_finite && box.non_finite > 0;
  std::vector<float> out = NewCloudBuffer(3 * (drop ? box.finite : count));
  float* o = out.data();
  const double ox = result.offset.x(), oy = result.offset.y(), oz = result.offset.z();
  for (size_t i = 0; i < count; ++i) {
    load(i, p);
    if (drop && !(std::isfinite(p[0]) && std::isfinite(p[1]) && std::isfinite(p[2]))) continue;
    o[0] = static_cast<float>(p[0] - ox);
    o[1] = static_cast<float>(p[1] - oy);
    o[2] = static_cast<float>(p[2] - oz);
    o += 3;
  }
  cloud_internal::SetCounts(box, box.non_finite > 0 ? where(box.first_non_finite) : 0, where_label,
                            drop, &result);
  result.cloud = PointCloud(std::move(out));
  return result;
}

// Coordinates stored as float32 in a file: point i's axis a is the 4 bytes at
// axis[a] + i * stride[a], in the host's byte order unless `byte_swapped`. Point i is at
// `where + i * where_step` in the file (a byte offset), for messages.
struct FloatColumns {
  const char* axis[3] = {nullptr, nullptr, nullptr};
  uint64_t stride[3] = {0, 0, 0};
  bool byte_swapped = false;
  uint64_t where = 0;
  uint64_t where_step = 0;
};

// What a CloudAccumulator fed with the `count` points of `columns` would return, bit for bit,
// without its double buffer: one pass finds the box of the finite points and counts the
// others, a second writes the final cloud. Cannot fail: every float fits a float after the
// shift. The caller has checked that the columns lie inside the file.
ReadResult ReadFloatColumns(const FloatColumns& columns, size_t count,
                            absl::string_view where_label, const ReadOptions& options);

}  // namespace shapeid

#endif  // SHAPEID_CORE_IO_CLOUD_ACCUMULATOR_H_
