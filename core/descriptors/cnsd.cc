// CNSD-3D (docs/descriptors.md section 3; dissertation chapter 5 and 8.2).
//
// Readings of points the spec and the dissertation leave open:
//  - Comparison. "w_ij <= T" is decided once, in squared form: the pair's float squared
//    distance (dx*dx + dy*dy) + dz*dz on the normalised coordinates (bounding-box centre
//    subtracted, scaled by a power of two) against the largest float <= T*T*d_max^2 (double).
//    d_max^2 is the largest float squared distance, so T = 1 joins the farthest pair exactly.
//    Every kernel (scalar, AVX2, AVX-512) computes the same floats and makes the same exact
//    comparison, so they agree bit for bit.
//  - Thresholds are t_start + k * t_step (multiplied, not accumulated); one within 1e-9 of
//    t_end is snapped to t_end, so 0.3 + 2 * 0.35 is exactly 1, not 0.99999999999999989.
//  - t_start may be 0 (the dissertation says T_start >= 0; at 0 only coincident points are
//    joined) and may equal t_end (one threshold; the text asks T_end > T_start, which only
//    rules out a useless corner).
//  - n, the degree divisor, is the number of vertices of the graph, i.e. after downsampling.
//    No self-loops; distinct vertices at the same position have distance 0 and are joined.
//    D_avg = sum of degrees / n^2 and D_max = max degree / n, in double, rounded to float.
//  - max_points >= 8, not 3: a box grid anchored at the minimum with cells as large as the
//    widest extent has at most 8 occupied cells and still separates the two ends of that
//    axis; below 8, some clouds (a cube's corners) only fit in one cell, a one-vertex graph.
//  - Box grid filter: cubic cells (one leaf size for all axes), as a box grid filter does;
//    the paper reduced clouds over 8000 points "to 7000 to 8000" and we keep as many cells as
//    the leaf-size search finds, never more than max_points. Random: the paper's RPR removed
//    60% of every cloud; here, like the box filter, it only runs when n > max_points and
//    keeps exactly max_points points.
//  - Pairs are visited as full rows (each unordered pair measured from both ends) instead of
//    i < j with a per-vertex counter table: twice the distance arithmetic, but one row's
//    bucket counts then stay in registers (the packed kernels below), and memory is O(n + S)
//    instead of O(n S). One pass over the pairs i < j finds d_max first.
#include "core/descriptors/cnsd.h"

#include <immintrin.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <memory>
#include <numeric>
#include <string>
#include <utility>

#include "absl/strings/str_cat.h"
#include "core/status_macros.h"

