// Point smoothing: the k nearest points from a uniform grid, searched in rings of cells
// around each point's own.
#include "core/descriptors/point_smoothing.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <utility>
#include <vector>

#include "Eigen/Core"
#include "absl/base/casts.h"
#include "core/descriptors/cnsd_downsample.h"

namespace shapeid {
namespace {

// Seed of the reduction of large clouds; part of the descriptor's definition.
constexpr uint64_t kReductionSeed = 0x5f3759df;

// The grid spans the points' box cut to this many robust radii (the median distance from the
// coordinate-wise median) around the median, so that a stray point far away neither
// stretches the cells (which would put the object in a few and make every search scan it
// all) nor the index. The few points beyond are searched by brute force.
constexpr double kGridRobustRadii = 6;
// Cells per axis at most, so the index stays small (33^3 counters).
constexpr int kMaxCellsPerAxis = 32;
// Candidates counted per block (see MeanOfNearest), and the padding that never counts.
constexpr size_t kCountLanes = 8;
constexpr uint32_t kNeverBelow = 0x7fffffff;
constexpr size_t kMaxCells =
    static_cast<size_t>(kMaxCellsPerAxis + 1) * (kMaxCellsPerAxis + 1) * (kMaxCellsPerAxis + 1);

// The points sorted by grid cell, in cell units ((coordinate - grid corner) / cell width, so
// squared distances stay in float range whatever the cloud's scale), coordinates apart (x, y,
// z arrays) so the distance loop over one cell reads three contiguous runs.
class PointGrid {
 public:
  PointGrid(const PointCloud& points, const Eigen::Vector3d& center, double radius, double cell)
      : points_(points) {
    const size_t m = points.size();
    for (int a = 0; a < 3; ++a) {
      double lo = points.data()[a], hi = lo;
      for (size_t i = 1; i < m; ++i) {
        lo = std::min(lo, static_cast<double>(points.data()[3 * i + a]));
        hi = std::max(hi, static_cast<double>(points.data()[3 * i + a]));
      }
      lo_[a] = std::max(lo, center[a] - kGridRobustRadii * radius);
      hi_[a] = std::min(hi, center[a] + kGridRobustRadii * radius);
    }
    const double widest = std::max({hi_[0] - lo_[0], hi_[1] - lo_[1], hi_[2] - lo_[2]});
    cell_ = std::max(cell, widest / kMaxCellsPerAxis);
    if (!(cell_ > 0)) cell_ = 1;  // every point in one place (a reduced cloud may be)
    for (int a = 0; a < 3; ++a) {
      cells_[a] = static_cast<int>((hi_[a] - lo_[a]) / cell_) + 1;  // <= kMaxCellsPerAxis + 1
    }
    std::vector<uint32_t> cell_of(m);
    start_.assign(static_cast<size_t>(cells_[0]) * cells_[1] * cells_[2] + 1, 0);
    for (size_t i = 0; i < m; ++i) {
      const float* p = points.data() + 3 * i;
      cell_of[i] =
          static_cast<uint32_t>(Index(CellAlong(0, p[0]), CellAlong(1, p[1]), CellAlong(2, p[2])));
      ++start_[cell_of[i] + 1];
    }
    for (size_t c = 1; c < start_.size(); ++c) start_[c] += start_[c - 1];
    for (int a = 0; a < 3; ++a) sorted_[a].resize(m);
    order_.resize(m);
    std::vector<uint32_t> next(start_.begin(), start_.end() - 1);
    for (size_t i = 0; i < m; ++i) {
      const uint32_t slot = next[cell_of[i]]++;
      for (int a = 0; a < 3; ++a) sorted_[a][slot] = InCells(a, points.data()[3 * i + a]);
      order_[slot] = static_cast<uint32_t>(i);
    }
  }

  // Scratch for MeanOfNearest, reused between calls: each candidate's squared distance as
  // the bits of a non-negative float (which order as the floats do), and its sorted index;
  // and (distance, sorted index) pairs for points outside the grid.
  struct Candidates {
    std::vector<uint32_t> squared_bits;
    std::vector<uint32_t> index;
    std::vector<std::pair<double, uint32_t>> outside;
  };

