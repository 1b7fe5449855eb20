// COMSD-3D (docs/descriptors.md section 2; dissertation chapter 4 and 8.1).
//
// Readings where the spec leaves room, and why:
//  - Direction axes. The spec lists directions as (dx, dy, dz) while the dissertation gives
//    angles (table 1) and grid indices i (row, from y), j (column, from x), k (depth, from z)
//    (eq. 8.1). We read each component as a step along the axis it names: dx moves j, dy
//    moves i, dz moves k, so the pair is (V[i, j, k], V[i + dy, j + dx, k + dz]), the first
//    voxel giving the row a of C_d and the second the column b.
//  - "Normalize by the number of pairs counted": every in-grid pair counts, empty-empty ones
//    included, so sum(C_d) = (N - |dx|)(N - |dy|)(N - dz) > 0 for N >= 2. This is the
//    dissertation's "total number of transitions" (4.2); it never divides by zero.
//  - Arithmetic of eq. 8.1. The spec gives real arithmetic; we evaluate it in float, in the
//    written order ((v - vmin) / (vmax - vmin) * (N - 1), then truncation), so a point that
//    sits exactly on a cell boundary in real numbers may land on either side by rounding, the
//    same on every machine. The division form makes v = vmax land in N - 1 exactly. Where
//    some vmax - vmin overflows float (coordinates beyond +-1.7e38) the cloud is evaluated
//    in double instead, the only way to keep the formula finite.
//  - Logarithm: natural (the spec says so; the dissertation writes "log").
// Everything else (zero-extent axis -> index 0, 0 ln 0 = 0, correlation 0 where the variance
// is 0, the direction order) the spec states outright.
//
// Speed: the grid is packed along z into 64-bit words, and every direction has dz in {0, 1},
// so the 1-1 pairs of a direction are popcount(rowA & (rowB >> dz)) summed over row pairs.
// The other three cells follow from the ones in the source and target regions and the pair
// count, so the whole matrix set costs 13 passes over N^2 rows of ceil(N / 64) words.

#include "core/descriptors/comsd.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <memory>
#include <utility>

#include "absl/status/status.h"
#include "absl/strings/str_cat.h"
#include "core/descriptor.h"
#include "core/descriptor_spec.h"
#include "core/descriptors/cost_model.h"
#include "core/simd.h"
#include "core/status_macros.h"