namespace shapeid {
namespace cnsd_internal {
namespace {

constexpr size_t kMaxLanes = 16;   // widest kernel; coordinate arrays are padded to a multiple
constexpr float kFarAway = 1e18f;  // padding: squared distance ~3e36, finite and beyond every
                                   // bound, so padding pairs land in bucket S (ignored)
constexpr uint32_t kPackedBuckets = 32;      // S + 1 up to this: counters held in registers
constexpr uint32_t kHistogramBudget = 4096;  // otherwise: counters over all sub-histograms

// Coordinates in structure-of-arrays form, padded to a multiple of kMaxLanes.
struct PairData {
  const float* x;
  const float* y;
  const float* z;
  size_t n;
  size_t padded;
};

// Pair (i, j) goes to bucket b = the number of bounds below its squared distance d2, i.e. it
// is joined at thresholds b..S-1 (b = S: at none). Kernels first approximate
// a = floor(sqrt(d2) * scale + offset), i.e. (sqrt(d2) / d_max - t_start) / t_step + 0.5,
// clamped to [0, S]. Float errors are under 0.01 of a bucket (t_step >= 1e-4), so a is b or
// b - 1 and b = a + (d2 > bound[a]) exactly; the scalar kernel fixes up with loops instead.
struct BucketTables {
  uint32_t num_thresholds;  // S
  const float* bound;       // S + 1 entries (bound[S] = +inf), padded with +inf to >= 32
  float scale;
  float offset;
  uint32_t stride;    // scalar and scatter kernels: counters per sub-histogram (S + 1)
  uint32_t sub_mask;  // scalar and scatter kernels: lane l counts into sub-histogram l & mask
};

using MaxFn = float (*)(const PairData&);
// Counts how many j in [0, n), j = i included, fall in each bucket of row i: counts[0..S].
// `scratch` holds (sub_mask + 1) * stride counters.
using RowFn = void (*)(const PairData&, const BucketTables&, size_t i, uint32_t* scratch,
                       uint32_t* counts);

inline float SquaredDistance(float dx, float dy, float dz) { return (dx * dx + dy * dy) + dz * dz; }

void MergeSubHistograms(const BucketTables& t, const uint32_t* scratch, uint32_t* counts) {
  for (uint32_t k = 0; k <= t.num_thresholds; ++k) {
    uint32_t total = 0;
    for (uint32_t sub = 0; sub <= t.sub_mask; ++sub) total += scratch[sub * t.stride + k];
    counts[k] = total;
  }
}

float MaxSquaredDistanceScalar(const PairData& p) {
  float best = 0;
  for (size_t i = 0; i < p.n; ++i) {
    for (size_t j = i + 1; j < p.n; ++j) {
      best = std::max(best, SquaredDistance(p.x[j] - p.x[i], p.y[j] - p.y[i], p.z[j] - p.z[i]));
    }
  }
  return best;
}

void RowScalar(const PairData& p, const BucketTables& t, size_t i, uint32_t* scratch,
               uint32_t* counts) {
  std::fill(scratch, scratch + (t.sub_mask + 1) * t.stride, 0u);
  const float xi = p.x[i], yi = p.y[i], zi = p.z[i];
  const float top = static_cast<float>(t.num_thresholds);
  for (size_t j = 0; j < p.n; ++j) {
    const float d2 = SquaredDistance(p.x[j] - xi, p.y[j] - yi, p.z[j] - zi);
    const float a = std::min(std::max(std::sqrt(d2) * t.scale + t.offset, 0.0f), top);
    uint32_t b = static_cast<uint32_t>(a);
    b += d2 > t.bound[b];         // what the vector kernels do; the loops below never run unless
    while (d2 > t.bound[b]) ++b;  // the error bound is wrong (bound[S] = +inf stops this)
    while (b > 0 && d2 <= t.bound[b - 1]) --b;
    ++scratch[(j & t.sub_mask) * t.stride + b];
  }
  MergeSubHistograms(t, scratch, counts);
}

// GCC 12's AVX-512 headers trip -W(maybe-)uninitialized on their own _mm512_undefined_*
// placeholders (a known false positive, GCC bug 105593).
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#pragma GCC diagnostic ignored "-Wuninitialized"

// The vector kernels come in two kinds.
//  - Packed (S + 1 <= 32), the fast one: no memory traffic per pair. Each lane keeps 4-bit
//    counters, 8 buckets to a 32-bit word (M words), and adds the one-hot nibble of the
//    pair's bucket. After 15 rounds (before a nibble can overflow) the nibbles are spread
//    into byte counters, and after 17 such spreads (255 rounds) the bytes into 32-bit
//    counters in memory.
//  - Scatter (larger S): the bucket plus the lane's sub-histogram offset is stored and the
//    counters incremented one by one; lanes use separate sub-histograms so one counter is
//    not bumped back to back (which would serialise on store forwarding).
constexpr int kNibbleRounds = 15;
constexpr int kByteSpreads = 17;

__attribute__((target("avx2"))) float MaxSquaredDistanceAvx2(const PairData& p) {
  __m256 best = _mm256_setzero_ps();
  for (size_t i = 0; i < p.n; ++i) {
    const __m256 xi = _mm256_set1_ps(p.x[i]);
    const __m256 yi = _mm256_set1_ps(p.y[i]);
    const __m256 zi = _mm256_set1_ps(p.z[i]);
    // Starting at the aligned block holding i + 1 re-measures a few pairs j <= i: harmless
    // for a maximum. Padding holds copies of point 0 during this pass.
    for (size_t j = (i + 1) & ~size_t{7}; j < p.padded; j += 8) {
      const __m256 dx = _mm256_sub_ps(_mm256_loadu_ps(p.x + j), xi);
      const __m256 dy = _mm256_sub_ps(_mm256_loadu_ps(p.y + j), yi);
      const __m256 dz = _mm256_sub_ps(_mm256_loadu_ps(p.z + j), zi);
      const __m256 d2 = _mm256_add_ps(_mm256_add_ps(_mm256_mul_ps(dx, dx), _mm256_mul_ps(dy, dy)),
                                      _mm256_mul_ps(dz, dz));
      best = _mm256_max_ps(best, d2);
    }
  }
  alignas(32) float lanes[8];
  _mm256_store_ps(lanes, best);
  return *std::max_element(lanes, lanes + 8);
}

// bound[idx] for idx in [0, 32) from a table held in four registers.
__attribute__((target("avx2"))) inline __m256 Lookup32Avx2(const __m256 table[4], __m256i idx) {
  const __m256 p0 = _mm256_permutevar8x32_ps(table[0], idx);
  const __m256 p1 = _mm256_permutevar8x32_ps(table[1], idx);
  const __m256 p2 = _mm256_permutevar8x32_ps(table[2], idx);
  const __m256 p3 = _mm256_permutevar8x32_ps(table[3], idx);
  const __m256 bit3 = _mm256_castsi256_ps(_mm256_slli_epi32(idx, 28));  // blendv reads the sign
  const __m256 bit4 = _mm256_castsi256_ps(_mm256_slli_epi32(idx, 27));
  return _mm256_blendv_ps(_mm256_blendv_ps(p0, p1, bit3), _mm256_blendv_ps(p2, p3, bit3), bit4);
}

// Squared distances from point i to points j..j+7 and the approximate buckets a.
struct Avx2Row {
  __m256 xi, yi, zi, scale, offset, top;

  __attribute__((target("avx2"))) Avx2Row(const PairData& p, const BucketTables& t, size_t i)
      : xi(_mm256_set1_ps(p.x[i])),
        yi(_mm256_set1_ps(p.y[i])),
        zi(_mm256_set1_ps(p.z[i])),
        scale(_mm256_set1_ps(t.scale)),
        offset(_mm256_set1_ps(t.offset)),
        top(_mm256_set1_ps(static_cast<float>(t.num_thresholds))) {}

  __attribute__((target("avx2"))) __m256 SquaredDistances(const PairData& p, size_t j) const {
    const __m256 dx = _mm256_sub_ps(_mm256_loadu_ps(p.x + j), xi);
    const __m256 dy = _mm256_sub_ps(_mm256_loadu_ps(p.y + j), yi);
    const __m256 dz = _mm256_sub_ps(_mm256_loadu_ps(p.z + j), zi);
    return _mm256_add_ps(_mm256_add_ps(_mm256_mul_ps(dx, dx), _mm256_mul_ps(dy, dy)),
                         _mm256_mul_ps(dz, dz));
  }

