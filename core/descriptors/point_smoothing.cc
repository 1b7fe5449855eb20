// Point smoothing: the k nearest points from a uniform grid, searched in rings of cells
// around each point's own.
#include "core/descriptors/point_smoothing.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include "absl/base/casts.h"
#include "core/descriptors/cnsd_downsample.h"

namespace shapeid {
namespace {

// Seed of the reduction of large clouds; part of the descriptor's definition.
constexpr uint64_t kReductionSeed = 0x5f3759df;

// Cells per axis at most, so the grid's index stays small (33^3 counters) even when an
// outlier stretches the box: cells then grow wider, which costs time, never a neighbour.
constexpr int kMaxCellsPerAxis = 32;
// Candidates counted per block (see MeanOfNearest), and the padding that never counts.
constexpr size_t kCountLanes = 8;
constexpr uint32_t kNeverBelow = 0x7fffffff;
constexpr size_t kMaxCells =
    static_cast<size_t>(kMaxCellsPerAxis + 1) * (kMaxCellsPerAxis + 1) * (kMaxCellsPerAxis + 1);

// The points sorted by grid cell, coordinates apart (x, y, z arrays) so the distance loop
// over one cell reads three contiguous runs.
class PointGrid {
 public:
  PointGrid(const PointCloud& points, double cell) {
    const size_t m = points.size();
    for (int a = 0; a < 3; ++a) {
      lo_[a] = hi_[a] = points.data()[a];
      for (size_t i = 1; i < m; ++i) {
        lo_[a] = std::min(lo_[a], static_cast<double>(points.data()[3 * i + a]));
        hi_[a] = std::max(hi_[a], static_cast<double>(points.data()[3 * i + a]));
      }
    }
    const double widest = std::max({hi_[0] - lo_[0], hi_[1] - lo_[1], hi_[2] - lo_[2]});
    cell_ = std::max(cell, widest / kMaxCellsPerAxis);
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
    std::vector<uint32_t> next(start_.begin(), start_.end() - 1);
    for (size_t i = 0; i < m; ++i) {
      const uint32_t slot = next[cell_of[i]]++;
      for (int a = 0; a < 3; ++a) sorted_[a][slot] = points.data()[3 * i + a];
    }
  }

  // Scratch for MeanOfNearest, reused between calls: each candidate's squared distance as
  // the bits of a non-negative float (which order as the floats do), and its sorted index.
  struct Candidates {
    std::vector<uint32_t> squared_bits;
    std::vector<uint32_t> index;
  };