namespace shapeid {
namespace comsd_internal {
namespace {

// Points per voxelization block. A fixed trip count lets the compiler vectorise the index
// loop even at -O2 (GCC's "very cheap" cost model refuses loops that need an epilogue).
constexpr int kBlockPoints = 256;
constexpr int kBlockFloats = 3 * kBlockPoints;

// The eq. 8.1 index of every coordinate of a block of interleaved xyz floats. `lo` and
// `extent` repeat the per-axis values with period 3, so the loop is one contiguous stream.
void BlockIndices(const float* xyz, const float* lo, const float* extent, float last,
                  int32_t* index) {
  for (int e = 0; e < kBlockFloats; ++e) {
    float t = (xyz[e] - lo[e]) / extent[e] * last;
    // Rounding cannot push t outside [0, last] for a validated cloud; the clamp is a guard
    // that also sends a NaN to a valid index instead of into an undefined conversion.
    t = t < last ? t : last;
    t = t > 0.0f ? t : 0.0f;
    index[e] = static_cast<int32_t>(t);
  }
}

// The same indices in double, for clouds whose extent overflows float.
void BlockIndicesDouble(const float* xyz, const double* lo, const double* extent, double last,
                        int32_t* index) {
  for (int e = 0; e < kBlockFloats; ++e) {
    double t = (static_cast<double>(xyz[e]) - lo[e % 3]) / extent[e % 3] * last;
    t = t < last ? t : last;
    t = t > 0.0 ? t : 0.0;
    index[e] = static_cast<int32_t>(t);
  }
}

inline int PopcountPortable(uint64_t x) {
  x = x - ((x >> 1) & 0x5555555555555555ULL);
  x = (x & 0x3333333333333333ULL) + ((x >> 2) & 0x3333333333333333ULL);
  x = (x + (x >> 4)) & 0x0F0F0F0F0F0F0F0FULL;
  return static_cast<int>((x * 0x0101010101010101ULL) >> 56);
}

template <bool kHardware>
__attribute__((always_inline)) inline int Popcount(uint64_t x) {
  if constexpr (kHardware) {
    return __builtin_popcountll(x);
  } else {
    return PopcountPortable(x);
  }
}

// The counting kernel. always_inline puts one copy inside each entry point below, so the
// hardware copy is compiled with the POPCNT target and __builtin_popcountll becomes one
// instruction; at the x86-64 baseline it would be a library call.
template <bool kHardware>
__attribute__((always_inline)) inline void CountKernel(const PackedGrid& grid, AllCounts* out) {
  const int n = grid.n;
  const int words = grid.words;
  const uint64_t* bits = grid.bits.data();
  const size_t num_rows = static_cast<size_t>(n) * n;
  const int last_word = (n - 1) / 64;
  const int last_bit = (n - 1) % 64;

  // Prefix sums over rows (i, j) in memory order, so the ones in a run of rows cost two
  // loads: all filled voxels; without k = n - 1 (the source side of a dz = 1 direction, whose
  // voxel k = n - 1 has no partner); without k = 0 (its target side).
  std::vector<int64_t> prefix(3 * (num_rows + 1));
  int64_t* all_before = prefix.data();
  int64_t* no_last_before = all_before + num_rows + 1;
  int64_t* no_first_before = no_last_before + num_rows + 1;
  all_before[0] = no_last_before[0] = no_first_before[0] = 0;
  for (size_t r = 0; r < num_rows; ++r) {
    const uint64_t* row = bits + r * words;
    int64_t ones = 0;
    for (int w = 0; w < words; ++w) ones += Popcount<kHardware>(row[w]);
    const int64_t last = static_cast<int64_t>((row[last_word] >> last_bit) & 1);
    const int64_t first = static_cast<int64_t>(row[0] & 1);
    all_before[r + 1] = all_before[r] + ones;
    no_last_before[r + 1] = no_last_before[r] + ones - last;
    no_first_before[r + 1] = no_first_before[r] + ones - first;
  }

  for (int d = 0; d < kNumDirections; ++d) {
    const Direction dir = kDirections[d];
    const int i_begin = std::max(0, -dir.dy);
    const int i_end = n - std::max(0, dir.dy);
    const int j_begin = std::max(0, -dir.dx);
    const int j_end = n - std::max(0, dir.dx);
    const size_t run = static_cast<size_t>(j_end - j_begin);  // rows per i, contiguous
    const int64_t* source_before = dir.dz == 0 ? all_before : no_last_before;
    const int64_t* target_before = dir.dz == 0 ? all_before : no_first_before;

    int64_t both = 0;    // pairs with V[v] = 1 and V[v + d] = 1
    int64_t source = 0;  // ones over the source region
    int64_t target = 0;  // ones over the target region
    for (int i = i_begin; i < i_end; ++i) {
      const size_t ra = static_cast<size_t>(i) * n + j_begin;
      const size_t rb = static_cast<size_t>(i + dir.dy) * n + (j_begin + dir.dx);
      source += source_before[ra + run] - source_before[ra];
      target += target_before[rb + run] - target_before[rb];
      const uint64_t* a = bits + ra * words;
      const uint64_t* b = bits + rb * words;
      if (dir.dz == 0) {
        // Same k on both ends: the rows of the run are one contiguous stretch of words.
        const size_t stretch = run * words;
        for (size_t w = 0; w < stretch; ++w) both += Popcount<kHardware>(a[w] & b[w]);
      } else {
        // b shifted down one voxel: bit k holds V[.., k + 1]. Bits at k >= n are 0, so
        // source voxel k = n - 1 meets a 0 and needs no mask.
        for (size_t row = 0; row < run; ++row, a += words, b += words) {
          for (int w = 0; w + 1 < words; ++w) {
            both += Popcount<kHardware>(a[w] & ((b[w] >> 1) | (b[w + 1] << 63)));
          }
          both += Popcount<kHardware>(a[words - 1] & (b[words - 1] >> 1));
        }
      }
    }
    const int64_t pairs = static_cast<int64_t>(i_end - i_begin) * (j_end - j_begin) * (n - dir.dz);
    CooccurrenceCounts& c = (*out)[d];
    c.counts[1][1] = both;
    c.counts[1][0] = source - both;
    c.counts[0][1] = target - both;
    c.counts[0][0] = pairs - source - target + both;
  }
}

void CountPortable(const PackedGrid& grid, AllCounts* out) { CountKernel<false>(grid, out); }

#if defined(__x86_64__) || defined(__i386__)
__attribute__((target("popcnt"))) void CountHardware(const PackedGrid& grid, AllCounts* out) {
  CountKernel<true>(grid, out);
}
#endif

class ComsdDescriptor final : public Descriptor {
 public:
  ComsdDescriptor(DescriptorSpec canonical_spec, int grid)
      : Descriptor(std::move(canonical_spec), kDimension), grid_(grid) {}