  __attribute__((target("avx2"))) __m256i Approximate(__m256 d2) const {
    const __m256 a = _mm256_add_ps(_mm256_mul_ps(_mm256_sqrt_ps(d2), scale), offset);
    return _mm256_cvttps_epi32(_mm256_min_ps(_mm256_max_ps(a, _mm256_setzero_ps()), top));
  }
};

template <int kWords>
__attribute__((target("avx2"))) void RowPackedAvx2(const PairData& p, const BucketTables& t,
                                                   size_t i, uint32_t* /*scratch*/,
                                                   uint32_t* counts) {
  const Avx2Row row(p, t, i);
  const __m256 table[4] = {_mm256_loadu_ps(t.bound), _mm256_loadu_ps(t.bound + 8),
                           _mm256_loadu_ps(t.bound + 16), _mm256_loadu_ps(t.bound + 24)};
  const __m256i one = _mm256_set1_epi32(1);
  const __m256i low_nibbles = _mm256_set1_epi32(0x0F0F0F0F);
  const __m256i low_byte = _mm256_set1_epi32(0xFF);
  alignas(32) uint32_t wide[8 * kWords][8] = {};
  __m256i even[kWords], odd[kWords];  // byte counters of even and odd nibbles
  for (int w = 0; w < kWords; ++w) even[w] = odd[w] = _mm256_setzero_si256();
  int spreads = 0;
  for (size_t j = 0; j < p.padded;) {
    __m256i nibbles[kWords];
    for (int w = 0; w < kWords; ++w) nibbles[w] = _mm256_setzero_si256();
    for (const size_t end = std::min(p.padded, j + 8 * kNibbleRounds); j < end; j += 8) {
      const __m256 d2 = row.SquaredDistances(p, j);
      const __m256i a = row.Approximate(d2);
      const __m256i above =
          _mm256_castps_si256(_mm256_cmp_ps(d2, Lookup32Avx2(table, a), _CMP_GT_OQ));
      const __m256i shift = _mm256_slli_epi32(_mm256_sub_epi32(a, above), 2);  // 4 * b
#pragma GCC unroll 4
      for (int w = 0; w < kWords; ++w) {
        // Shift counts outside [0, 31] give 0: only the word holding b gets its nibble.
        nibbles[w] = _mm256_add_epi32(
            nibbles[w], _mm256_sllv_epi32(one, _mm256_sub_epi32(shift, _mm256_set1_epi32(32 * w))));
      }
    }
#pragma GCC unroll 4
    for (int w = 0; w < kWords; ++w) {
      even[w] = _mm256_add_epi32(even[w], _mm256_and_si256(nibbles[w], low_nibbles));
      odd[w] =
          _mm256_add_epi32(odd[w], _mm256_and_si256(_mm256_srli_epi32(nibbles[w], 4), low_nibbles));
    }
    if (++spreads == kByteSpreads || j >= p.padded) {
      spreads = 0;
      for (int w = 0; w < kWords; ++w) {
        for (int q = 0; q < 4; ++q) {
          for (int parity = 0; parity < 2; ++parity) {
            __m256i* counter = reinterpret_cast<__m256i*>(wide[8 * w + 2 * q + parity]);
            const __m256i bytes = parity == 0 ? even[w] : odd[w];
            *counter = _mm256_add_epi32(
                *counter, _mm256_and_si256(_mm256_srli_epi32(bytes, 8 * q), low_byte));
          }
        }
        even[w] = odd[w] = _mm256_setzero_si256();
      }
    }
  }
  for (uint32_t k = 0; k <= t.num_thresholds; ++k) {
    uint32_t total = 0;
    for (int l = 0; l < 8; ++l) total += wide[k][l];
    counts[k] = total;
  }
}

__attribute__((target("avx2"))) void RowScatterAvx2(const PairData& p, const BucketTables& t,
                                                    size_t i, uint32_t* scratch, uint32_t* counts) {
  std::fill(scratch, scratch + (t.sub_mask + 1) * t.stride, 0u);
  const Avx2Row row(p, t, i);
  alignas(32) uint32_t offsets[8];
  for (uint32_t l = 0; l < 8; ++l) offsets[l] = (l & t.sub_mask) * t.stride;
  const __m256i lane_offset = _mm256_load_si256(reinterpret_cast<const __m256i*>(offsets));
  alignas(32) uint32_t idx[8];
  for (size_t j = 0; j < p.padded; j += 8) {
    const __m256 d2 = row.SquaredDistances(p, j);
    const __m256i a = row.Approximate(d2);
    const __m256i above =
        _mm256_castps_si256(_mm256_cmp_ps(d2, _mm256_i32gather_ps(t.bound, a, 4), _CMP_GT_OQ));
    const __m256i b = _mm256_sub_epi32(a, above);  // above is -1 where d2 > bound[a]
    _mm256_store_si256(reinterpret_cast<__m256i*>(idx), _mm256_add_epi32(b, lane_offset));
    for (int l = 0; l < 8; ++l) ++scratch[idx[l]];
  }
  MergeSubHistograms(t, scratch, counts);
}

__attribute__((target("avx512f"))) float MaxSquaredDistanceAvx512(const PairData& p) {
  __m512 best = _mm512_setzero_ps();
  for (size_t i = 0; i < p.n; ++i) {
    const __m512 xi = _mm512_set1_ps(p.x[i]);
    const __m512 yi = _mm512_set1_ps(p.y[i]);
    const __m512 zi = _mm512_set1_ps(p.z[i]);
    for (size_t j = (i + 1) & ~size_t{15}; j < p.padded; j += 16) {
      const __m512 dx = _mm512_sub_ps(_mm512_loadu_ps(p.x + j), xi);
      const __m512 dy = _mm512_sub_ps(_mm512_loadu_ps(p.y + j), yi);
      const __m512 dz = _mm512_sub_ps(_mm512_loadu_ps(p.z + j), zi);
      const __m512 d2 = _mm512_add_ps(_mm512_add_ps(_mm512_mul_ps(dx, dx), _mm512_mul_ps(dy, dy)),
                                      _mm512_mul_ps(dz, dz));
      best = _mm512_max_ps(best, d2);
    }
  }
  return _mm512_reduce_max_ps(best);
}

struct Avx512Row {
  __m512 xi, yi, zi, scale, offset, top;

