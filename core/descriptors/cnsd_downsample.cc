// CNSD-3D downsampling: the box-grid filter and the seeded random subset. Both are
// deterministic, so a cloud's descriptor does not depend on the run.
#include "core/descriptors/cnsd_downsample.h"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <limits>
#include <utility>
#include <vector>

namespace shapeid::cnsd_internal {
namespace {

// splitmix64 and a multiply-shift range reduction rather than <random>: the standard
// distributions are not specified bit for bit, and a gallery built with one standard library
// must describe the same subset as a query made with another.
uint64_t SplitMix64(uint64_t& state) {
  uint64_t z = (state += 0x9e3779b97f4a7c15ULL);
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  return z ^ (z >> 31);
}

// A uniform integer in [0, range) from 64 random bits (multiply-shift; bias <= range / 2^64).
uint64_t Below(uint64_t bits, uint64_t range) {
  __extension__ using Wide = unsigned __int128;
  return static_cast<uint64_t>((static_cast<Wide>(bits) * range) >> 64);
}

constexpr int kVoxelIndexBits = 21;
constexpr uint64_t kVoxelMaxIndex = (uint64_t{1} << kVoxelIndexBits) - 1;
constexpr int kVoxelSearchSteps = 20;

// Occupied cells of a box grid anchored at the bounding-box minimum, in an open-addressing
// table sized for `max_cells`, so a count can stop as soon as it is too large.
// The places of a permutation of 0 .. n - 1 that differ from the identity, in an
// open-addressing table for at most `entries` of them: a partial shuffle of max_points
// places in memory that does not grow with n.
class MovedPlaces {
 public:
  explicit MovedPlaces(size_t entries) : keys_(Slots(entries), kEmpty), values_(keys_.size()) {}

  // Slots for `entries` entries: at least twice as many, a power of two.
  static size_t Slots(size_t entries) {
    size_t slots = 16;
    while (slots < 2 * entries) slots *= 2;
    return slots;
  }

  size_t Get(size_t place) const {
    const size_t slot = Find(place);
    return keys_[slot] == place ? values_[slot] : place;
  }

  void Set(size_t place, size_t value) {
    const size_t slot = Find(place);
    keys_[slot] = place;
    values_[slot] = value;
  }

 private:
  static constexpr size_t kEmpty = ~size_t{0};  // places are < n

  size_t Find(size_t place) const {
    const size_t mask = keys_.size() - 1;
    size_t slot = static_cast<size_t>((place * 0x9e3779b97f4a7c15ULL) >> 20) & mask;
    while (keys_[slot] != kEmpty && keys_[slot] != place) slot = (slot + 1) & mask;
    return slot;
  }

  std::vector<size_t> keys_;
  std::vector<size_t> values_;
};

// Slots of VoxelGrid's table for `max_cells` cells.
size_t TableSlots(size_t max_cells) {
  size_t capacity = 16;
  while (capacity < 2 * (max_cells + 1)) capacity *= 2;
  return capacity;
}

class VoxelGrid {
 public:
  VoxelGrid(const PointCloud& cloud, size_t max_cells) : cloud_(cloud), max_cells_(max_cells) {
    for (int a = 0; a < 3; ++a) {
      lo_[a] = std::numeric_limits<double>::infinity();
      hi_[a] = -lo_[a];
    }
    for (size_t i = 0; i < cloud.size(); ++i) {
      for (int a = 0; a < 3; ++a) {
        lo_[a] = std::min(lo_[a], static_cast<double>(cloud.data()[3 * i + a]));
        hi_[a] = std::max(hi_[a], static_cast<double>(cloud.data()[3 * i + a]));
      }
    }
    const size_t capacity = TableSlots(max_cells);
    shift_ = 64 - __builtin_ctzll(capacity);
    keys_.resize(capacity);
    cell_of_slot_.resize(capacity);
  }

  // Largest extent over the three axes (0 for a single repeated point).
  double Extent() const { return std::max({hi_[0] - lo_[0], hi_[1] - lo_[1], hi_[2] - lo_[2]}); }

  // Occupied cells of size `leaf`, or max_cells + 1 when there are more.
  size_t CountCells(double leaf) {
    Clear();
    size_t cells = 0;
    for (size_t i = 0; i < cloud_.size(); ++i) {
      if (Insert(Key(i, leaf)) && ++cells > max_cells_) return cells;
    }
    return cells;
  }

  struct Cell {
    uint64_t key;
    double sum[3];
    size_t count;
  };

