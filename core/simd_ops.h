#ifndef SHAPEID_CORE_SIMD_OPS_H_
#define SHAPEID_CORE_SIMD_OPS_H_

// The vector operations that shapeid's kernels share, one struct per instruction set, so a
// kernel body written once against `Ops::Add`, `Ops::Load`... compiles for each set (see
// core/descriptors/rphsd_kernels.cc). Each struct is defined under its own
// `SHAPEID_TARGET_REGION_BEGIN`, so it may only be used from functions compiled for that set, which
// run after dispatch on ActiveSimdLevel() (core/simd.h). A kernel that needs more derives
// from these structs inside its own target region.
//
// Only plain IEEE operations (no FMA, no approximations): every set gives the same bits.

#if defined(__x86_64__)

#include <immintrin.h>

#include <cstddef>
#include <cstdint>

#include "core/target_region.h"

namespace shapeid::simd {

SHAPEID_TARGET_REGION_BEGIN("avx2")
struct Avx2Ops {
  using Vec = __m256;
  using IVec = __m256i;
  static constexpr size_t kLanes = 8;
  static Vec Set1(float v) { return _mm256_set1_ps(v); }
  static Vec Load(const float* p) { return _mm256_loadu_ps(p); }
  static Vec Add(Vec a, Vec b) { return _mm256_add_ps(a, b); }
  static Vec Sub(Vec a, Vec b) { return _mm256_sub_ps(a, b); }
  static Vec Mul(Vec a, Vec b) { return _mm256_mul_ps(a, b); }
  static Vec Max(Vec a, Vec b) { return _mm256_max_ps(a, b); }
  static Vec Min(Vec a, Vec b) { return _mm256_min_ps(a, b); }
  // Bit l set where a[l] <= b[l] (false for NaN).
  static uint32_t LessEqualMask(Vec a, Vec b) {
    return static_cast<uint32_t>(_mm256_movemask_ps(_mm256_cmp_ps(a, b, _CMP_LE_OQ)));
  }
  // The smallest lane (a tree of pairwise minima: exact, so any order gives the same bits).
  static float HorizontalMin(Vec v) {
    __m128 m = _mm_min_ps(_mm256_castps256_ps128(v), _mm256_extractf128_ps(v, 1));
    m = _mm_min_ps(m, _mm_movehl_ps(m, m));
    m = _mm_min_ss(m, _mm_shuffle_ps(m, m, 1));
    return _mm_cvtss_f32(m);
  }
  static void Store(float* p, Vec v) { _mm256_storeu_ps(p, v); }
  static Vec Sqrt(Vec a) { return _mm256_sqrt_ps(a); }
  static IVec Truncate(Vec a) { return _mm256_cvttps_epi32(a); }  // toward zero
  // 32-bit integer lanes; int32_t and uint32_t arrays alike.
  static IVec Set1I(uint32_t v) { return _mm256_set1_epi32(static_cast<int>(v)); }
  template <typename T>
  static IVec LoadI(const T* p) {
    static_assert(sizeof(T) == 4);
    return _mm256_loadu_si256(reinterpret_cast<const __m256i*>(p));
  }
  template <typename T>
  static void StoreI(T* p, IVec v) {
    static_assert(sizeof(T) == 4);
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(p), v);
  }
  static IVec AddI(IVec a, IVec b) { return _mm256_add_epi32(a, b); }
  static IVec AndI(IVec a, IVec b) { return _mm256_and_si256(a, b); }
  static IVec MinI(IVec a, IVec b) { return _mm256_min_epi32(a, b); }  // signed
  template <int kBits>
  static IVec SrliI(IVec a) {
    return _mm256_srli_epi32(a, kBits);
  }
};
SHAPEID_TARGET_REGION_END

SHAPEID_TARGET_REGION_BEGIN("avx512f")
#pragma GCC diagnostic push
// GCC 12's AVX-512 headers trip these on their own placeholders (GCC bug 105593).
SHAPEID_IGNORE_GCC_WARNING("-Wmaybe-uninitialized")
SHAPEID_IGNORE_GCC_WARNING("-Wuninitialized")
struct Avx512Ops {
  using Vec = __m512;
  using IVec = __m512i;
  static constexpr size_t kLanes = 16;
  static Vec Set1(float v) { return _mm512_set1_ps(v); }
  static Vec Load(const float* p) { return _mm512_loadu_ps(p); }
  static Vec Add(Vec a, Vec b) { return _mm512_add_ps(a, b); }
  static Vec Sub(Vec a, Vec b) { return _mm512_sub_ps(a, b); }
  static Vec Mul(Vec a, Vec b) { return _mm512_mul_ps(a, b); }
  static Vec Max(Vec a, Vec b) { return _mm512_max_ps(a, b); }
  static Vec Min(Vec a, Vec b) { return _mm512_min_ps(a, b); }
  static uint32_t LessEqualMask(Vec a, Vec b) {
    return static_cast<uint32_t>(_mm512_cmp_ps_mask(a, b, _CMP_LE_OQ));
  }
  static float HorizontalMin(Vec v) { return _mm512_reduce_min_ps(v); }
  static void Store(float* p, Vec v) { _mm512_storeu_ps(p, v); }
  static Vec Sqrt(Vec a) { return _mm512_sqrt_ps(a); }
  static IVec Truncate(Vec a) { return _mm512_cvttps_epi32(a); }
  static IVec Set1I(uint32_t v) { return _mm512_set1_epi32(static_cast<int>(v)); }
  template <typename T>
  static IVec LoadI(const T* p) {
    static_assert(sizeof(T) == 4);
    return _mm512_loadu_si512(p);
  }
  template <typename T>
  static void StoreI(T* p, IVec v) {
    static_assert(sizeof(T) == 4);
    _mm512_storeu_si512(p, v);
  }
  static IVec AddI(IVec a, IVec b) { return _mm512_add_epi32(a, b); }
  static IVec AndI(IVec a, IVec b) { return _mm512_and_si512(a, b); }
  static IVec MinI(IVec a, IVec b) { return _mm512_min_epi32(a, b); }
  template <int kBits>
  static IVec SrliI(IVec a) {
    return _mm512_srli_epi32(a, kBits);
  }
};
#pragma GCC diagnostic pop
SHAPEID_TARGET_REGION_END

}  // namespace shapeid::simd

#endif  // __x86_64__

#endif  // SHAPEID_CORE_SIMD_OPS_H_