  __attribute__((target("avx512f"))) Avx512Row(const PairData& p, const BucketTables& t, size_t i)
      : xi(_mm512_set1_ps(p.x[i])),
        yi(_mm512_set1_ps(p.y[i])),
        zi(_mm512_set1_ps(p.z[i])),
        scale(_mm512_set1_ps(t.scale)),
        offset(_mm512_set1_ps(t.offset)),
        top(_mm512_set1_ps(static_cast<float>(t.num_thresholds))) {}

  __attribute__((target("avx512f"))) __m512 SquaredDistances(const PairData& p, size_t j) const {
    const __m512 dx = _mm512_sub_ps(_mm512_loadu_ps(p.x + j), xi);
    const __m512 dy = _mm512_sub_ps(_mm512_loadu_ps(p.y + j), yi);
    const __m512 dz = _mm512_sub_ps(_mm512_loadu_ps(p.z + j), zi);
    return _mm512_add_ps(_mm512_add_ps(_mm512_mul_ps(dx, dx), _mm512_mul_ps(dy, dy)),
                         _mm512_mul_ps(dz, dz));
  }

  __attribute__((target("avx512f"))) __m512i Approximate(__m512 d2) const {
    const __m512 a = _mm512_add_ps(_mm512_mul_ps(_mm512_sqrt_ps(d2), scale), offset);
    return _mm512_cvttps_epi32(_mm512_min_ps(_mm512_max_ps(a, _mm512_setzero_ps()), top));
  }
};

template <int kWords>
__attribute__((target("avx512f"))) void RowPackedAvx512(const PairData& p, const BucketTables& t,
                                                        size_t i, uint32_t* /*scratch*/,
                                                        uint32_t* counts) {
  const Avx512Row row(p, t, i);
  const __m512 bound_lo = _mm512_loadu_ps(t.bound);
  const __m512 bound_hi = _mm512_loadu_ps(t.bound + 16);
  const __m512i one = _mm512_set1_epi32(1);
  const __m512i low_nibbles = _mm512_set1_epi32(0x0F0F0F0F);
  const __m512i low_byte = _mm512_set1_epi32(0xFF);
  // One-hot nibbles by bucket, word w: bucket b in [8w, 8w + 8) -> 1 << 4 (b - 8w), else 0.
  __m512i onehot_lo[kWords], onehot_hi[kWords];
  for (int w = 0; w < kWords; ++w) {
    alignas(64) uint32_t entries[32];
    for (int b = 0; b < 32; ++b) entries[b] = b / 8 == w ? 1u << (4 * (b % 8)) : 0u;
    onehot_lo[w] = _mm512_load_si512(entries);
    onehot_hi[w] = _mm512_load_si512(entries + 16);
  }
  alignas(64) uint32_t wide[8 * kWords][16] = {};
  __m512i even[kWords], odd[kWords];  // byte counters of even and odd nibbles
  for (int w = 0; w < kWords; ++w) even[w] = odd[w] = _mm512_setzero_si512();
  int spreads = 0;
  for (size_t j = 0; j < p.padded;) {
    __m512i nibbles[kWords];
    for (int w = 0; w < kWords; ++w) nibbles[w] = _mm512_setzero_si512();
    for (const size_t end = std::min(p.padded, j + 16 * kNibbleRounds); j < end; j += 16) {
      const __m512 d2 = row.SquaredDistances(p, j);
      const __m512i a = row.Approximate(d2);
      const __m512 bound = _mm512_permutex2var_ps(bound_lo, a, bound_hi);
      const __mmask16 above = _mm512_cmp_ps_mask(d2, bound, _CMP_GT_OQ);
      const __m512i b = _mm512_mask_add_epi32(a, above, a, one);
#pragma GCC unroll 4
      for (int w = 0; w < kWords; ++w) {
        nibbles[w] =
            _mm512_add_epi32(nibbles[w], _mm512_permutex2var_epi32(onehot_lo[w], b, onehot_hi[w]));
      }
    }
#pragma GCC unroll 4
    for (int w = 0; w < kWords; ++w) {
      even[w] = _mm512_add_epi32(even[w], _mm512_and_si512(nibbles[w], low_nibbles));
      odd[w] =
          _mm512_add_epi32(odd[w], _mm512_and_si512(_mm512_srli_epi32(nibbles[w], 4), low_nibbles));
    }
    if (++spreads == kByteSpreads || j >= p.padded) {
      spreads = 0;
      for (int w = 0; w < kWords; ++w) {
        for (int q = 0; q < 4; ++q) {
          for (int parity = 0; parity < 2; ++parity) {
            uint32_t* counter = wide[8 * w + 2 * q + parity];
            const __m512i bytes = parity == 0 ? even[w] : odd[w];
            _mm512_store_si512(
                counter,
                _mm512_add_epi32(_mm512_load_si512(counter),
                                 _mm512_and_si512(_mm512_srli_epi32(bytes, 8 * q), low_byte)));
          }
        }
        even[w] = odd[w] = _mm512_setzero_si512();
      }
    }
  }
  for (uint32_t k = 0; k <= t.num_thresholds; ++k) {
    counts[k] = static_cast<uint32_t>(_mm512_reduce_add_epi32(_mm512_load_si512(wide[k])));
  }
}

__attribute__((target("avx512f"))) void RowScatterAvx512(const PairData& p, const BucketTables& t,
                                                         size_t i, uint32_t* scratch,
                                                         uint32_t* counts) {
  std::fill(scratch, scratch + (t.sub_mask + 1) * t.stride, 0u);
  const Avx512Row row(p, t, i);
  const __m512i one = _mm512_set1_epi32(1);
  alignas(64) uint32_t offsets[16];
  for (uint32_t l = 0; l < 16; ++l) offsets[l] = (l & t.sub_mask) * t.stride;
  const __m512i lane_offset = _mm512_load_si512(offsets);
  alignas(64) uint32_t idx[16];
  for (size_t j = 0; j < p.padded; j += 16) {
    const __m512 d2 = row.SquaredDistances(p, j);
    const __m512i a = row.Approximate(d2);
    const __mmask16 above = _mm512_cmp_ps_mask(d2, _mm512_i32gather_ps(a, t.bound, 4), _CMP_GT_OQ);
    const __m512i b = _mm512_mask_add_epi32(a, above, a, one);
    _mm512_store_si512(idx, _mm512_add_epi32(b, lane_offset));
    for (int l = 0; l < 16; ++l) ++scratch[idx[l]];
  }
  MergeSubHistograms(t, scratch, counts);
}

#pragma GCC diagnostic pop

uint64_t SplitMix64(uint64_t& state) {
  uint64_t z = (state += 0x9e3779b97f4a7c15ULL);
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  return z ^ (z >> 31);
}

// A uniform integer in [0, range) from 64 random bits (multiply-shift; bias <= range / 2^64).
uint64_t Below(uint64_t bits, uint64_t range) {
  __extension__ using Wide = unsigned __int128;
  return static_cast<uint64_t>((static_cast<Wide>(bits) * range) >> 64);
}

constexpr int kVoxelIndexBits = 21;
constexpr uint64_t kVoxelMaxIndex = (uint64_t{1} << kVoxelIndexBits) - 1;
constexpr int kVoxelSearchSteps = 20;

// Occupied cells of a box grid anchored at the bounding-box minimum, in an open-addressing
// table sized for `max_cells`, so a count can stop as soon as it is too large.
class VoxelGrid {
 public:
  VoxelGrid(const PointCloud& cloud, size_t max_cells) : cloud_(cloud), max_cells_(max_cells) {
    for (int a = 0; a < 3; ++a) {
      lo_[a] = std::numeric_limits<double>::infinity();
      hi_[a] = -lo_[a];
    }
    for (size_t i = 0; i < cloud.size(); ++i) {
      for (int a = 0; a < 3; ++a) {
        lo_[a] = std::min(lo_[a], static_cast<double>(cloud.data()[3 * i + a]));
        hi_[a] = std::max(hi_[a], static_cast<double>(cloud.data()[3 * i + a]));
      }
    }
    size_t capacity = 16;
    while (capacity < 2 * (max_cells + 1)) capacity *= 2;
    shift_ = 64 - __builtin_ctzll(capacity);
    keys_.resize(capacity);
    cell_of_slot_.resize(capacity);
  }

