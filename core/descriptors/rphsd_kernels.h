#ifndef SHAPEID_CORE_DESCRIPTORS_RPHSD_KERNELS_H_
#define SHAPEID_CORE_DESCRIPTORS_RPHSD_KERNELS_H_

// The RPHSD hot loop: one distance and one histogram increment per (point, reference) pair.
// Internal to core; exposed for tests and benchmarks that compare SIMD levels.

#include <cstddef>
#include <cstdint>

#include "core/simd.h"

namespace shapeid::rphsd_internal {

// References are stored structure-of-arrays, padded with zeros to a multiple of this many
// lanes so every SIMD level loads whole vectors.
inline constexpr size_t kReferenceLanes = 16;

struct HistogramInput {
  const float* xyz = nullptr;  // n interleaved points
  size_t num_points = 0;
  // The point normalization of RPHSD step 1: p' = (p - center) * inv_scale.
  float center[3] = {0, 0, 0};
  float inv_scale = 1;
  const float* ref_x = nullptr;  // padded reference coordinates
  const float* ref_y = nullptr;
  const float* ref_z = nullptr;
  size_t num_refs = 0;  // K, real references (not counting padding)
  int bins = 0;         // M
  float bin_scale = 0;  // M / d_max, d_max = 2 sqrt(3)
};

// Adds every point to the K histograms `counts` (K * M counters, reference-major), which the
// caller zeroes. For each pair, in this exact float order on every level:
//   p' = (p - center) * inv_scale;  d = (p' - q);  d2 = (dx*dx + dy*dy) + dz*dz;
//   bin = min(int(sqrt(d2) * bin_scale), M - 1).
// So all levels give identical counts. `level` must not exceed DetectedSimdLevel().
void AccumulateHistograms(const HistogramInput& input, uint32_t* counts, SimdLevel level);

}  // namespace shapeid::rphsd_internal

#endif  // SHAPEID_CORE_DESCRIPTORS_RPHSD_KERNELS_H_
