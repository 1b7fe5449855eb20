#ifndef SHAPEID_CORE_POINT_CLOUD_H_
#define SHAPEID_CORE_POINT_CLOUD_H_

#include <cstddef>
#include <limits>
#include <utility>
#include <vector>

#include "Eigen/Core"
#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/types/span.h"

namespace shapeid {

// A point cloud: n points stored as one contiguous array of float xyz triples
// (x0 y0 z0 x1 y1 z1 ...), the layout of PCD binary files and of the wire format, so readers
// and the server fill it without reshaping. Cheap to move; copying copies the points.
class PointCloud {
 public:
  PointCloud() = default;
  // Takes interleaved xyz; `xyz.size()` must be a multiple of 3.
  explicit PointCloud(std::vector<float> xyz) : xyz_(std::move(xyz)) {}
  // Convenience for tests and small clouds.
  PointCloud(std::initializer_list<Eigen::Vector3f> points);

  size_t size() const { return xyz_.size() / 3; }
  bool empty() const { return xyz_.empty(); }
  const float* data() const { return xyz_.data(); }
  float* data() { return xyz_.data(); }
  absl::Span<const float> xyz() const { return xyz_; }

  Eigen::Map<const Eigen::Vector3f> point(size_t i) const {
    return Eigen::Map<const Eigen::Vector3f>(xyz_.data() + 3 * i);
  }
  // A 3 x n column-major view of all points, for Eigen expressions.
  Eigen::Map<const Eigen::Matrix3Xf> matrix() const {
    return Eigen::Map<const Eigen::Matrix3Xf>(xyz_.data(), 3, static_cast<Eigen::Index>(size()));
  }

  void Reserve(size_t points) { xyz_.reserve(3 * points); }
  void Add(float x, float y, float z) {
    xyz_.push_back(x);
    xyz_.push_back(y);
    xyz_.push_back(z);
  }
  void Add(const Eigen::Vector3f& p) { Add(p.x(), p.y(), p.z()); }
  // Appends interleaved xyz floats (a multiple of 3), e.g. one chunk of a streamed cloud.
  void Append(absl::Span<const float> xyz) { xyz_.insert(xyz_.end(), xyz.begin(), xyz.end()); }
  std::vector<float>& mutable_xyz() { return xyz_; }

 private:
  std::vector<float> xyz_;
};

// Bounds that a caller (the server, the CLI) puts on what it accepts. The core itself has
// no size limit: a library user who describes a 50-million-point scan may.
struct CloudLimits {
  size_t max_points = std::numeric_limits<size_t>::max();
  // Threads one Compute may use, the calling thread included. The default keeps the work on
  // the calling thread, as a server running many requests at once wants; a program describing
  // one large cloud may give it its cores. Only large clouds are split (RPHSD from 2 x 65,536
  // points), and the result is the same bits whatever the count.
  int max_threads = 1;
};

// What one pass over a valid cloud learns; every descriptor needs some of it.
struct CloudStats {
  size_t num_points = 0;
  Eigen::Vector3d min = Eigen::Vector3d::Zero();  // axis-aligned bounding box
  Eigen::Vector3d max = Eigen::Vector3d::Zero();
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();  // mean, accumulated in double

  // Largest |p - centroid| over every coordinate of every point: the L-infinity radius
  // that RPHSD divides by. Derived from the box, so no second pass is needed.
  double MaxAbsCentered() const;
};

// Validates a cloud as in section 0 of docs/descriptors.md, in one pass, and returns its
// stats. Errors (all InvalidArgument, except the size limit, which is ResourceExhausted):
//  - fewer than 3 points;
//  - more than `limits.max_points` points (both numbers in the message);
//  - a non-finite coordinate (the message names the first such point and its values);
//  - every point identical (zero extent).
absl::StatusOr<CloudStats> ValidateCloud(const PointCloud& cloud, const CloudLimits& limits = {});

}  // namespace shapeid

#endif  // SHAPEID_CORE_POINT_CLOUD_H_
