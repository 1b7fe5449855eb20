// A measurement aid for bench/faiss (target faiss_knn_bench_avx2): Debian's libfaiss.a (1.7.3) is
// built for baseline x86-64, so its fvec_L2sqr and fvec_norm_L2sqr are scalar loops (fvec_*_ref).
// Upstream's AVX2 build ("faiss_avx2", what pip/conda ship) computes them with one 8-wide
// accumulator of sub/mul/add, a 4-wide step, a masked tail and a horizontal sum. These two
// definitions do the same and are linked ahead of libfaiss.a with -Wl,--allow-multiple-definition,
// so every Faiss path that computes an L2 distance or norm (flat scan, the BLAS path's norms,
// IVF-Flat lists, HNSW) uses them. Everything else stays Debian's code.
#include <immintrin.h>

#include <cstddef>

namespace faiss {
namespace {

__attribute__((target("avx2"))) inline __m128 MaskedRead(std::size_t d, const float* x) {
  alignas(16) float buf[4] = {0, 0, 0, 0};
  for (std::size_t i = 0; i < d; ++i) buf[i] = x[i];
  return _mm_load_ps(buf);
}

__attribute__((target("avx2"))) inline float Finish(__m256 acc8, __m128 acc4) {
  __m128 s = _mm_add_ps(_mm256_extractf128_ps(acc8, 1), _mm256_castps256_ps128(acc8));
  s = _mm_add_ps(s, acc4);
  s = _mm_hadd_ps(s, s);
  s = _mm_hadd_ps(s, s);
  return _mm_cvtss_f32(s);
}

}  // namespace

__attribute__((target("avx2"))) float fvec_L2sqr(const float* x, const float* y, std::size_t d) {
  __m256 acc8 = _mm256_setzero_ps();
  for (; d >= 8; d -= 8, x += 8, y += 8) {
    const __m256 diff = _mm256_sub_ps(_mm256_loadu_ps(x), _mm256_loadu_ps(y));
    acc8 = _mm256_add_ps(acc8, _mm256_mul_ps(diff, diff));
  }
  __m128 acc4 = _mm_setzero_ps();
  if (d >= 4) {
    const __m128 diff = _mm_sub_ps(_mm_loadu_ps(x), _mm_loadu_ps(y));
    acc4 = _mm_mul_ps(diff, diff);
    x += 4;
    y += 4;
    d -= 4;
  }
  if (d > 0) {
    const __m128 diff = _mm_sub_ps(MaskedRead(d, x), MaskedRead(d, y));
    acc4 = _mm_add_ps(acc4, _mm_mul_ps(diff, diff));
  }
  return Finish(acc8, acc4);
}

__attribute__((target("avx2"))) float fvec_norm_L2sqr(const float* x, std::size_t d) {
  __m256 acc8 = _mm256_setzero_ps();
  for (; d >= 8; d -= 8, x += 8) {
    const __m256 v = _mm256_loadu_ps(x);
    acc8 = _mm256_add_ps(acc8, _mm256_mul_ps(v, v));
  }
  __m128 acc4 = _mm_setzero_ps();
  if (d >= 4) {
    const __m128 v = _mm_loadu_ps(x);
    acc4 = _mm_mul_ps(v, v);
    x += 4;
    d -= 4;
  }
  if (d > 0) {
    const __m128 v = MaskedRead(d, x);
    acc4 = _mm_add_ps(acc4, _mm_mul_ps(v, v));
  }
  return Finish(acc8, acc4);
}

}  // namespace faiss
