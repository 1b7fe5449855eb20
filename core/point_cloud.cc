#include "core/point_cloud.h"

#include <algorithm>
#include <cmath>

#include "absl/strings/str_cat.h"

namespace shapeid {

PointCloud::PointCloud(std::initializer_list<Eigen::Vector3f> points) {
  Reserve(points.size());
  for (const auto& p : points) Add(p);
}

double CloudStats::MaxAbsCentred() const {
  return std::max({max.x() - centroid.x(), centroid.x() - min.x(),
                   max.y() - centroid.y(), centroid.y() - min.y(),
                   max.z() - centroid.z(), centroid.z() - min.z()});
}

namespace {

absl::Status NonFiniteError(const PointCloud& cloud) {
  for (size_t i = 0; i < cloud.size(); ++i) {
    const auto p = cloud.point(i);
    if (!p.allFinite()) {
      return absl::InvalidArgumentError(absl::StrCat(
          "point ", i, " has a non-finite coordinate (", p.x(), ", ", p.y(), ", ", p.z(),
          "); drop or repair non-finite points before describing the cloud"));
    }
  }
  return absl::InternalError("non-finite coordinate detected but not found again");
}

}  // namespace

absl::StatusOr<CloudStats> ValidateCloud(const PointCloud& cloud, const CloudLimits& limits) {
  const size_t n = cloud.size();
  if (cloud.xyz().size() % 3 != 0) {
    return absl::InvalidArgumentError(absl::StrCat(
        "cloud holds ", cloud.xyz().size(), " floats, not a whole number of xyz points"));
  }
  if (n < 3) {
    return absl::InvalidArgumentError(
        absl::StrCat("cloud has ", n, " point", n == 1 ? "" : "s", "; at least 3 are needed"));
  }
  if (n > limits.max_points) {
    return absl::ResourceExhaustedError(absl::StrCat(
        "cloud has ", n, " points, more than the limit of ", limits.max_points));
  }

  // One pass: box, sum (in double, so a million points do not lose the centroid) and a
  // finiteness flag. NaN fails every comparison, so the flag is computed explicitly.
  const float* xyz = cloud.data();
  float lo[3] = {xyz[0], xyz[1], xyz[2]};
  float hi[3] = {xyz[0], xyz[1], xyz[2]};
  double sum[3] = {0, 0, 0};
  bool all_finite = true;
  for (size_t i = 0; i < n; ++i) {
    for (int a = 0; a < 3; ++a) {
      const float v = xyz[3 * i + a];
      all_finite &= std::fabs(v) <= std::numeric_limits<float>::max();
      lo[a] = std::min(lo[a], v);
      hi[a] = std::max(hi[a], v);
      sum[a] += v;
    }
  }
  if (!all_finite) return NonFiniteError(cloud);
  if (lo[0] == hi[0] && lo[1] == hi[1] && lo[2] == hi[2]) {
    return absl::InvalidArgumentError(absl::StrCat(
        "all ", n, " points are identical (", lo[0], ", ", lo[1], ", ", lo[2],
        "): the cloud has zero extent and no shape"));
  }

  CloudStats stats;
  stats.num_points = n;
  stats.min = Eigen::Vector3d(lo[0], lo[1], lo[2]);
  stats.max = Eigen::Vector3d(hi[0], hi[1], hi[2]);
  stats.centroid = Eigen::Vector3d(sum[0], sum[1], sum[2]) / static_cast<double>(n);
  return stats;
}

}  // namespace shapeid