  // The mean of the k nearest points to point i (k <= the number of points; i itself among
  // them) into `mean`. Ties at the k-th distance go to the first in sorted order.
  void MeanOfNearest(size_t i, size_t k, Candidates* candidates, float* mean) const {
    const float* const p = points_.data() + 3 * i;
    float u[3];
    int center[3];
    bool inside = true;
    for (int a = 0; a < 3; ++a) {
      u[a] = InCells(a, p[a]);
      center[a] = CellAlong(a, p[a]);
      inside = inside && u[a] >= 0 && u[a] < static_cast<float>(cells_[a]);
    }
    if (!inside) return MeanOfNearestOutside(p, k, candidates, mean);
    // Rings of cells around p's own until the k-th nearest is nearer than any point outside
    // the cells searched can be: p lies in its cell, so a ring of r cells holds every point
    // within r cells (a point beyond the grid sits in a border cell, and is farther still).
    for (int ring = 1;; ++ring) {
      candidates->squared_bits.clear();
      candidates->index.clear();
      bool everything = true;
      int from[3], to[3];
      for (int a = 0; a < 3; ++a) {
        from[a] = std::max(center[a] - ring, 0);
        to[a] = std::min(center[a] + ring, cells_[a] - 1);
        everything = everything && from[a] == 0 && to[a] == cells_[a] - 1;
      }
      // Cells in index order, so candidates come in sorted order.
      for (int ci = from[0]; ci <= to[0]; ++ci) {
        for (int cj = from[1]; cj <= to[1]; ++cj) {
          // Cells along z are adjacent in the index: one run.
          const uint32_t last = start_[Index(ci, cj, to[2]) + 1];
          for (uint32_t q = start_[Index(ci, cj, from[2])]; q < last; ++q) {
            const float dx = sorted_[0][q] - u[0], dy = sorted_[1][q] - u[1],
                        dz = sorted_[2][q] - u[2];
            candidates->squared_bits.push_back(
                absl::bit_cast<uint32_t>(dx * dx + dy * dy + dz * dz));
            candidates->index.push_back(q);
          }
        }
      }
      const size_t count = candidates->squared_bits.size();
      if (count < k && !everything) continue;
      const size_t take = std::min(k, count);
      // The take-th smallest distance, bit by bit from the top: each step counts the
      // candidates below a bound, where a selection algorithm's data-dependent branches
      // would mispredict on every other candidate. Non-negative float bits compare as
      // signed integers; padding to whole blocks with the largest (never below a bound)
      // lets the compiler count a block in vector lanes.
      while (candidates->squared_bits.size() % kCountLanes != 0) {
        candidates->squared_bits.push_back(kNeverBelow);
      }
      const int32_t* const signed_bits =
          reinterpret_cast<const int32_t*>(candidates->squared_bits.data());
      const size_t blocks = candidates->squared_bits.size() / kCountLanes;
      uint32_t kth = 0;
      for (int b = 30; b >= 0; --b) {
        const int32_t bound = static_cast<int32_t>(kth | (uint32_t{1} << b));
        int32_t lanes[kCountLanes] = {};
        for (size_t block = 0; block < blocks; ++block) {
          for (size_t l = 0; l < kCountLanes; ++l) {
            lanes[l] += signed_bits[block * kCountLanes + l] < bound ? 1 : 0;
          }
        }
        int32_t below = 0;
        for (size_t l = 0; l < kCountLanes; ++l) below += lanes[l];
        if (static_cast<size_t>(below) < take) kth = static_cast<uint32_t>(bound);
      }
      if (!everything && absl::bit_cast<float>(kth) > static_cast<float>(ring * ring)) continue;
      const uint32_t* const bits = candidates->squared_bits.data();
      double sum[3] = {0, 0, 0};
      size_t taken = 0;
      for (size_t c = 0; c < count; ++c) {
        if (bits[c] < kth) {
          Add(candidates->index[c], sum);
          ++taken;
        }
      }
      for (size_t c = 0; c < count && taken < take; ++c) {
        if (bits[c] == kth) {
          Add(candidates->index[c], sum);
          ++taken;
        }
      }
      for (int a = 0; a < 3; ++a) mean[a] = static_cast<float>(sum[a] / static_cast<double>(take));
      return;
    }
  }

 private:
  // A point beyond the grid: every point is a candidate, distances in double (a far point's
  // cell coordinates could overflow float).
  void MeanOfNearestOutside(const float* p, size_t k, Candidates* candidates, float* mean) const {
    std::vector<std::pair<double, uint32_t>>& outside = candidates->outside;
    outside.clear();
    for (uint32_t q = 0; q < order_.size(); ++q) {
      const float* o = points_.data() + 3 * static_cast<size_t>(order_[q]);
      double d = 0;
      for (int a = 0; a < 3; ++a) {
        const double delta = static_cast<double>(o[a]) - p[a];
        d += delta * delta;
      }
      outside.emplace_back(d, q);
    }
    std::nth_element(outside.begin(), outside.begin() + static_cast<std::ptrdiff_t>(k - 1),
                     outside.end());
    double sum[3] = {0, 0, 0};
    for (size_t c = 0; c < k; ++c) Add(outside[c].second, sum);
    for (int a = 0; a < 3; ++a) mean[a] = static_cast<float>(sum[a] / static_cast<double>(k));
  }

