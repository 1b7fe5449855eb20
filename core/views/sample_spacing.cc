#include "core/views/sample_spacing.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include "Eigen/Core"

namespace shapeid {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr size_t kProbes = 256;
// Probes count neighbors among every stride-th point, at most this many: enough for a 2 %
// estimate, and a 100,000-point surface costs a quarter of a pass.
constexpr size_t kMaxCandidates = 32768;
// Neighbors per probe that make a usable estimate (below: too noisy; above: needless work,
// and balls that outgrow the surface's curvature).
constexpr uint64_t kMinMeanCount = 8;
constexpr uint64_t kMaxMeanCount = 256;
constexpr int kMaxTries = 12;

struct Cell {
  int64_t x, y, z;
  bool operator==(const Cell& o) const { return x == o.x && y == o.y && z == o.z; }
};

// Ball counts for all probes at one radius, through a table of the 27 cells around each probe
// (cell side = the radius, so every neighbor lies in one of them). A point costs one hash and
// one table read; only points near a probe go further. The buffers live across tries.
class NeighborCounter {
 public:
  NeighborCounter(const PointCloud& surface, const Eigen::Vector3d& origin)
      : surface_(surface),
        origin_(origin),
        stride_((surface.size() + kMaxCandidates - 1) / kMaxCandidates),
        candidates_((surface.size() + stride_ - 1) / stride_) {
    const size_t m = std::min(kProbes, candidates_);
    probes_.reserve(m);
    for (size_t k = 0; k < m; ++k) {
      // The middle candidate of each of m equal runs of them; each counts itself once.
      probes_.push_back(
          surface.point(stride_ * ((2 * k + 1) * candidates_ / (2 * m))).cast<double>());
    }
    while (table_size_ < 2 * 27 * m) table_size_ *= 2;
    bucket_start_.resize(table_size_ + 1);
    unsorted_.resize(27 * m);
    entries_.resize(27 * m);
    entry_hash_.resize(27 * m);
  }

  size_t num_probes() const { return probes_.size(); }
  size_t num_candidates() const { return candidates_; }

  // Pairs (probe, candidate) with |probe - candidate| <= radius, each probe's pair with
  // itself included; stops counting once past `cap` (the result is then > cap).
  uint64_t Count(double radius, uint64_t cap) {
    inv_cell_ = 1.0 / radius;
    BuildTable();
    const double r2 = radius * radius;
    uint64_t total = 0;
    const float* xyz = surface_.data();
    for (size_t i = 0; i < surface_.size(); i += stride_) {
      const Eigen::Vector3d p(xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2]);
      const Cell cell = CellOf(p);
      const uint64_t h = Hash(cell);
      for (uint32_t e = bucket_start_[h]; e < bucket_start_[h + 1]; ++e) {
        const Entry& entry = entries_[e];
        if (entry.cell == cell && (probes_[entry.probe] - p).squaredNorm() <= r2) {
          if (++total > cap) return total;
        }
      }
    }
    return total;
  }

 private:
  struct Entry {
    Cell cell;
    uint32_t probe;
  };

  // The origin is the box's corner, so coordinates are >= 0 and truncation is floor (which
  // is a library call on baseline x86-64).
  Cell CellOf(const Eigen::Vector3d& p) const {
    const Eigen::Vector3d c = (p - origin_) * inv_cell_;
    return Cell{static_cast<int64_t>(c.x()), static_cast<int64_t>(c.y()),
                static_cast<int64_t>(c.z())};
  }
  uint64_t Hash(const Cell& c) const {
    uint64_t h = static_cast<uint64_t>(c.x) * 0x9e3779b97f4a7c15ull ^
                 static_cast<uint64_t>(c.y) * 0xc2b2ae3d27d4eb4full ^
                 static_cast<uint64_t>(c.z) * 0x165667b19e3779f9ull;
    h ^= h >> 32;
    return h & (table_size_ - 1);
  }

  // Counting sort of the probes' 27 cells each by hash.
  void BuildTable() {
    std::fill(bucket_start_.begin(), bucket_start_.end(), 0u);
    size_t n = 0;
    for (uint32_t k = 0; k < probes_.size(); ++k) {
      const Cell c = CellOf(probes_[k]);
      for (int64_t dx = -1; dx <= 1; ++dx) {
        for (int64_t dy = -1; dy <= 1; ++dy) {
          for (int64_t dz = -1; dz <= 1; ++dz) {
            const Cell nc{c.x + dx, c.y + dy, c.z + dz};
            unsorted_[n] = Entry{nc, k};
            entry_hash_[n] = Hash(nc);
            ++bucket_start_[entry_hash_[n] + 1];
            ++n;
          }
        }
      }
    }
    for (size_t b = 0; b < table_size_; ++b) bucket_start_[b + 1] += bucket_start_[b];
    next_.assign(bucket_start_.begin(), bucket_start_.end() - 1);
    for (size_t e = 0; e < n; ++e) entries_[next_[entry_hash_[e]]++] = unsorted_[e];
  }

  const PointCloud& surface_;
  const Eigen::Vector3d origin_;
  const size_t stride_, candidates_;
  std::vector<Eigen::Vector3d> probes_;
  size_t table_size_ = 1;
  double inv_cell_ = 1;
  std::vector<uint32_t> bucket_start_;
  std::vector<Entry> unsorted_, entries_;  // entries_: bucketed by hash
  std::vector<uint64_t> entry_hash_;
  std::vector<uint32_t> next_;
};

}  // namespace

double EstimateSampleSpacing(const PointCloud& surface, const CloudStats& stats) {
  const double radius = 0.5 * (stats.max - stats.min).norm();  // > 0 for a valid cloud
  NeighborCounter counter(surface, stats.min);
  const uint64_t m = counter.num_probes();
  // First guess: the surface area of a compact object is about 4 r^2 (a sphere's is 4.2 r^2
  // for r the half-diagonal of its box, a cube's 8 r^2); aim at 32 neighbors per probe.
  const double guess_area = 4 * radius * radius;
  const double n = static_cast<double>(counter.num_candidates());
  double g = std::sqrt(32 * guess_area / (kPi * n));
  uint64_t pairs = 0;
  for (int attempt = 0; attempt < kMaxTries; ++attempt) {
    pairs = counter.Count(g, (kMaxMeanCount + 1) * m);
    if (pairs > (kMaxMeanCount + 1) * m) {
      g *= 0.5;  // a dense cluster: smaller balls
    } else if (pairs < (kMinMeanCount + 1) * m && g < radius) {
      g *= 2;  // a sparse sampling, or more area than guessed
    } else {
      break;
    }
  }
  const double neighbors = static_cast<double>(pairs - std::min(pairs, m));  // not themselves
  if (neighbors == 0) return g;  // nothing within g of any probe: the spacing is at least g
  const double density =
      neighbors / (static_cast<double>(m) * kPi * g * g) * static_cast<double>(surface.size()) / n;
  return 1 / std::sqrt(density);
}

}  // namespace shapeid
