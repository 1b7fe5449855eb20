#include "core/knn/knn_kernels.h"

#if defined(__linux__)
#include <sys/mman.h>
#endif

#if defined(__x86_64__) || defined(__i386__)
#include <immintrin.h>
#define SHAPEID_KNN_X86 1
#endif

namespace shapeid {
namespace knn_internal {

void AdviseHugePages(void* p, std::size_t bytes) {
#if defined(__linux__)
  madvise(p, bytes, MADV_HUGEPAGE);
#else
  (void)p;
  (void)bytes;
#endif
}

namespace {

int64_t NumBlocks(int64_t size) { return (size + kBlockLanes - 1) / kBlockLanes; }

// Lanes of block b that hold samples (all but the padding of the last block).
unsigned ValidLaneMask(const BlockedView& v, int64_t b) {
  static_assert(kBlockLanes == 32, "lane masks are 32-bit");
  const int64_t lanes = v.size - b * kBlockLanes;
  return lanes >= kBlockLanes ? ~0u : (1u << lanes) - 1u;
}

// Offers the lanes of `mask` (ascending) whose distance still beats the k-th. The k-th can
// tighten while a block is being emitted, hence the re-check.
inline void EmitLanes(const float* dist, int64_t base_slot, unsigned mask, TopK* top) {
  while (mask != 0) {
    const int lane = __builtin_ctz(mask);
    mask &= mask - 1;
    if (!top->full() || dist[lane] < top->threshold()) top->Offer(dist[lane], base_slot + lane);
  }
}

// Portable path: the compiler may vectorise the lane loop (lanes are independent, so the
// per-lane operation order is unchanged).
template <bool kScaled>
void ScanScalar(const BlockedView& v, const float* query, const float* scale, TopK* top) {
  const int d = v.dim;
  const int64_t num_blocks = NumBlocks(v.size);
  alignas(kStorageAlignment) float acc[kBlockLanes];
  for (int64_t b = 0; b < num_blocks; ++b) {
    const float* x = v.data + static_cast<std::size_t>(b) * BlockFloats(d);
    for (int l = 0; l < kBlockLanes; ++l) acc[l] = 0.0f;
    for (int j = 0; j < d; ++j) {
      const float qj = query[j];
      const float sj = kScaled ? scale[j] : 1.0f;
      const float* xj = x + static_cast<std::size_t>(j) * kBlockLanes;
      for (int l = 0; l < kBlockLanes; ++l) {
        float e = qj - xj[l];
        if (kScaled) e = e * sj;
        acc[l] = acc[l] + e * e;
      }
    }
    unsigned mask = ValidLaneMask(v, b);
    if (top->full()) {
      const float t = top->threshold();
      for (int l = 0; l < kBlockLanes; ++l) {
        if (!(acc[l] < t)) mask &= ~(1u << l);
      }
    }
    EmitLanes(acc, b * kBlockLanes, mask, top);
  }
}

#ifdef SHAPEID_KNN_X86

// AVX2: a block is four 8-lane registers per dimension, four independent add chains.
__attribute__((target("avx2"))) inline unsigned LessMaskAvx2(__m256 v, __m256 t) {
  return static_cast<unsigned>(_mm256_movemask_ps(_mm256_cmp_ps(v, t, _CMP_LT_OQ)));
}

template <bool kScaled>
__attribute__((target("avx2"))) inline __m256 StepAvx2(__m256 qj, __m256 sj, const float* x,
                                                       __m256 acc) {
  __m256 e = _mm256_sub_ps(qj, _mm256_load_ps(x));
  if (kScaled) e = _mm256_mul_ps(e, sj);
  return _mm256_add_ps(acc, _mm256_mul_ps(e, e));
}

template <bool kScaled>
__attribute__((target("avx2"))) void ScanAvx2(const BlockedView& v, const float* query,
                                              const float* scale, TopK* top) {
  const int d = v.dim;
  const int64_t num_blocks = NumBlocks(v.size);
  const __m256 one = _mm256_set1_ps(1.0f);
  alignas(kStorageAlignment) float dist[kBlockLanes];
  for (int64_t b = 0; b < num_blocks; ++b) {
    const float* x = v.data + static_cast<std::size_t>(b) * BlockFloats(d);
    __m256 a0 = _mm256_setzero_ps(), a1 = _mm256_setzero_ps();
    __m256 a2 = _mm256_setzero_ps(), a3 = _mm256_setzero_ps();
    for (int j = 0; j < d; ++j, x += kBlockLanes) {
      const __m256 qj = _mm256_set1_ps(query[j]);
      const __m256 sj = kScaled ? _mm256_set1_ps(scale[j]) : one;
      a0 = StepAvx2<kScaled>(qj, sj, x, a0);
      a1 = StepAvx2<kScaled>(qj, sj, x + 8, a1);
      a2 = StepAvx2<kScaled>(qj, sj, x + 16, a2);
      a3 = StepAvx2<kScaled>(qj, sj, x + 24, a3);
    }
    unsigned mask = ValidLaneMask(v, b);
    if (top->full()) {
      const __m256 t = _mm256_set1_ps(top->threshold());
      mask &= LessMaskAvx2(a0, t) | LessMaskAvx2(a1, t) << 8 | LessMaskAvx2(a2, t) << 16 |
              LessMaskAvx2(a3, t) << 24;
    }
    if (mask == 0) continue;
    _mm256_store_ps(dist, a0);
    _mm256_store_ps(dist + 8, a1);
    _mm256_store_ps(dist + 16, a2);
    _mm256_store_ps(dist + 24, a3);
    EmitLanes(dist, b * kBlockLanes, mask, top);
  }
}

// AVX-512: a block is two registers per dimension, two independent add chains.
template <bool kScaled>
__attribute__((target("avx512f"))) inline __m512 StepAvx512(__m512 qj, __m512 sj, const float* x,
                                                            __m512 acc) {
  __m512 e = _mm512_sub_ps(qj, _mm512_load_ps(x));
  if (kScaled) e = _mm512_mul_ps(e, sj);
  return _mm512_add_ps(acc, _mm512_mul_ps(e, e));
}

template <bool kScaled>
__attribute__((target("avx512f"))) void ScanAvx512(const BlockedView& v, const float* query,
                                                   const float* scale, TopK* top) {
  const int d = v.dim;
  const int64_t num_blocks = NumBlocks(v.size);
  const __m512 one = _mm512_set1_ps(1.0f);
  alignas(kStorageAlignment) float dist[kBlockLanes];
  for (int64_t b = 0; b < num_blocks; ++b) {
    const float* x = v.data + static_cast<std::size_t>(b) * BlockFloats(d);
    __m512 a0 = _mm512_setzero_ps();
    __m512 a1 = _mm512_setzero_ps();
    for (int j = 0; j < d; ++j, x += kBlockLanes) {
      const __m512 qj = _mm512_set1_ps(query[j]);
      const __m512 sj = kScaled ? _mm512_set1_ps(scale[j]) : one;
      a0 = StepAvx512<kScaled>(qj, sj, x, a0);
      a1 = StepAvx512<kScaled>(qj, sj, x + 16, a1);
    }
    unsigned mask = ValidLaneMask(v, b);
    if (top->full()) {
      const __m512 t = _mm512_set1_ps(top->threshold());
      const unsigned lo = _mm512_cmp_ps_mask(a0, t, _CMP_LT_OQ);
      const unsigned hi = _mm512_cmp_ps_mask(a1, t, _CMP_LT_OQ);
      mask &= lo | hi << 16;
    }
    if (mask == 0) continue;
    _mm512_store_ps(dist, a0);
    _mm512_store_ps(dist + 16, a1);
    EmitLanes(dist, b * kBlockLanes, mask, top);
  }
}

#endif  // SHAPEID_KNN_X86

}  // namespace

void ScanBlocks(SimdLevel level, const BlockedView& view, const float* query, const float* scale,
                TopK* top) {
  if (view.size <= 0) return;
  const bool scaled = scale != nullptr;
#ifdef SHAPEID_KNN_X86
  switch (level) {
    case SimdLevel::kAvx512:
      return scaled ? ScanAvx512<true>(view, query, scale, top)
                    : ScanAvx512<false>(view, query, scale, top);
    case SimdLevel::kAvx2:
      return scaled ? ScanAvx2<true>(view, query, scale, top)
                    : ScanAvx2<false>(view, query, scale, top);
    case SimdLevel::kScalar:
      break;
  }
#else
  (void)level;
#endif
  return scaled ? ScanScalar<true>(view, query, scale, top)
                : ScanScalar<false>(view, query, scale, top);
}

float DistanceSq(const float* query, const float* scale, const float* x, std::ptrdiff_t stride,
                 int dim) {
  float acc = 0.0f;
  for (int j = 0; j < dim; ++j) {
    float e = query[j] - x[j * stride];
    if (scale != nullptr) e = e * scale[j];
    acc = acc + e * e;
  }
  return acc;
}

}  // namespace knn_internal
}  // namespace shapeid
