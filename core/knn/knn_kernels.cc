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

void TopK::Offer(float distance_sq, int64_t row, int query) {
  const Candidate c{distance_sq, row, query};
  if (full() && !Before(c, heap_.front())) return;
  if (grouped_) {
    // A group keeps one entry, its best. A linear scan is fine: k is small and only
    // candidates that beat the k-th get here.
    const int64_t group = GroupOf(row);
    for (Candidate& kept : heap_) {
      if (GroupOf(kept.row) != group) continue;
      if (Before(c, kept)) {
        kept = c;
        SiftDown(static_cast<std::size_t>(&kept - heap_.data()));
      }
      return;
    }
  }
  if (full()) {
    std::pop_heap(heap_.begin(), heap_.end(), kBefore);
    heap_.back() = c;
  } else {
    heap_.push_back(c);
  }
  std::push_heap(heap_.begin(), heap_.end(), kBefore);
}

void TopK::SiftDown(std::size_t i) {
  const std::size_t n = heap_.size();
  for (std::size_t child = 2 * i + 1; child < n; i = child, child = 2 * i + 1) {
    if (child + 1 < n && Before(heap_[child], heap_[child + 1])) ++child;
    if (!Before(heap_[i], heap_[child])) return;
    std::swap(heap_[i], heap_[child]);
  }
}

