#include "core/descriptors/point_network_kernels.h"

#include "core/target_region.h"

#if defined(__x86_64__)
#include <immintrin.h>

#include "core/simd_ops.h"
#endif

// GCC 12's AVX-512 headers trip -Wmaybe-uninitialized on their own _mm512_undefined_*
// placeholders (a known false positive, GCC bug 105593).
SHAPEID_IGNORE_GCC_WARNING("-Wmaybe-uninitialized")

namespace shapeid::point_network_internal {
namespace {

// One point at a time, with the vector sets' semantics: Max(a, b) is maxps's, a if a > b
// else b (so max(-0, +0) is +0, as in the vector kernels).
struct ScalarOps {
  using Vec = float;
  static constexpr size_t kLanes = 1;
  static Vec Set1(float v) { return v; }
  static Vec Load(const float* p) { return *p; }
  static Vec Add(Vec a, Vec b) { return a + b; }
  static Vec Mul(Vec a, Vec b) { return a * b; }
  static Vec Max(Vec a, Vec b) { return a > b ? a : b; }
  static void Store(float* p, Vec v) { *p = v; }
};

namespace scalar {
using Ops = ScalarOps;
#include "core/descriptors/point_network_kernel_body.inc"
}  // namespace scalar

#if defined(__x86_64__)

SHAPEID_TARGET_REGION_BEGIN("avx2")
namespace avx2 {
using Ops = simd::Avx2Ops;
#include "core/descriptors/point_network_kernel_body.inc"
}  // namespace avx2
SHAPEID_TARGET_REGION_END

SHAPEID_TARGET_REGION_BEGIN("avx512f")
namespace avx512 {
using Ops = simd::Avx512Ops;
#include "core/descriptors/point_network_kernel_body.inc"
}  // namespace avx512
SHAPEID_TARGET_REGION_END

#endif  // __x86_64__

}  // namespace

void DenseReluLayer(const LayerInput& input, float* out, float* pooled, SimdLevel level) {
#if defined(__x86_64__)
  if (level == SimdLevel::kAvx512) return avx512::Kernel(input, out, pooled);
  if (level == SimdLevel::kAvx2) return avx2::Kernel(input, out, pooled);
#endif
  (void)level;
  scalar::Kernel(input, out, pooled);
}

}  // namespace shapeid::point_network_internal