  // Largest extent over the three axes (0 for a single repeated point).
  double Extent() const { return std::max({hi_[0] - lo_[0], hi_[1] - lo_[1], hi_[2] - lo_[2]}); }

  // Occupied cells of size `leaf`, or max_cells + 1 when there are more.
  size_t CountCells(double leaf) {
    Clear();
    size_t cells = 0;
    for (size_t i = 0; i < cloud_.size(); ++i) {
      if (Insert(Key(i, leaf)) && ++cells > max_cells_) return cells;
    }
    return cells;
  }

  // One point per occupied cell, the centroid of its points, in key order. `leaf` must give
  // at most max_cells cells.
  PointCloud Centroids(double leaf) {
    Clear();
    struct Cell {
      uint64_t key;
      double sum[3];
      size_t count;
    };
    std::vector<Cell> cells;
    for (size_t i = 0; i < cloud_.size(); ++i) {
      const uint64_t key = Key(i, leaf);
      const size_t slot = Find(key);
      if (keys_[slot] == kEmpty) {
        keys_[slot] = key;
        cell_of_slot_[slot] = static_cast<uint32_t>(cells.size());
        cells.push_back({key, {0, 0, 0}, 0});
      }
      Cell& cell = cells[cell_of_slot_[slot]];
      for (int a = 0; a < 3; ++a) cell.sum[a] += cloud_.data()[3 * i + a];
      ++cell.count;
    }
    std::sort(cells.begin(), cells.end(),
              [](const Cell& l, const Cell& r) { return l.key < r.key; });
    PointCloud out;
    out.Reserve(cells.size());
    for (const Cell& cell : cells) {
      const double count = static_cast<double>(cell.count);
      out.Add(static_cast<float>(cell.sum[0] / count), static_cast<float>(cell.sum[1] / count),
              static_cast<float>(cell.sum[2] / count));
    }
    return out;
  }

