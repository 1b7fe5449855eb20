#include "core/descriptors/dfsd_kernels.h"

#include <algorithm>
#include <vector>

#include "core/target_region.h"

#if defined(__x86_64__)
#include <immintrin.h>

#include "core/simd_ops.h"
#endif

// GCC 12's AVX-512 headers trip -Wmaybe-uninitialized on their own _mm512_undefined_*
// placeholders (a known false positive, GCC bug 105593).
SHAPEID_IGNORE_GCC_WARNING("-Wmaybe-uninitialized")

namespace shapeid::dfsd_internal {
namespace {

// Portable path: the same sums in the same order as the vector kernels, one cell at a time.
void KernelScalar(const FieldInput& in, float* out) {
  const size_t stride = in.stride;
  const int g = in.grid;
  std::vector<float> xy(stride);
  for (int i = 0; i < g; ++i) {
    const float* dx2 = in.dx2 + static_cast<size_t>(i) * stride;
    for (int j = 0; j < g; ++j) {
      const float* dy2 = in.dy2 + static_cast<size_t>(j) * stride;
      for (size_t p = 0; p < stride; ++p) xy[p] = dx2[p] + dy2[p];
      float* column = out + (static_cast<size_t>(i) * g + j) * g;
      for (int k = 0; k < g; ++k) {
        const float* z = in.dz2 + static_cast<size_t>(k) * stride;
        float m = in.accumulate ? column[k] : kFarSquared;
        for (size_t p = 0; p < stride; ++p) m = std::min(m, xy[p] + z[p]);
        column[k] = m;
      }
    }
  }
}

#if defined(__x86_64__)

// core/descriptors/dfsd_kernel_body.inc compiled once per instruction set, each copy inside
// its own target region and namespace, over that set's operations.
SHAPEID_TARGET_REGION_BEGIN("avx2")
namespace avx2 {
using Ops = simd::Avx2Ops;
#include "core/descriptors/dfsd_kernel_body.inc"
}  // namespace avx2
SHAPEID_TARGET_REGION_END

SHAPEID_TARGET_REGION_BEGIN("avx512f")
namespace avx512 {
using Ops = simd::Avx512Ops;
#include "core/descriptors/dfsd_kernel_body.inc"
}  // namespace avx512
SHAPEID_TARGET_REGION_END

#endif  // __x86_64__

}  // namespace

void NearestSquaredDistances(const FieldInput& input, float* out, SimdLevel level) {
#if defined(__x86_64__)
  if (level == SimdLevel::kAvx512) return avx512::Kernel(input, out);
  if (level == SimdLevel::kAvx2) return avx2::Kernel(input, out);
#endif
  (void)level;
  KernelScalar(input, out);
}

}  // namespace shapeid::dfsd_internal