  // One point per occupied cell, the centroid of its points, in key order. `leaf` must give
  // at most max_cells cells.
  PointCloud Centroids(double leaf) {
    Clear();
    std::vector<Cell> cells;
    for (size_t i = 0; i < cloud_.size(); ++i) {
      const uint64_t key = Key(i, leaf);
      const size_t slot = Find(key);
      if (keys_[slot] == kEmpty) {
        keys_[slot] = key;
        cell_of_slot_[slot] = static_cast<uint32_t>(cells.size());
        cells.push_back({key, {0, 0, 0}, 0});
      }
      Cell& cell = cells[cell_of_slot_[slot]];
      for (int a = 0; a < 3; ++a) cell.sum[a] += cloud_.data()[3 * i + a];
      ++cell.count;
    }
    std::sort(cells.begin(), cells.end(),
              [](const Cell& l, const Cell& r) { return l.key < r.key; });
    PointCloud out;
    out.Reserve(cells.size());
    for (const Cell& cell : cells) {
      const double count = static_cast<double>(cell.count);
      out.Add(static_cast<float>(cell.sum[0] / count), static_cast<float>(cell.sum[1] / count),
              static_cast<float>(cell.sum[2] / count));
    }
    return out;
  }

 private:
  static constexpr uint64_t kEmpty = ~uint64_t{0};  // keys use 63 bits

  void Clear() { std::fill(keys_.begin(), keys_.end(), kEmpty); }

  uint64_t Key(size_t i, double leaf) const {
    uint64_t key = 0;
    for (int a = 0; a < 3; ++a) {
      // Division, not a reciprocal: at leaf = Extent() the far end of the widest axis gives
      // exactly 1, so it is in a different cell from the near end.
      const double q = (static_cast<double>(cloud_.data()[3 * i + a]) - lo_[a]) / leaf;
      const uint64_t index =
          q < static_cast<double>(kVoxelMaxIndex) ? static_cast<uint64_t>(q) : kVoxelMaxIndex;
      key = (key << kVoxelIndexBits) | index;
    }
    return key;
  }

  size_t Find(uint64_t key) const {
    size_t slot = static_cast<size_t>((key * 0x9e3779b97f4a7c15ULL) >> shift_);
    const size_t mask = keys_.size() - 1;
    while (keys_[slot] != kEmpty && keys_[slot] != key) slot = (slot + 1) & mask;
    return slot;
  }

  // True when `key` was new.
  bool Insert(uint64_t key) {
    const size_t slot = Find(key);
    if (keys_[slot] == key) return false;
    keys_[slot] = key;
    return true;
  }

  const PointCloud& cloud_;
  size_t max_cells_;
  double lo_[3];
  double hi_[3];
  int shift_ = 0;
  std::vector<uint64_t> keys_;
  std::vector<uint32_t> cell_of_slot_;
};

}  // namespace

PointCloud VoxelDownsample(const PointCloud& cloud, size_t max_points) {
  if (cloud.size() <= max_points) return cloud;
  VoxelGrid grid(cloud, std::max<size_t>(max_points, 1));
  const double extent = grid.Extent();
  if (!(extent > 0)) return PointCloud(std::vector<float>(cloud.data(), cloud.data() + 3));
  // Invariant: `hi` gives at most max_points cells. At the extent there are at most 8; for
  // max_points < 8 (outside the contract) fall back to one cell.
  double hi = extent;
  if (grid.CountCells(hi) > max_points) hi = 2 * extent;
  double lo = std::ldexp(extent, -20);
  for (int step = 0; step < kVoxelSearchSteps; ++step) {
    const double mid = std::sqrt(lo * hi);
    if (grid.CountCells(mid) <= max_points) {
      hi = mid;
    } else {
      lo = mid;
    }
  }
  return grid.Centroids(hi);
}

PointCloud RandomDownsample(const PointCloud& cloud, size_t max_points, uint64_t seed) {
  const size_t n = cloud.size();
  if (n <= max_points) return cloud;
  // The partial shuffle of 0 .. n - 1: step k swaps places k and j >= k, and place k is final
  // after it. Only the places a swap has moved are stored.
  MovedPlaces moved(max_points);
  std::vector<size_t> chosen(max_points);
  uint64_t state = seed;
  for (size_t k = 0; k < max_points; ++k) {
    const size_t j = k + Below(SplitMix64(state), n - k);
    chosen[k] = moved.Get(j);
    moved.Set(j, moved.Get(k));
  }
  std::sort(chosen.begin(), chosen.end());
  PointCloud out;
  out.Reserve(max_points);
  for (size_t k = 0; k < max_points; ++k) out.Add(cloud.point(chosen[k]));
  return out;
}

size_t VoxelDownsampleBytes(size_t n, size_t max_points) {
  if (n <= max_points) return n * 3 * sizeof(float);  // a copy
  const size_t cells = std::max<size_t>(max_points, 1);
  const size_t table = TableSlots(cells) * (sizeof(uint64_t) + sizeof(uint32_t));
  // Growing the cells vector holds its old and new blocks at once.
  size_t capacity = 1;
  while (capacity < cells) capacity *= 2;
  return table + (capacity + capacity / 2) * sizeof(VoxelGrid::Cell) + cells * 3 * sizeof(float);
}

size_t RandomDownsampleBytes(size_t n, size_t max_points) {
  if (n <= max_points) return n * 3 * sizeof(float);           // a copy
  return 2 * MovedPlaces::Slots(max_points) * sizeof(size_t)   // the shuffle's table
         + max_points * (sizeof(size_t) + 3 * sizeof(float));  // chosen places, the points
}

}  // namespace shapeid::cnsd_internal