 private:
  static constexpr uint64_t kEmpty = ~uint64_t{0};  // keys use 63 bits

  void Clear() { std::fill(keys_.begin(), keys_.end(), kEmpty); }

  uint64_t Key(size_t i, double leaf) const {
    uint64_t key = 0;
    for (int a = 0; a < 3; ++a) {
      // Division, not a reciprocal: at leaf = Extent() the far end of the widest axis gives
      // exactly 1, so it is in a different cell from the near end.
      const double q = (static_cast<double>(cloud_.data()[3 * i + a]) - lo_[a]) / leaf;
      const uint64_t index =
          q < static_cast<double>(kVoxelMaxIndex) ? static_cast<uint64_t>(q) : kVoxelMaxIndex;
      key = (key << kVoxelIndexBits) | index;
    }
    return key;
  }

  size_t Find(uint64_t key) const {
    size_t slot = static_cast<size_t>((key * 0x9e3779b97f4a7c15ULL) >> shift_);
    const size_t mask = keys_.size() - 1;
    while (keys_[slot] != kEmpty && keys_[slot] != key) slot = (slot + 1) & mask;
    return slot;
  }

  // True when `key` was new.
  bool Insert(uint64_t key) {
    const size_t slot = Find(key);
    if (keys_[slot] == key) return false;
    keys_[slot] = key;
    return true;
  }