namespace {

int64_t NumBlocks(int64_t size) { return (size + kBlockLanes - 1) / kBlockLanes; }

// Lanes of block b that hold rows (all but the padding of the last block).
unsigned ValidLaneMask(const BlockedView& v, int64_t b) {
  static_assert(kBlockLanes == 32, "lane masks are 32-bit");
  const int64_t lanes = v.size - b * kBlockLanes;
  return lanes >= kBlockLanes ? ~0u : (1u << lanes) - 1u;
}

// Offers the lanes of `mask` (ascending) that are still within the limit. The limit can
// tighten while a block is being emitted, hence the re-check.
inline void EmitLanes(const float* dist, const BlockedView& v, int64_t block, int query,
                      unsigned mask, TopK* top) {
  while (mask != 0) {
    const int lane = __builtin_ctz(mask);
    mask &= mask - 1;
    if (dist[lane] <= top->limit())
      top->Offer(dist[lane], v.RowId(block * kBlockLanes + lane), query);
  }
}

// Each kernel below scans block by block and, inside a block, query by query: the block
// is read from memory once and stays in cache for the other queries, and each query is
// abandoned against the limit the earlier ones (and earlier blocks) have set. The limit
// is read once per (block, query); it only tightens, so a stale one is merely less
// selective. The dimension loop stops to test for abandonment after `first_check`
// dimensions (kAbandonFirstCheck, or dim when abandonment is off), then after twice as
// many, and so on while a quarter of the block is left. The test looks at all 32 lanes,
// padding included: padding can only keep the last block alive, which costs nothing in
// exactness.

// Portable path: the compiler may vectorise the lane loops (lanes are independent, so the
// per-lane operation order is unchanged).
bool AnyAtMostScalar(const float* acc, float limit) {
  unsigned any = 0;
  for (int l = 0; l < kBlockLanes; ++l) any |= static_cast<unsigned>(acc[l] <= limit);
  return any != 0;
}

unsigned AtMostMaskScalar(const float* acc, float limit) {
  unsigned mask = 0;
  for (int l = 0; l < kBlockLanes; ++l) mask |= static_cast<unsigned>(acc[l] <= limit) << l;
  return mask;
}

template <bool kScaled>
void ScanScalar(const BlockedView& v, const float* queries, int num_queries, const float* scale,
                int first_check, TopK* top, const int* query_ids) {
  const int d = v.dim;
  const int64_t num_blocks = NumBlocks(v.size);
  alignas(kStorageAlignment) float acc[kBlockLanes];
  for (int64_t b = 0; b < num_blocks; ++b) {
    const float* block = v.data + static_cast<std::size_t>(b) * BlockFloats(d);
    const unsigned valid = ValidLaneMask(v, b);
    for (int q = 0; q < num_queries; ++q) {
      const float* query = queries + static_cast<std::size_t>(q) * d;
      const float limit = top->limit();
      for (int l = 0; l < kBlockLanes; ++l) acc[l] = 0.0f;
      int j = 0;
      for (int check = first_check;; check *= 2) {
        for (const int end = 4 * check <= 3 * d ? check : d; j < end; ++j) {
          const float qj = query[j];
          const float sj = kScaled ? scale[j] : 1.0f;
          const float* xj = block + static_cast<std::size_t>(j) * kBlockLanes;
          for (int l = 0; l < kBlockLanes; ++l) {
            float e = qj - xj[l];
            if (kScaled) e = e * sj;
            acc[l] = acc[l] + e * e;
          }
        }
        if (j == d || !AnyAtMostScalar(acc, limit)) break;
      }
      if (j < d) continue;  // abandoned
      EmitLanes(acc, v, b, query_ids != nullptr ? query_ids[q] : q,
                valid & AtMostMaskScalar(acc, limit), top);
    }
  }
}

#ifdef SHAPEID_KNN_X86

// AVX2: a block is four 8-lane registers per dimension, four independent add chains.
__attribute__((target("avx2"))) inline unsigned AtMostMaskAvx2(__m256 a0, __m256 a1, __m256 a2,
                                                               __m256 a3, __m256 t) {
  return static_cast<unsigned>(_mm256_movemask_ps(_mm256_cmp_ps(a0, t, _CMP_LE_OQ))) |
         static_cast<unsigned>(_mm256_movemask_ps(_mm256_cmp_ps(a1, t, _CMP_LE_OQ))) << 8 |
         static_cast<unsigned>(_mm256_movemask_ps(_mm256_cmp_ps(a2, t, _CMP_LE_OQ))) << 16 |
         static_cast<unsigned>(_mm256_movemask_ps(_mm256_cmp_ps(a3, t, _CMP_LE_OQ))) << 24;
}

__attribute__((target("avx2"))) inline bool AnyAtMostAvx2(__m256 a0, __m256 a1, __m256 a2,
                                                          __m256 a3, __m256 t) {
  const __m256 m = _mm256_or_ps(
      _mm256_or_ps(_mm256_cmp_ps(a0, t, _CMP_LE_OQ), _mm256_cmp_ps(a1, t, _CMP_LE_OQ)),
      _mm256_or_ps(_mm256_cmp_ps(a2, t, _CMP_LE_OQ), _mm256_cmp_ps(a3, t, _CMP_LE_OQ)));
  return _mm256_movemask_ps(m) != 0;
}

template <bool kScaled>
__attribute__((target("avx2"))) inline __m256 StepAvx2(__m256 qj, __m256 sj, const float* x,
                                                       __m256 acc) {
  __m256 e = _mm256_sub_ps(qj, _mm256_load_ps(x));
  if (kScaled) e = _mm256_mul_ps(e, sj);
  return _mm256_add_ps(acc, _mm256_mul_ps(e, e));
}

template <bool kScaled>
__attribute__((target("avx2"))) void ScanAvx2(const BlockedView& v, const float* queries,
                                              int num_queries, const float* scale, int first_check,
                                              TopK* top, const int* query_ids) {
  const int d = v.dim;
  const int64_t num_blocks = NumBlocks(v.size);
  const __m256 one = _mm256_set1_ps(1.0f);
  alignas(kStorageAlignment) float dist[kBlockLanes];
  for (int64_t b = 0; b < num_blocks; ++b) {
    const float* block = v.data + static_cast<std::size_t>(b) * BlockFloats(d);
    const unsigned valid = ValidLaneMask(v, b);
    for (int q = 0; q < num_queries; ++q) {
      const float* query = queries + static_cast<std::size_t>(q) * d;
      const __m256 limit = _mm256_set1_ps(top->limit());
      __m256 a0 = _mm256_setzero_ps(), a1 = _mm256_setzero_ps();
      __m256 a2 = _mm256_setzero_ps(), a3 = _mm256_setzero_ps();
      const float* x = block;
      int j = 0;
      for (int check = first_check;; check *= 2) {
        for (const int end = 4 * check <= 3 * d ? check : d; j < end; ++j, x += kBlockLanes) {
          const __m256 qj = _mm256_set1_ps(query[j]);
          const __m256 sj = kScaled ? _mm256_set1_ps(scale[j]) : one;
          a0 = StepAvx2<kScaled>(qj, sj, x, a0);
          a1 = StepAvx2<kScaled>(qj, sj, x + 8, a1);
          a2 = StepAvx2<kScaled>(qj, sj, x + 16, a2);
          a3 = StepAvx2<kScaled>(qj, sj, x + 24, a3);
        }
        if (j == d || !AnyAtMostAvx2(a0, a1, a2, a3, limit)) break;
      }
      if (j < d) continue;  // abandoned
      const unsigned mask = valid & AtMostMaskAvx2(a0, a1, a2, a3, limit);
      if (mask == 0) continue;
      _mm256_store_ps(dist, a0);
      _mm256_store_ps(dist + 8, a1);
      _mm256_store_ps(dist + 16, a2);
      _mm256_store_ps(dist + 24, a3);
      EmitLanes(dist, v, b, query_ids != nullptr ? query_ids[q] : q, mask, top);
    }
  }
}

// AVX-512: a block is two registers per dimension, two independent add chains.
__attribute__((target("avx512f"))) inline unsigned AtMostMaskAvx512(__m512 a0, __m512 a1,
                                                                    __m512 t) {
  return static_cast<unsigned>(_mm512_cmp_ps_mask(a0, t, _CMP_LE_OQ)) |
         static_cast<unsigned>(_mm512_cmp_ps_mask(a1, t, _CMP_LE_OQ)) << 16;
}

__attribute__((target("avx512f"))) inline bool AnyAtMostAvx512(__m512 a0, __m512 a1, __m512 t) {
  return (_mm512_cmp_ps_mask(a0, t, _CMP_LE_OQ) | _mm512_cmp_ps_mask(a1, t, _CMP_LE_OQ)) != 0;
}

template <bool kScaled>
__attribute__((target("avx512f"))) inline __m512 StepAvx512(__m512 qj, __m512 sj, const float* x,
                                                            __m512 acc) {
  __m512 e = _mm512_sub_ps(qj, _mm512_load_ps(x));
  if (kScaled) e = _mm512_mul_ps(e, sj);
  return _mm512_add_ps(acc, _mm512_mul_ps(e, e));
}

template <bool kScaled>
__attribute__((target("avx512f"))) void ScanAvx512(const BlockedView& v, const float* queries,
                                                   int num_queries, const float* scale,
                                                   int first_check, TopK* top,
                                                   const int* query_ids) {
  const int d = v.dim;
  const int64_t num_blocks = NumBlocks(v.size);
  const __m512 one = _mm512_set1_ps(1.0f);
  alignas(kStorageAlignment) float dist[kBlockLanes];
  for (int64_t b = 0; b < num_blocks; ++b) {
    const float* block = v.data + static_cast<std::size_t>(b) * BlockFloats(d);
    const unsigned valid = ValidLaneMask(v, b);
    for (int q = 0; q < num_queries; ++q) {
      const float* query = queries + static_cast<std::size_t>(q) * d;
      const __m512 limit = _mm512_set1_ps(top->limit());
      __m512 a0 = _mm512_setzero_ps();
      __m512 a1 = _mm512_setzero_ps();
      const float* x = block;
      int j = 0;
      for (int check = first_check;; check *= 2) {
        for (const int end = 4 * check <= 3 * d ? check : d; j < end; ++j, x += kBlockLanes) {
          const __m512 qj = _mm512_set1_ps(query[j]);
          const __m512 sj = kScaled ? _mm512_set1_ps(scale[j]) : one;
          a0 = StepAvx512<kScaled>(qj, sj, x, a0);
          a1 = StepAvx512<kScaled>(qj, sj, x + 16, a1);
        }
        if (j == d || !AnyAtMostAvx512(a0, a1, limit)) break;
      }
      if (j < d) continue;  // abandoned
      const unsigned mask = valid & AtMostMaskAvx512(a0, a1, limit);
      if (mask == 0) continue;
      _mm512_store_ps(dist, a0);
      _mm512_store_ps(dist + 16, a1);
      EmitLanes(dist, v, b, query_ids != nullptr ? query_ids[q] : q, mask, top);
    }
  }
}

#endif  // SHAPEID_KNN_X86

}  // namespace

void ScanBlocks(SimdLevel level, const BlockedView& view, const float* queries, int num_queries,
                const float* scale, bool abandon, TopK* top, const int* query_ids) {
  if (view.size <= 0) return;
  const int first_check = abandon ? kAbandonFirstCheck : view.dim;
#ifdef SHAPEID_KNN_X86
  switch (level) {
    case SimdLevel::kAvx512:
      return scale != nullptr
                 ? ScanAvx512<true>(view, queries, num_queries, scale, first_check, top, query_ids)
                 : ScanAvx512<false>(view, queries, num_queries, scale, first_check, top,
                                     query_ids);
    case SimdLevel::kAvx2:
      return scale != nullptr
                 ? ScanAvx2<true>(view, queries, num_queries, scale, first_check, top, query_ids)
                 : ScanAvx2<false>(view, queries, num_queries, scale, first_check, top, query_ids);
    case SimdLevel::kScalar:
      break;
  }
#else
  (void)level;
#endif
  return scale != nullptr
             ? ScanScalar<true>(view, queries, num_queries, scale, first_check, top, query_ids)
             : ScanScalar<false>(view, queries, num_queries, scale, first_check, top, query_ids);
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
