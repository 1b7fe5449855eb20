#ifndef SHAPEID_CORE_DESCRIPTORS_CNSD_KERNELS_H_
#define SHAPEID_CORE_DESCRIPTORS_CNSD_KERNELS_H_

// The CNSD-3D hot loops, the two passes over all pairs of points: the largest squared
// distance, then each pair's bucket among the threshold bounds, reduced to degree sums and
// maxima. Internal to core; exposed for tests and benchmarks that compare SIMD levels.
//
// A pair's squared distance is (dx*dx + dy*dy) + dz*dz in float, dx = x[j] - x[i], on every
// level and for both passes, and the bucket comparison is exact, so every level gives the
// same bits.

#include <cstddef>
#include <cstdint>

#include "absl/types/span.h"
#include "core/simd.h"

namespace shapeid::cnsd_internal {

// The largest squared distance over the pairs i < j of the interleaved points `xyz`
// (0 for fewer than 2 points). `level` must not exceed DetectedSimdLevel().
float MaxSquaredDistance(absl::Span<const float> xyz, SimdLevel level);

// How a squared distance d2 maps to thresholds. Bucket b = the number of bounds below d2:
// the pair is joined at thresholds b..S-1 (b = S: at none).
struct BucketRule {
  // S squared bounds, ascending (SquaredThreshold of each threshold).
  absl::Span<const float> bounds;
  // a = floor(sqrt(d2) * scale + offset), clamped to [0, S], must be b or b - 1 for every d2
  // when `approximate` is set: then the vector kernels find b = a + (d2 > bound[a]) with one
  // lookup. For thresholds t_start + k t_step, scale = 1 / (d_max t_step) and
  // offset = 0.5 - t_start / t_step make a the nearest k to (sqrt(d2) / d_max - t_start) /
  // t_step, and float errors stay under 0.01 of a bucket for t_step >= 1e-4. Otherwise the
  // scalar kernel runs whatever the level, walking from a to b.
  float scale = 0;
  float offset = 0;
  bool approximate = false;
};

// For each threshold k < S, over the vertices v of the graph on `xyz` (no self-loops):
// degree_sum[k] = sum of deg_k(v) and degree_max[k] = max of deg_k(v), where deg_k(v) counts
// the other points whose bucket with v is <= k. Both spans have S entries. `level` must not
// exceed DetectedSimdLevel(). Time O(n^2 + n S); memory O(n S) up to S = 31, where each pair
// is measured once, and O(n + S) beyond, where it is measured from both ends.
void DegreeStatistics(absl::Span<const float> xyz, const BucketRule& rule, SimdLevel level,
                      absl::Span<uint64_t> degree_sum, absl::Span<uint64_t> degree_max);

// The most heap MaxSquaredDistance or DegreeStatistics allocates for n points and S
// thresholds, whichever kernel runs.
size_t PairPassBytes(size_t n, size_t num_thresholds);

}  // namespace shapeid::cnsd_internal

#endif  // SHAPEID_CORE_DESCRIPTORS_CNSD_KERNELS_H_