  // Adds the original coordinates of the point in sorted place q.
  void Add(uint32_t q, double* sum) const {
    const float* o = points_.data() + 3 * static_cast<size_t>(order_[q]);
    for (int a = 0; a < 3; ++a) sum[a] += o[a];
  }

  float InCells(int a, float v) const {
    return static_cast<float>((static_cast<double>(v) - lo_[a]) / cell_);
  }
  // The cell along axis a of coordinate v, clamped to the grid.
  int CellAlong(int a, float v) const {
    const double q = std::floor((static_cast<double>(v) - lo_[a]) / cell_);
    return static_cast<int>(std::clamp(q, 0.0, static_cast<double>(cells_[a] - 1)));
  }
  size_t Index(int i, int j, int k) const {
    return (static_cast<size_t>(i) * cells_[1] + j) * cells_[2] + k;
  }

  const PointCloud& points_;
  double lo_[3], hi_[3];
  double cell_ = 0;
  int cells_[3] = {1, 1, 1};
  std::vector<uint32_t> start_;  // [cell] -> first sorted point; one past the end
  std::vector<float> sorted_[3];
  std::vector<uint32_t> order_;  // [sorted place] -> index in the points
};

}  // namespace

PointCloud SmoothPoints(const PointCloud& cloud, double share) {
  const size_t n = cloud.size();
  PointCloud reduced;
  if (n > kSmoothingReferencePoints) {
    reduced = cnsd_internal::RandomDownsample(cloud, kSmoothingReferencePoints, kReductionSeed);
  }
  const PointCloud& points = n > kSmoothingReferencePoints ? reduced : cloud;
  const size_t m = points.size();
  PointCloud smoothed(std::vector<float>(points.data(), points.data() + 3 * m));
  if (!(share > 0) || m == 0) return smoothed;
  const size_t k =
      std::min(m, std::max(kMinSmoothingNeighbors,
                           static_cast<size_t>(std::lround(share * static_cast<double>(m)))));
  // A center and radius that stray points cannot move: the coordinate-wise median, and the
  // median distance from it.
  std::vector<double> values(m);
  const auto middle = values.begin() + static_cast<std::ptrdiff_t>(m / 2);
  Eigen::Vector3d center;
  for (int a = 0; a < 3; ++a) {
    for (size_t i = 0; i < m; ++i) values[i] = points.data()[3 * i + a];
    std::nth_element(values.begin(), middle, values.end());
    center[a] = *middle;
  }
  for (size_t i = 0; i < m; ++i) values[i] = (points.point(i).cast<double>() - center).norm();
  std::nth_element(values.begin(), middle, values.end());
  const double radius = *middle;
  // Cells about as wide as the k nearest reach on a sphere's surface (pi r^2 = share x 4 pi
  // R^2), so one ring of cells mostly holds them.
  const PointGrid grid(points, center, radius, 2 * radius * std::sqrt(share));
  PointGrid::Candidates candidates;
  candidates.squared_bits.reserve(m + kCountLanes);
  candidates.index.reserve(m);
  for (size_t i = 0; i < m; ++i) grid.MeanOfNearest(i, k, &candidates, smoothed.data() + 3 * i);
  return smoothed;
}

size_t SmoothPointsBytes(size_t n) {
  const size_t m = std::min(n, kSmoothingReferencePoints);
  size_t bytes = 3 * m * sizeof(float)                             // the smoothed cloud
                 + 2 * (kMaxCells + 1) * sizeof(uint32_t)          // cell starts, next free slots
                 + m * (2 * sizeof(uint32_t) + 3 * sizeof(float))  // cells of, order, sorted
                 + 2 * (m + kCountLanes) * sizeof(uint32_t)        // candidates, padded
                 + m * sizeof(std::pair<double, uint32_t>);        // candidates beyond the grid
  if (n > kSmoothingReferencePoints) {
    bytes += cnsd_internal::RandomDownsampleBytes(n, kSmoothingReferencePoints);  // reduced
  }
  return bytes;
}

}  // namespace shapeid