  const PointCloud& cloud_;
  size_t max_cells_;
  double lo_[3];
  double hi_[3];
  int shift_ = 0;
  std::vector<uint64_t> keys_;
  std::vector<uint32_t> cell_of_slot_;
};

std::string FormatDouble(double value) {
  if (value == 0) value = 0;  // no "-0"
  char buffer[32];
  for (int precision = 1; precision <= 17; ++precision) {
    std::snprintf(buffer, sizeof(buffer), "%.*g", precision, value);
    if (std::strtod(buffer, nullptr) == value) break;
  }
  return buffer;
}

}  // namespace

std::vector<double> Thresholds(double t_start, double t_end, double t_step) {
  std::vector<double> thresholds;
  if (!(t_step > 0)) return thresholds;
  for (size_t k = 0;; ++k) {
    double t = t_start + static_cast<double>(k) * t_step;
    if (t > t_end + 1e-9) break;
    if (std::fabs(t - t_end) <= 1e-9) t = t_end;
    thresholds.push_back(t);
  }
  return thresholds;
}

std::vector<float> NormalizedXyz(const PointCloud& cloud) {
  const size_t n = cloud.size();
  const float* xyz = cloud.data();
  double lo[3], hi[3];
  for (int a = 0; a < 3; ++a) lo[a] = hi[a] = n > 0 ? xyz[a] : 0.0f;
  for (size_t i = 0; i < n; ++i) {
    for (int a = 0; a < 3; ++a) {
      lo[a] = std::min(lo[a], static_cast<double>(xyz[3 * i + a]));
      hi[a] = std::max(hi[a], static_cast<double>(xyz[3 * i + a]));
    }
  }
  double centre[3];
  double radius = 0;
  for (int a = 0; a < 3; ++a) {
    centre[a] = 0.5 * (lo[a] + hi[a]);
    radius = std::max({radius, hi[a] - centre[a], centre[a] - lo[a]});
  }
  int exponent = 0;
  if (radius > 0) std::frexp(radius, &exponent);  // radius = f * 2^exponent, f in [0.5, 1)
  std::vector<float> out(3 * n);
  for (size_t i = 0; i < 3 * n; ++i) {
    out[i] = static_cast<float>(std::ldexp(xyz[i] - centre[i % 3], -exponent));
  }
  return out;
}

float SquaredThreshold(double t, float max_d2) {
  const double exact = t * t * static_cast<double>(max_d2);
  float bound = static_cast<float>(exact);
  if (static_cast<double>(bound) > exact) {
    bound = std::nextafter(bound, -std::numeric_limits<float>::infinity());
  }
  return bound;
}

absl::Status ComputeFeatures(const PointCloud& cloud, absl::Span<const double> thresholds,
                             SimdLevel level, absl::Span<float> out) {
  const size_t n = cloud.size();
  const size_t num_thresholds = thresholds.size();
  if (out.size() != 2 * num_thresholds || num_thresholds == 0) {
    return absl::InternalError(
        absl::StrCat("cnsd: ", num_thresholds, " thresholds but ", out.size(), " output values"));
  }
  if (n < 2) {
    return absl::InvalidArgumentError(
        absl::StrCat("cnsd: a network needs at least 2 points; the cloud has ", n));
  }

  // Structure of arrays, padded to whole vectors of the widest kernel.
  const std::vector<float> xyz = NormalizedXyz(cloud);
  const size_t padded = (n + kMaxLanes - 1) / kMaxLanes * kMaxLanes;
  std::vector<float> coords(3 * padded);
  float* x = coords.data();
  float* y = x + padded;
  float* z = y + padded;
  for (size_t i = 0; i < padded; ++i) {
    const size_t from = i < n ? i : 0;  // the maximum pass pads with copies of point 0
    x[i] = xyz[3 * from];
    y[i] = xyz[3 * from + 1];
    z[i] = xyz[3 * from + 2];
  }
  const PairData pairs{x, y, z, n, padded};

  level = std::min(level, DetectedSimdLevel());
  MaxFn max_fn = MaxSquaredDistanceScalar;
  if (level == SimdLevel::kAvx2) max_fn = MaxSquaredDistanceAvx2;
  if (level == SimdLevel::kAvx512) max_fn = MaxSquaredDistanceAvx512;
  const float max_d2 = max_fn(pairs);
  if (!(max_d2 > 0)) {
    return absl::InvalidArgumentError(
        absl::StrCat("cnsd: all ", n, " points coincide, so no distance can be normalised"));
  }
  for (size_t i = n; i < padded; ++i) x[i] = y[i] = z[i] = kFarAway;  // bucket S

  const uint32_t s = static_cast<uint32_t>(num_thresholds);
  std::vector<float> bound(std::max<size_t>(num_thresholds + 1, 32),
                           std::numeric_limits<float>::infinity());
  for (size_t k = 0; k < num_thresholds; ++k) bound[k] = SquaredThreshold(thresholds[k], max_d2);
  // a = sqrt(d2) / d_max / t_step - t_start / t_step + 0.5 (see BucketTables).
  const double step = num_thresholds > 1 ? thresholds[1] - thresholds[0] : 1.0;
  const double per_distance = 1.0 / (std::sqrt(static_cast<double>(max_d2)) * step);
  // That approximation needs thresholds evenly spaced at least 1e-4 apart, as Thresholds()
  // makes them for every valid spec; anything else takes the scalar kernel, exact regardless.
  bool evenly_spaced = num_thresholds == 1 || step >= 1e-4;
  for (size_t k = 0; k < num_thresholds; ++k) {
    evenly_spaced &=
        std::fabs(thresholds[k] - (thresholds[0] + static_cast<double>(k) * step)) <= 1e-3 * step;
  }
  if (!evenly_spaced) level = SimdLevel::kScalar;
  uint32_t subs = kMaxLanes;
  while (subs > 1 && subs * (s + 1) > kHistogramBudget) subs /= 2;
  const BucketTables tables{s,
                            bound.data(),
                            static_cast<float>(per_distance),
                            static_cast<float>(0.5 - thresholds[0] / step),
                            s + 1,
                            subs - 1};

  RowFn row_fn = RowScalar;
  if (s + 1 <= kPackedBuckets) {
    static constexpr RowFn kAvx2[] = {RowPackedAvx2<1>, RowPackedAvx2<2>, RowPackedAvx2<3>,
                                      RowPackedAvx2<4>};
    static constexpr RowFn kAvx512[] = {RowPackedAvx512<1>, RowPackedAvx512<2>, RowPackedAvx512<3>,
                                        RowPackedAvx512<4>};
    const uint32_t words = (s + 1 + 7) / 8;
    if (level == SimdLevel::kAvx2) row_fn = kAvx2[words - 1];
    if (level == SimdLevel::kAvx512) row_fn = kAvx512[words - 1];
  } else {
    if (level == SimdLevel::kAvx2) row_fn = RowScatterAvx2;
    if (level == SimdLevel::kAvx512) row_fn = RowScatterAvx512;
  }

  std::vector<uint32_t> scratch(static_cast<size_t>(subs) * (s + 1));
  std::vector<uint32_t> counts(s + 1);
  std::vector<uint64_t> degree_sum(num_thresholds, 0);
  std::vector<uint64_t> degree_max(num_thresholds, 0);
  for (size_t i = 0; i < n; ++i) {
    row_fn(pairs, tables, i, scratch.data(), counts.data());
    // Prefix sums over buckets give the degree at every threshold; the pair (i, i) has
    // distance 0 and sits in bucket 0, so start from -1.
    uint64_t degree = ~uint64_t{0};
    for (uint32_t k = 0; k < s; ++k) {
      degree += counts[k];
      degree_sum[k] += degree;
      degree_max[k] = std::max(degree_max[k], degree);
    }
  }
  const double nd = static_cast<double>(n);
  for (size_t k = 0; k < num_thresholds; ++k) {
    out[2 * k] = static_cast<float>(static_cast<double>(degree_sum[k]) / (nd * nd));
    out[2 * k + 1] = static_cast<float>(static_cast<double>(degree_max[k]) / nd);
  }
  return absl::OkStatus();
}

PointCloud VoxelDownsample(const PointCloud& cloud, size_t max_points) {
  if (cloud.size() <= max_points) return cloud;
  VoxelGrid grid(cloud, std::max<size_t>(max_points, 1));
  const double extent = grid.Extent();
  if (!(extent > 0)) return PointCloud(std::vector<float>(cloud.data(), cloud.data() + 3));
  // Invariant: `hi` gives at most max_points cells. At the extent there are at most 8; for
  // max_points < 8 (outside the contract) fall back to one cell.
  double hi = extent;
  if (grid.CountCells(hi) > max_points) hi = 2 * extent;
  double lo = std::ldexp(extent, -20);
  for (int step = 0; step < kVoxelSearchSteps; ++step) {
    const double mid = std::sqrt(lo * hi);
    if (grid.CountCells(mid) <= max_points) {
      hi = mid;
    } else {
      lo = mid;
    }
  }
  return grid.Centroids(hi);
}

PointCloud RandomDownsample(const PointCloud& cloud, size_t max_points, uint64_t seed) {
  const size_t n = cloud.size();
  if (n <= max_points) return cloud;
  std::vector<size_t> order(n);
  std::iota(order.begin(), order.end(), size_t{0});
  uint64_t state = seed;
  for (size_t k = 0; k < max_points; ++k) {
    std::swap(order[k], order[k + Below(SplitMix64(state), n - k)]);
  }
  std::sort(order.begin(), order.begin() + static_cast<std::ptrdiff_t>(max_points));
  PointCloud out;
  out.Reserve(max_points);
  for (size_t k = 0; k < max_points; ++k) out.Add(cloud.point(order[k]));
  return out;
}

}  // namespace cnsd_internal

namespace {

enum class Downsample { kVoxel, kRandom };

class CnsdDescriptor final : public Descriptor {
 public:
  CnsdDescriptor(DescriptorSpec spec, std::vector<double> thresholds, size_t max_points,
                 Downsample downsample, uint64_t seed)
      : Descriptor(std::move(spec), 2 * thresholds.size()),
        thresholds_(std::move(thresholds)),
        max_points_(max_points),
        downsample_(downsample),
        seed_(seed) {}

