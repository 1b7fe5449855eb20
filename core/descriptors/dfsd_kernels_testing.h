#ifndef SHAPEID_CORE_DESCRIPTORS_DFSD_KERNELS_TESTING_H_
#define SHAPEID_CORE_DESCRIPTORS_DFSD_KERNELS_TESTING_H_

// Test and benchmark helpers for the DFSD kernel: its input built from points in [-1, 1]^3
// the way DFSD builds it, so the pruned kernel can be set against reading every point.

#include <algorithm>
#include <array>
#include <cstdint>
#include <vector>

#include "core/descriptors/dfsd_kernels.h"
#include "core/point_cloud.h"

namespace shapeid::dfsd_internal {

using Points = std::vector<std::array<float, 3>>;

// The kernel's stride for n points.
inline size_t PaddedStride(size_t n) { return (n + kPointLanes - 1) / kPointLanes * kPointLanes; }

// DFSD's cell centers on a grid of g.
inline std::vector<float> Centers(int g) {
  std::vector<float> centers(static_cast<size_t>(g));
  for (int i = 0; i < g; ++i) centers[i] = static_cast<float>((2.0 * i + 1.0) / g - 1.0);
  return centers;
}

// The cloud moved and scaled into [-1, 1]^3 by its bounding box, its largest side spanning
// it, as DFSD's isotropic field in the axes frame lays it.
inline Points BoxNormalized(const PointCloud& cloud) {
  std::array<float, 3> lo = {1e30f, 1e30f, 1e30f}, hi = {-1e30f, -1e30f, -1e30f};
  for (size_t p = 0; p < cloud.size(); ++p) {
    for (int a = 0; a < 3; ++a) {
      lo[a] = std::min(lo[a], cloud.point(p)[a]);
      hi[a] = std::max(hi[a], cloud.point(p)[a]);
    }
  }
  float half = 0;
  for (int a = 0; a < 3; ++a) half = std::max(half, 0.5f * (hi[a] - lo[a]));
  Points points(cloud.size());
  for (size_t p = 0; p < cloud.size(); ++p) {
    for (int a = 0; a < 3; ++a) {
      points[p][a] = half > 0 ? (cloud.point(p)[a] - 0.5f * (lo[a] + hi[a])) / half : 0.0f;
    }
  }
  return points;
}

// The kernel's input for points in [-1, 1]^3 as DFSD lays it out: spatially ordered, every
// axis's tables and block bounds; a chunk after the first keeps the earlier tables' tail.
class GeometricInput {
 public:
  GeometricInput(int g, size_t stride) : g_(g), centers_(Centers(g)), stride_(stride) {
    tables_.assign(3 * g * stride, kFarSquared);
    bounds_.assign(3 * g * BlockStride(stride), kFarSquared);
    for (int i = 1; i < g; ++i) {
      spacing_ = std::max(spacing_, static_cast<double>(centers_[i]) - centers_[i - 1]);
    }
  }

  // Fills the tables with `points` (at most stride of them), first chunk or a later one.
  void Fill(const Points& points, bool first_chunk) {
    const size_t n = points.size();
    std::vector<double> coords(3 * n);
    const double* coord[3] = {coords.data(), coords.data() + n, coords.data() + 2 * n};
    for (size_t p = 0; p < n; ++p) {
      for (int a = 0; a < 3; ++a) coords[a * n + p] = points[p][a];
    }
    const double half[3] = {1, 1, 1};
    std::vector<uint32_t> order;
    SpatialOrder(coord, n, half, &order);
    std::vector<float> values(n);
    const size_t block_stride = BlockStride(stride_);
    for (int a = 0; a < 3; ++a) {
      for (size_t p = 0; p < n; ++p) values[p] = points[order[p]][a];
      FillAxisTables(values.data(), n, centers_.data(), g_, stride_, block_stride, first_chunk,
                     tables_.data() + a * g_ * stride_, bounds_.data() + a * g_ * block_stride);
    }
  }

  FieldInput Input(bool pruned, bool accumulate) const {
    FieldInput in = pruned ? LaidOutInput(tables_.data(), g_, stride_, bounds_.data(),
                                          BlockStride(stride_), spacing_)
                           : LaidOutInput(tables_.data(), g_, stride_);
    in.accumulate = accumulate;
    return in;
  }

 private:
  int g_;
  std::vector<float> centers_;
  size_t stride_;
  double spacing_ = 0;
  std::vector<float> tables_, bounds_;
};

}  // namespace shapeid::dfsd_internal

#endif  // SHAPEID_CORE_DESCRIPTORS_DFSD_KERNELS_TESTING_H_