  DescribeCost EstimateCost(size_t num_points) const override {
    // CPU: voxelizing is per point; counting is 13 passes over N^2 rows of ceil(N / 64)
    // words, after one pass of prefix sums. Constants: docs/performance.md, "Describe cost".
    constexpr double kNsBase = 2000, kNsPerPoint = 3.5, kNsPerWord = 0.75;
    const size_t n = static_cast<size_t>(grid_);
    const size_t rows = n * n;
    const size_t words = rows * static_cast<size_t>((grid_ + 63) / 64);
    DescribeCost cost;
    cost.cpu =
        cost_model::Nanoseconds(kNsBase + kNsPerPoint * static_cast<double>(num_points) +
                                kNsPerWord * (kNumDirections + 1) * static_cast<double>(words));
    cost.working_bytes = words * sizeof(uint64_t)            // the packed grid
                         + 3 * (rows + 1) * sizeof(int64_t)  // prefix sums
                         + kDimension * sizeof(float) + cost_model::kHeapSlack;
    return cost;
  }

 protected:
  absl::Status ComputeValidated(const PointCloud& cloud, const CloudStats& stats,
                                const CloudLimits& /*limits*/,
                                absl::Span<float> out) const override {
    if (out.size() != static_cast<size_t>(kDimension)) {
      return absl::InternalError(
          absl::StrCat("comsd output has ", out.size(), " floats, expected ", kDimension));
    }
    const PackedGrid voxels = Voxelize(cloud, stats, grid_);
    // SHAPEID_SIMD=scalar also selects the portable count, so one switch exercises the
    // baseline path everywhere; every AVX2 CPU has POPCNT.
    const PopcountPath path =
        ActiveSimdLevel() != SimdLevel::kScalar ? PopcountPath::kHardware : PopcountPath::kPortable;
    ComputeFeatures(CountCooccurrences(voxels, path), out);
    return absl::OkStatus();
  }