  // The mean of the k nearest points to p (k <= the number of points; p itself counts when
  // it is one of them; ties at the k-th distance go to the first in cell order) into `mean`.
  void MeanOfNearest(const float* p, size_t k, Candidates* candidates, float* mean) const {
    int centre[3];
    for (int a = 0; a < 3; ++a) centre[a] = CellAlong(a, p[a]);
    // Rings of cells around p's own until the k-th nearest is nearer than any point outside
    // the cells searched can be: p lies in its cell, so a ring of r cells holds every point
    // within r cell widths.
    for (int ring = 1;; ++ring) {
      candidates->squared_bits.clear();
      candidates->index.clear();
      bool everything = true;
      int from[3], to[3];
      for (int a = 0; a < 3; ++a) {
        from[a] = std::max(centre[a] - ring, 0);
        to[a] = std::min(centre[a] + ring, cells_[a] - 1);
        everything = everything && from[a] == 0 && to[a] == cells_[a] - 1;
      }
      for (int i = from[0]; i <= to[0]; ++i) {
        for (int j = from[1]; j <= to[1]; ++j) {
          // Cells along z are adjacent in the index: one run.
          const uint32_t last = start_[Index(i, j, to[2]) + 1];
          for (uint32_t q = start_[Index(i, j, from[2])]; q < last; ++q) {
            const float dx = sorted_[0][q] - p[0], dy = sorted_[1][q] - p[1],
                        dz = sorted_[2][q] - p[2];
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
      // signed integers; padding to whole blocks of 8 with the largest (never below a bound)
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
      const uint32_t* const bits = candidates->squared_bits.data();
      const double reach = ring * cell_;
      if (!everything && static_cast<double>(absl::bit_cast<float>(kth)) > reach * reach) continue;
      double sum[3] = {0, 0, 0};
      size_t taken = 0;
      for (size_t c = 0; c < count; ++c) {
        if (bits[c] < kth) {
          const uint32_t q = candidates->index[c];
          for (int a = 0; a < 3; ++a) sum[a] += sorted_[a][q];
          ++taken;
        }
      }
      for (size_t c = 0; c < count && taken < take; ++c) {
        if (bits[c] == kth) {
          const uint32_t q = candidates->index[c];
          for (int a = 0; a < 3; ++a) sum[a] += sorted_[a][q];
          ++taken;
        }
      }
      for (int a = 0; a < 3; ++a) mean[a] = static_cast<float>(sum[a] / static_cast<double>(take));
      return;
    }
  }

 private:
  // The cell along axis a of coordinate v, clamped to the grid.
  int CellAlong(int a, float v) const {
    const double q = std::floor((static_cast<double>(v) - lo_[a]) / cell_);
    return static_cast<int>(std::clamp(q, 0.0, static_cast<double>(cells_[a] - 1)));
  }
  size_t Index(int i, int j, int k) const {
    return (static_cast<size_t>(i) * cells_[1] + j) * cells_[2] + k;
  }

  double lo_[3], hi_[3];
  double cell_ = 0;
  int cells_[3] = {1, 1, 1};
  std::vector<uint32_t> start_;  // [cell] -> first sorted point; one past the end
  std::vector<float> sorted_[3];
};

}  // namespace

PointCloud SmoothPoints(const PointCloud& cloud, const CloudStats& stats, double share) {
  const size_t n = cloud.size();
  PointCloud reduced;
  if (n > kSmoothingReferencePoints) {
    reduced = cnsd_internal::RandomDownsample(cloud, kSmoothingReferencePoints, kReductionSeed);
  }
  const PointCloud& points = n > kSmoothingReferencePoints ? reduced : cloud;
  const size_t m = points.size();
  PointCloud smoothed(std::vector<float>(points.data(), points.data() + 3 * m));
  if (!(share > 0)) return smoothed;
  const size_t k =
      std::min(m, std::max(kMinSmoothingNeighbours,
                           static_cast<size_t>(std::lround(share * static_cast<double>(m)))));
  // Cells about as wide as the k nearest reach on a sphere's surface (pi r^2 = share x 4 pi
  // R^2), so one ring of cells mostly holds them.
  double squares = 0;
  for (size_t i = 0; i < m; ++i) {
    squares += (points.point(i).cast<double>() - stats.centroid).squaredNorm();
  }
  const double rms_radius = std::sqrt(squares / static_cast<double>(m));
  const PointGrid grid(points, 2 * rms_radius * std::sqrt(share));
  PointGrid::Candidates candidates;
  candidates.squared_bits.reserve(m);
  candidates.index.reserve(m);
  for (size_t i = 0; i < m; ++i) {
    grid.MeanOfNearest(points.data() + 3 * i, k, &candidates, smoothed.data() + 3 * i);
  }
  return smoothed;
}

size_t SmoothPointsBytes(size_t n) {
  const size_t m = std::min(n, kSmoothingReferencePoints);
  size_t bytes = 3 * m * sizeof(float)                         // the smoothed cloud
                 + 2 * (kMaxCells + 1) * sizeof(uint32_t)      // cell starts, next free slots
                 + m * (sizeof(uint32_t) + 3 * sizeof(float))  // cells of, sorted points
                 + 2 * (m + kCountLanes) * sizeof(uint32_t);   // candidates, padded
  if (n > kSmoothingReferencePoints) {
    bytes += cnsd_internal::RandomDownsampleBytes(n, kSmoothingReferencePoints);  // reduced
  }
  return bytes;
}

}  // namespace shapeid
