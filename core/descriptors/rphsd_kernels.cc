#include "core/descriptors/rphsd_kernels.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include "core/target_region.h"

#if defined(__x86_64__)
#include <immintrin.h>

#include "core/simd_ops.h"
#endif

// GCC 12's AVX-512 headers trip -Wmaybe-uninitialized on their own _mm512_undefined_*
// placeholders (a known false positive, GCC bug 105593).
SHAPEID_IGNORE_GCC_WARNING("-Wmaybe-uninitialized")

namespace shapeid::rphsd_internal {
namespace {

// Portable path. The vector paths below are this loop with the reference loop spread over
// SIMD lanes; each computes the bin indices of one point against all references into
// `slots` and then increments K histograms. The increments hit K different histograms, so
// consecutive read-modify-writes never wait on each other (no store-forwarding chain).
void AccumulateScalar(const HistogramInput& in, uint32_t* counts) {
  const int last_bin = in.bins - 1;
  for (size_t i = 0; i < in.num_points; ++i) {
    const float* p = in.xyz + 3 * i;
    const float px = (p[0] - in.center[0]) * in.inv_scale;
    const float py = (p[1] - in.center[1]) * in.inv_scale;
    const float pz = (p[2] - in.center[2]) * in.inv_scale;
    uint32_t* histogram = counts;
    for (size_t k = 0; k < in.num_refs; ++k, histogram += in.bins) {
      const float dx = px - in.ref_x[k];
      const float dy = py - in.ref_y[k];
      const float dz = pz - in.ref_z[k];
      const float d2 = (dx * dx + dy * dy) + dz * dz;
      const int bin = static_cast<int>(std::sqrt(d2) * in.bin_scale);
      ++histogram[std::min(bin, last_bin)];
    }
  }
}

#if defined(__x86_64__)

// The vector kernels: core/descriptors/rphsd_kernel_body.inc compiled once per instruction
// set, each copy inside its own target region and namespace, over that set's
// operations from core/simd_ops.h.
SHAPEID_TARGET_REGION_BEGIN("avx2")
namespace avx2 {
using Ops = simd::Avx2Ops;
#include "core/descriptors/rphsd_kernel_body.inc"

void Accumulate(const HistogramInput& in, uint32_t* counts) {
  switch ((in.num_refs + Ops::kLanes - 1) / Ops::kLanes) {
    case 1:
      return AccumulateVector<1>(in, counts);
    case 2:
      return AccumulateVector<2>(in, counts);
    case 3:
      return AccumulateVector<3>(in, counts);
    case 4:
      return AccumulateVector<4>(in, counts);
    default:
      return AccumulateVector<0>(in, counts);
  }
}
}  // namespace avx2
SHAPEID_TARGET_REGION_END

SHAPEID_TARGET_REGION_BEGIN("avx512f")
namespace avx512 {
using Ops = simd::Avx512Ops;
#include "core/descriptors/rphsd_kernel_body.inc"

void Accumulate(const HistogramInput& in, uint32_t* counts) {
  switch ((in.num_refs + Ops::kLanes - 1) / Ops::kLanes) {
    case 1:
      return AccumulateVector<1>(in, counts);
    case 2:
      return AccumulateVector<2>(in, counts);
    default:
      return AccumulateVector<0>(in, counts);
  }
}
}  // namespace avx512
SHAPEID_TARGET_REGION_END

#endif  // __x86_64__

}  // namespace

void AccumulateHistograms(const HistogramInput& input, uint32_t* counts, SimdLevel level) {
#if defined(__x86_64__)
  // With at most 8 references (cross7) a 16-lane vector is mostly padding, and the 8-lane
  // kernel measured faster (docs/performance.md); the results are the same bits either way.
  if (level == SimdLevel::kAvx512 && input.num_refs <= avx2::Ops::kLanes) level = SimdLevel::kAvx2;
  if (level == SimdLevel::kAvx512) return avx512::Accumulate(input, counts);
  if (level == SimdLevel::kAvx2) return avx2::Accumulate(input, counts);
#endif
  (void)level;
  AccumulateScalar(input, counts);
}

}  // namespace shapeid::rphsd_internal