 private:
  int grid_;
};

absl::StatusOr<std::unique_ptr<Descriptor>> CreateComsd(const DescriptorSpec& filled) {
  SHAPEID_ASSIGN_OR_RETURN(const int64_t grid, SpecParams(filled).Int("grid", kMinGrid, kMaxGrid));
  DescriptorSpec canonical{"comsd", {{"grid", absl::StrCat(grid)}}};
  return std::unique_ptr<Descriptor>(
      std::make_unique<ComsdDescriptor>(std::move(canonical), static_cast<int>(grid)));
}

}  // namespace

PackedGrid Voxelize(const PointCloud& cloud, const CloudStats& stats, int n) {
  PackedGrid grid;
  grid.n = n;
  grid.words = (n + 63) / 64;
  grid.bits.assign(static_cast<size_t>(n) * n * grid.words, 0);

  // The box is the cloud's own float extremes widened to double, so narrowing is exact. A
  // zero-extent axis divides by 1: every coordinate there equals vmin, giving index 0.
  float lo[3];
  float extent[3];
  double lo_d[3];
  double extent_d[3];
  bool float_ok = true;
  for (int a = 0; a < 3; ++a) {
    lo[a] = static_cast<float>(stats.min[a]);
    extent[a] = static_cast<float>(stats.max[a]) - lo[a];
    if (extent[a] == 0.0f) extent[a] = 1.0f;
    float_ok &= std::isfinite(extent[a]);
    lo_d[a] = stats.min[a];
    extent_d[a] = stats.max[a] - stats.min[a];
    if (extent_d[a] == 0.0) extent_d[a] = 1.0;
  }
  float lo_pattern[kBlockFloats];
  float extent_pattern[kBlockFloats];
  for (int e = 0; e < kBlockFloats; ++e) {
    lo_pattern[e] = lo[e % 3];
    extent_pattern[e] = extent[e % 3];
  }

  const size_t num_points = cloud.size();
  const float* xyz = cloud.data();
  float tail[kBlockFloats];
  int32_t index[kBlockFloats];
  for (size_t start = 0; start < num_points; start += kBlockPoints) {
    const size_t count = std::min<size_t>(kBlockPoints, num_points - start);
    const float* block = xyz + 3 * start;
    if (count < static_cast<size_t>(kBlockPoints)) {
      // Pad the last block with the box minimum: a valid input whose indices go unused.
      std::copy(block, block + 3 * count, tail);
      std::copy(lo_pattern + 3 * count, lo_pattern + kBlockFloats, tail + 3 * count);
      block = tail;
    }
    if (float_ok) {
      BlockIndices(block, lo_pattern, extent_pattern, static_cast<float>(n - 1), index);
    } else {
      BlockIndicesDouble(block, lo_d, extent_d, static_cast<double>(n - 1), index);
    }
    for (size_t p = 0; p < count; ++p) {
      const size_t j = static_cast<size_t>(index[3 * p]);
      const size_t i = static_cast<size_t>(index[3 * p + 1]);
      const int k = index[3 * p + 2];
      grid.bits[(i * n + j) * grid.words + k / 64] |= uint64_t{1} << (k % 64);
    }
  }
  return grid;
}

bool HardwarePopcountAvailable() {
#if defined(__x86_64__) || defined(__i386__)
  static const bool available = [] {
    __builtin_cpu_init();
    return __builtin_cpu_supports("popcnt") != 0;
  }();
  return available;
#else
  return false;
#endif
}

AllCounts CountCooccurrences(const PackedGrid& grid, PopcountPath path) {
  AllCounts counts;
#if defined(__x86_64__) || defined(__i386__)
  if (path == PopcountPath::kHardware && HardwarePopcountAvailable()) {
    CountHardware(grid, &counts);
    return counts;
  }
#else
  (void)path;
#endif
  CountPortable(grid, &counts);
  return counts;
}

void ComputeFeatures(const AllCounts& counts, absl::Span<float> out) {
  for (int d = 0; d < kNumDirections; ++d) {
    const auto& c = counts[d].counts;
    const double total = static_cast<double>(c[0][0] + c[0][1] + c[1][0] + c[1][1]);
    double p[2][2];
    for (int r = 0; r < 2; ++r) {
      for (int s = 0; s < 2; ++s) p[r][s] = static_cast<double>(c[r][s]) / total;
    }
    double entropy = 0, energy = 0, contrast = 0, homogeneity = 0, sum_rc = 0;
    for (int r = 0; r < 2; ++r) {
      for (int s = 0; s < 2; ++s) {
        const double v = p[r][s];
        if (v > 0) entropy -= v * std::log(v);
        energy += v * v;
        contrast += (r - s) * (r - s) * v;
        homogeneity += v / (1 + std::abs(r - s));
        sum_rc += r * v + s * v;
      }
    }
    const double mu = 0.5 * sum_rc;
    double spread = 0, covariance = 0;
    for (int r = 0; r < 2; ++r) {
      for (int s = 0; s < 2; ++s) {
        const double v = p[r][s];
        spread += (r - mu) * (r - mu) * v + (s - mu) * (s - mu) * v;
        covariance += (r - mu) * (s - mu) * v;
      }
    }
    const double variance = 0.5 * spread;
    // Variance 0 means every pair has the same value on both ends (all empty or all filled):
    // the correlation is 0/0 there, and the spec defines it as 0.
    const double correlation = variance > 0 ? covariance / variance : 0.0;
    const double features[kNumFeatures] = {entropy, energy,   contrast,   homogeneity,
                                           mu,      variance, correlation};
    for (int f = 0; f < kNumFeatures; ++f) {
      out[static_cast<size_t>(d) * kNumFeatures + f] = static_cast<float>(features[f]);
    }
  }
}

}  // namespace comsd_internal

DescriptorKind ComsdKind() {
  return {"comsd",
          "COMSD-3D: features of 13 co-occurrence matrices of a binary voxel grid (91 values)",
          {{"grid", "50",
            "voxel grid size N (N x N x N, each axis scaled to its extent); integer in [2, 512]"}},
          &comsd_internal::CreateComsd};
}

}  // namespace shapeid