 protected:
  absl::Status ComputeValidated(const PointCloud& cloud, const CloudStats& /*stats*/,
                                absl::Span<float> out) const override {
    if (cloud.size() <= max_points_) {
      return cnsd_internal::ComputeFeatures(cloud, thresholds_, ActiveSimdLevel(), out);
    }
    const PointCloud reduced = downsample_ == Downsample::kVoxel
                                   ? cnsd_internal::VoxelDownsample(cloud, max_points_)
                                   : cnsd_internal::RandomDownsample(cloud, max_points_, seed_);
    const absl::Status status =
        cnsd_internal::ComputeFeatures(reduced, thresholds_, ActiveSimdLevel(), out);
    if (status.ok()) return status;
    return absl::Status(status.code(),
                        absl::StrCat(status.message(), " (after downsampling ", cloud.size(),
                                     " points to ", reduced.size(), ")"));
  }

 private:
  std::vector<double> thresholds_;
  size_t max_points_;
  Downsample downsample_;
  uint64_t seed_;
};

absl::StatusOr<std::unique_ptr<Descriptor>> CreateCnsd(const DescriptorSpec& filled) {
  const SpecParams params(filled);
  SHAPEID_ASSIGN_OR_RETURN(const double t_start, params.Double("t_start", 0.0, 1.0));
  SHAPEID_ASSIGN_OR_RETURN(const double t_end, params.Double("t_end", 0.0, 1.0));
  SHAPEID_ASSIGN_OR_RETURN(const double t_step, params.Double("t_step", 1e-4, 1.0));
  SHAPEID_ASSIGN_OR_RETURN(const int64_t max_points, params.Int("max_points", 8, 100000));
  SHAPEID_ASSIGN_OR_RETURN(const std::string downsample,
                           params.Choice("downsample", {"voxel", "random"}));
  SHAPEID_ASSIGN_OR_RETURN(const int64_t seed,
                           params.Int("seed", 0, std::numeric_limits<int64_t>::max()));
  if (t_start > t_end) {
    return absl::InvalidArgumentError(
        absl::StrCat("cnsd: t_start=", cnsd_internal::FormatDouble(t_start),
                     " is greater than t_end=", cnsd_internal::FormatDouble(t_end)));
  }
  std::vector<double> thresholds = cnsd_internal::Thresholds(t_start, t_end, t_step);
  DescriptorSpec canonical{"cnsd",
                           {{"t_start", cnsd_internal::FormatDouble(t_start)},
                            {"t_end", cnsd_internal::FormatDouble(t_end)},
                            {"t_step", cnsd_internal::FormatDouble(t_step)},
                            {"max_points", absl::StrCat(max_points)},
                            {"downsample", downsample},
                            {"seed", absl::StrCat(seed)}}};
  return std::unique_ptr<Descriptor>(new CnsdDescriptor(
      std::move(canonical), std::move(thresholds), static_cast<size_t>(max_points),
      downsample == "voxel" ? Downsample::kVoxel : Downsample::kRandom,
      static_cast<uint64_t>(seed)));
}

}  // namespace

DescriptorKind CnsdKind() {
  return {
      "cnsd",
      "complex network shape descriptor (CNSD-3D): mean and maximum vertex degree / n of "
      "the graph joining points at most T * d_max apart, for each threshold T",
      {{"t_start", "0.05", "first threshold T_0, a fraction of the largest distance; in [0, 1]"},
       {"t_end", "0.95", "last threshold (inclusive, 1e-9 slack); in [t_start, 1]"},
       {"t_step", "0.05",
        "threshold step; in [0.0001, 1] (at most 10001 thresholds; dimension 2 per threshold)"},
       {"max_points", "8000",
        "larger clouds are downsampled first (O(n^2) pairs); integer in [8, 100000]"},
       {"downsample", "voxel",
        "voxel (box grid filter: one centroid per occupied cell, cell size searched) | "
        "random (seeded subset of exactly max_points points)"},
       {"seed", "0", "seed of random downsampling; integer in [0, 2^63 - 1]"}},
      CreateCnsd};
}

}  // namespace shapeid
