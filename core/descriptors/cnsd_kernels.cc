// CNSD-3D pair kernels: cnsd_kernel_body.inc (and, for the vector sets, cnsd_packed_kernel.inc)
// compiled once per instruction set (scalar, AVX2, AVX-512), each over an `Ops` table of that
// set's intrinsics, and chosen at run time (core/simd.h).
//
// Which kernel counts the pairs:
//  - up to 31 thresholds (S + 1 <= 32 buckets, the default has 19): every pair i < j is
//    measured once and counted at both ends, vertex j's share kept in per-vertex counters
//    (O(n S) memory) until row j: PackedDegrees (vector sets, counters packed in nibbles) or
//    PairDegrees (scalar).
//  - more thresholds (up to 10001): ScatterDegrees, full rows, each pair measured from both
//    ends, memory O(n + S); per-vertex counters would take n (S + 1) words.
//
// The bucket of a pair: b = the number of bounds below its squared distance d2. Kernels first
// approximate a = floor(sqrt(d2) * scale + offset) clamped to [0, S], which BucketRule
// promises is b or b - 1, and then take b = a + (d2 > bound[a]) with one exact comparison.
// The scalar kernels walk from a to b with loops instead, so they are exact for any rule;
// rules without the promise take them at every level.
#include "core/descriptors/cnsd_kernels.h"

#include "core/simd_ops.h"
#include "core/target_region.h"

#if defined(__x86_64__)
#include <immintrin.h>
#endif

#include <algorithm>
#include <cfloat>
#include <cmath>
#include <cstddef>
#include <limits>
#include <memory>
#include <vector>

// GCC 12's AVX-512 headers trip -W(maybe-)uninitialized on their own _mm512_undefined_*
// placeholders (a known false positive, GCC bug 105593).
SHAPEID_IGNORE_GCC_WARNING("-Wmaybe-uninitialized")
SHAPEID_IGNORE_GCC_WARNING("-Wuninitialized")

namespace shapeid::cnsd_internal {
namespace {

constexpr size_t kMaxLanes = 16;  // widest kernel
// Padding of the degree passes: squared distance ~3e36 to any point, finite and beyond every
// bound, so padding pairs land in bucket S, which no threshold reads.
constexpr float kFarAway = 1e18f;
// S + 1 up to this: packed counters (PackedDegrees); above: ScatterDegrees.
constexpr uint32_t kPackedBuckets = 32;
// ScatterDegrees: counters over all its sub-histograms, at most.
constexpr uint32_t kHistogramBudget = 4096;

// A zeroed array starting on a cache line, so aligned vector loads never split lines.
template <typename T>
class CacheAligned {
 public:
  explicit CacheAligned(size_t size) : storage_(size + kLine / sizeof(T)) {
    void* start = storage_.data();
    size_t space = storage_.size() * sizeof(T);
    data_ = static_cast<T*>(std::align(kLine, size * sizeof(T), start, space));
  }
  CacheAligned(const CacheAligned&) = delete;
  CacheAligned& operator=(const CacheAligned&) = delete;

  T* data() { return data_; }
  T& operator[](size_t k) { return data_[k]; }

 private:
  static constexpr size_t kLine = 64;
  std::vector<T> storage_;
  T* data_;
};

// Vectors the pipelined loop of PackedDegrees reads beyond the last one it counts.
constexpr size_t kReadAhead = 3;

// Coordinates in structure-of-arrays form. Each array holds the n points and then padding up
// to a multiple of kMaxLanes, plus kReadAhead vectors more.
struct PairData {
  const float* x;
  const float* y;
  const float* z;
  size_t n;
};

size_t PaddedLength(size_t n) {
  return (n + kMaxLanes - 1) / kMaxLanes * kMaxLanes + kReadAhead * kMaxLanes;
}

// The points of `xyz` as PairData in `storage` (3 * PaddedLength(n) floats), padded with
// `padding` (three floats) or, when null, copies of point 0.
PairData Transpose(absl::Span<const float> xyz, const float* padding,
                   CacheAligned<float>& storage) {
  const size_t n = xyz.size() / 3;
  const size_t length = PaddedLength(n);
  float* x = storage.data();
  float* y = x + length;
  float* z = y + length;
  for (size_t i = 0; i < length; ++i) {
    const float* from = i < n ? &xyz[3 * i] : padding != nullptr ? padding : &xyz[0];
    x[i] = from[0];
    y[i] = from[1];
    z[i] = from[2];
  }
  return PairData{x, y, z, n};
}

// A BucketRule as the kernels read it.
struct BucketTables {
  uint32_t num_thresholds;  // S
  const float* bound;       // S + 1 entries (bound[S] = +inf), padded with +inf to >= 32
  float scale;
  float offset;
  uint32_t stride;    // ScatterDegrees: counters per sub-histogram (S + 1)
  uint32_t sub_mask;  // ScatterDegrees: pair j counts into sub-histogram j & sub_mask
};

namespace scalar {
struct Ops {
  using Vec = float;
  using IVec = uint32_t;
  static constexpr size_t kLanes = 1;
  static Vec Load(const float* p) { return *p; }
  static Vec Set1(float v) { return v; }
  static Vec Add(Vec a, Vec b) { return a + b; }
  static Vec Sub(Vec a, Vec b) { return a - b; }
  static Vec Mul(Vec a, Vec b) { return a * b; }
  static Vec Max(Vec a, Vec b) { return std::max(a, b); }
  static float ReduceMax(Vec v) { return v; }
  static IVec AddI(IVec a, IVec b) { return a + b; }
  static IVec LoadI(const uint32_t* p) { return *p; }
  static void StoreI(uint32_t* p, IVec v) { *p = v; }

  class TableBuckets {
   public:
    explicit TableBuckets(const BucketTables& t)
        : t_(t), top_(static_cast<float>(t.num_thresholds)) {}
    IVec Approximate(Vec d2) const {
      return static_cast<uint32_t>(
          std::min(std::max(std::sqrt(d2) * t_.scale + t_.offset, 0.0f), top_));
    }
    // The loops only run when the rule's promise is wrong (bound[S] = +inf stops the first).
    IVec Exact(Vec d2, IVec a) const {
      uint32_t b = a + (d2 > t_.bound[a]);
      while (d2 > t_.bound[b]) ++b;
      while (b > 0 && d2 <= t_.bound[b - 1]) --b;
      return b;
    }

   private:
    const BucketTables& t_;
    float top_;
  };
};
#include "core/descriptors/cnsd_kernel_body.inc"

// Degree statistics for S + 1 <= kPackedBuckets, every pair i < j measured once and counted
// at both ends: row i's counts in sub-histograms (as in ScatterDegrees), vertex j's in its own
// counter array, complete by the time row j starts. Half the pairs of ScatterDegrees for one
// more increment each (8000 points, 19 thresholds: 300 -> 164 ms).
void PairDegrees(const PairData& p, const BucketTables& t, uint64_t* degree_sum,
                 uint64_t* degree_max) {
  const size_t n = p.n;
  const uint32_t s = t.num_thresholds;
  const size_t stride = t.stride;
  const Ops::TableBuckets buckets(t);
  std::vector<uint32_t> columns(n * stride);
  std::vector<uint32_t> scratch((t.sub_mask + 1) * stride);
  for (size_t i = 0; i < n; ++i) {
    std::fill(scratch.begin(), scratch.end(), 0u);
    for (size_t j = i + 1; j < n; ++j) {
      const float d2 = SquaredDistances(p, j, p.x[i], p.y[i], p.z[i]);
      const uint32_t b = buckets.Exact(d2, buckets.Approximate(d2));
      ++scratch[(j & t.sub_mask) * stride + b];
      ++columns[j * stride + b];
    }
    uint64_t degree = 0;
    for (uint32_t k = 0; k < s; ++k) {
      degree += columns[i * stride + k];
      for (uint32_t sub = 0; sub <= t.sub_mask; ++sub) degree += scratch[sub * stride + k];
      degree_sum[k] += degree;
      degree_max[k] = std::max(degree_max[k], degree);
    }
  }
}
}  // namespace scalar

#if defined(__x86_64__)

SHAPEID_TARGET_REGION_BEGIN("avx2")
namespace avx2 {
struct Ops : simd::Avx2Ops {
  static float ReduceMax(Vec v) {
    alignas(32) float lanes[kLanes];
    _mm256_store_ps(lanes, v);
    return *std::max_element(lanes, lanes + kLanes);
  }
  // Lanes j0 + l <= i become FLT_MAX, which lands in bucket S.
  static Vec FarUpTo(Vec d2, size_t j0, size_t i) {
    const IVec before = _mm256_cmpgt_epi32(_mm256_set1_epi32(static_cast<int>(i + 1 - j0)),
                                           _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7));
    return _mm256_blendv_ps(d2, _mm256_set1_ps(FLT_MAX), _mm256_castsi256_ps(before));
  }

  class TableBuckets {
   public:
    explicit TableBuckets(const BucketTables& t)
        : bound_(t.bound),
          scale_(_mm256_set1_ps(t.scale)),
          offset_(_mm256_set1_ps(t.offset)),
          top_(_mm256_set1_ps(static_cast<float>(t.num_thresholds))) {}
    IVec Approximate(Vec d2) const { return FromRoot(Root(d2)); }
    Vec Root(Vec d2) const { return _mm256_sqrt_ps(d2); }
    IVec FromRoot(Vec root) const {
      const Vec a = _mm256_add_ps(_mm256_mul_ps(root, scale_), offset_);
      return _mm256_max_epi32(_mm256_cvttps_epi32(_mm256_min_ps(a, top_)), _mm256_setzero_si256());
    }
    IVec Exact(Vec d2, IVec a) const {
      const Vec above = _mm256_cmp_ps(d2, _mm256_i32gather_ps(bound_, a, 4), _CMP_GT_OQ);
      return _mm256_sub_epi32(a, _mm256_castps_si256(above));  // above is -1 where d2 > bound
    }

   private:
    const float* bound_;
    Vec scale_, offset_, top_;
  };

  // bound[0 .. 8 kWords) in kWords registers; the code of bucket b is 4 b, the shift of its
  // nibble.
  template <int kWords>
  class PackedBuckets : public TableBuckets {
   public:
    explicit PackedBuckets(const BucketTables& t) : TableBuckets(t) {
      for (int w = 0; w < kWords; ++w) table_[w] = _mm256_loadu_ps(t.bound + 8 * w);
    }
    IVec Code(Vec d2, IVec a) const {
      // blendv reads the sign bit: bits 3 and 4 of a pick the register.
      const Vec bit3 = _mm256_castsi256_ps(_mm256_slli_epi32(a, 28));
      const Vec bit4 = _mm256_castsi256_ps(_mm256_slli_epi32(a, 27));
      const auto entry = [&](int w) { return _mm256_permutevar8x32_ps(table_[w], a); };
      Vec bound = entry(0);
      if constexpr (kWords == 2) bound = _mm256_blendv_ps(bound, entry(1), bit3);
      if constexpr (kWords == 3) {
        bound = _mm256_blendv_ps(_mm256_blendv_ps(bound, entry(1), bit3), entry(2), bit4);
      }
      if constexpr (kWords == 4) {
        bound = _mm256_blendv_ps(_mm256_blendv_ps(bound, entry(1), bit3),
                                 _mm256_blendv_ps(entry(2), entry(3), bit3), bit4);
      }
      const IVec above = _mm256_castps_si256(_mm256_cmp_ps(d2, bound, _CMP_GT_OQ));
      return _mm256_slli_epi32(_mm256_sub_epi32(a, above), 2);  // above is -1 where d2 > bound
    }
    // Shift counts outside [0, 31] give 0: only the word holding b gets its nibble.
    static IVec OneHot(IVec code, int w) {
      return _mm256_sllv_epi32(_mm256_set1_epi32(1),
                               _mm256_sub_epi32(code, _mm256_set1_epi32(32 * w)));
    }

   private:
    Vec table_[kWords];
  };
};
#include "core/descriptors/cnsd_kernel_body.inc"
#include "core/descriptors/cnsd_packed_kernel.inc"
}  // namespace avx2
SHAPEID_TARGET_REGION_END

SHAPEID_TARGET_REGION_BEGIN("avx512f")
namespace avx512 {
struct Ops : simd::Avx512Ops {
  static float ReduceMax(Vec v) { return _mm512_reduce_max_ps(v); }
  // Lanes j0 + l <= i become FLT_MAX, which lands in bucket S.
  static Vec FarUpTo(Vec d2, size_t j0, size_t i) {
    const __mmask16 before = static_cast<__mmask16>((1u << (i + 1 - j0)) - 1);
    return _mm512_mask_mov_ps(d2, before, _mm512_set1_ps(FLT_MAX));
  }

  class TableBuckets {
   public:
    explicit TableBuckets(const BucketTables& t)
        : bound_(t.bound),
          scale_(_mm512_set1_ps(t.scale)),
          offset_(_mm512_set1_ps(t.offset)),
          top_(_mm512_set1_ps(static_cast<float>(t.num_thresholds))) {}
    IVec Approximate(Vec d2) const { return FromRoot(Root(d2)); }
    Vec Root(Vec d2) const { return _mm512_sqrt_ps(d2); }
    IVec FromRoot(Vec root) const {
      const Vec a = _mm512_add_ps(_mm512_mul_ps(root, scale_), offset_);
      return _mm512_max_epi32(_mm512_cvttps_epi32(_mm512_min_ps(a, top_)), _mm512_setzero_si512());
    }
    IVec Exact(Vec d2, IVec a) const {
      const __mmask16 above = _mm512_cmp_ps_mask(d2, _mm512_i32gather_ps(a, bound_, 4), _CMP_GT_OQ);
      return _mm512_mask_add_epi32(a, above, a, _mm512_set1_epi32(1));
    }

   private:
    const float* bound_;
    Vec scale_, offset_, top_;
  };

  // bound[0 .. 32) in two registers; the code of bucket b is b itself, and its nibble comes
  // from a 32-entry table per word, also in two registers.
  template <int kWords>
  class PackedBuckets : public TableBuckets {
   public:
    explicit PackedBuckets(const BucketTables& t)
        : TableBuckets(t),
          bound_lo_(_mm512_loadu_ps(t.bound)),
          bound_hi_(_mm512_loadu_ps(t.bound + 16)) {
      for (int w = 0; w < kWords; ++w) {
        alignas(64) uint32_t entries[32];
        for (int b = 0; b < 32; ++b) entries[b] = b / 8 == w ? 1u << (4 * (b % 8)) : 0u;
        one_hot_lo_[w] = _mm512_load_si512(entries);
        one_hot_hi_[w] = _mm512_load_si512(entries + 16);
      }
    }
    IVec Code(Vec d2, IVec a) const {
      const Vec bound = _mm512_permutex2var_ps(bound_lo_, a, bound_hi_);
      const __mmask16 above = _mm512_cmp_ps_mask(d2, bound, _CMP_GT_OQ);
      return _mm512_mask_add_epi32(a, above, a, _mm512_set1_epi32(1));
    }
    IVec OneHot(IVec b, int w) const {
      return _mm512_permutex2var_epi32(one_hot_lo_[w], b, one_hot_hi_[w]);
    }

   private:
    Vec bound_lo_, bound_hi_;
    IVec one_hot_lo_[kWords], one_hot_hi_[kWords];
  };
};
#include "core/descriptors/cnsd_kernel_body.inc"
#include "core/descriptors/cnsd_packed_kernel.inc"
}  // namespace avx512
SHAPEID_TARGET_REGION_END

#endif  // __x86_64__

using DegreesFn = void (*)(const PairData&, const BucketTables&, uint64_t*, uint64_t*);

DegreesFn ChooseDegrees(uint32_t num_thresholds, SimdLevel level) {
  if (num_thresholds + 1 <= kPackedBuckets) {
    const uint32_t words = (num_thresholds + 1 + 7) / 8;
#if defined(__x86_64__)
    static constexpr DegreesFn kAvx2[] = {avx2::PackedDegrees<1>, avx2::PackedDegrees<2>,
                                          avx2::PackedDegrees<3>, avx2::PackedDegrees<4>};
    static constexpr DegreesFn kAvx512[] = {avx512::PackedDegrees<1>, avx512::PackedDegrees<2>,
                                            avx512::PackedDegrees<3>, avx512::PackedDegrees<4>};
    if (level == SimdLevel::kAvx512) return kAvx512[words - 1];
    if (level == SimdLevel::kAvx2) return kAvx2[words - 1];
#endif
    return scalar::PairDegrees;
  }
#if defined(__x86_64__)
  if (level == SimdLevel::kAvx512) return avx512::ScatterDegrees;
  if (level == SimdLevel::kAvx2) return avx2::ScatterDegrees;
#endif
  return scalar::ScatterDegrees;
}

}  // namespace

float MaxSquaredDistance(absl::Span<const float> xyz, SimdLevel level) {
  const size_t n = xyz.size() / 3;
  if (n < 2) return 0;
  // Only pairs with an end far from the origin can be the farthest. A pair's float squared
  // distance is at most (1 + 1e-6) times its exact square when it is a normal float (six
  // roundings of 2^-24, plus at most 3 * 2^-149 from products that underflow), and its exact
  // distance at most r_i + r_j (r: distance to the origin). So once some pair's float `lower`
  // is known, a pair reaching it has r_i + r_j >= sqrt(lower / (1 + 1e-6)): one end at least
  // half that (1e-5 below, and 1e-9 for the double roundings, for margin). Those candidates
  // go first and only their rows are measured, each pair once. For a cloud like a sphere every
  // point is a candidate; for most shapes, only the ends of the longest axis.
  std::vector<double> radius(n);
  size_t far = 0;
  for (size_t i = 0; i < n; ++i) {
    const double x = xyz[3 * i], y = xyz[3 * i + 1], z = xyz[3 * i + 2];
    radius[i] = std::sqrt(x * x + y * y + z * z);
    if (radius[i] > radius[far]) far = i;
  }
  float lower = 0;  // the float squared distance from `far` to the point farthest from it
  for (size_t j = 0; j < n; ++j) {
    const float dx = xyz[3 * j] - xyz[3 * far], dy = xyz[3 * j + 1] - xyz[3 * far + 1],
                dz = xyz[3 * j + 2] - xyz[3 * far + 2];
    lower = std::max(lower, (dx * dx + dy * dy) + dz * dz);
  }
  // Below normal floats the relative bound does not hold: measure every row.
  const double reach = lower >= FLT_MIN ? 0.5 * std::sqrt(lower / (1 + 1e-5)) * (1 - 1e-9) : 0;
  std::vector<float> ordered(xyz.begin(), xyz.end());
  size_t candidates = 0;
  for (size_t i = 0; i < n; ++i) {
    if (radius[i] < reach) continue;
    std::swap_ranges(&ordered[3 * i], &ordered[3 * i + 3], &ordered[3 * candidates]);
    ++candidates;
  }
  CacheAligned<float> storage(3 * PaddedLength(n));
  const PairData pairs = Transpose(ordered, nullptr, storage);
#if defined(__x86_64__)
  if (level == SimdLevel::kAvx512) return avx512::MaxSquaredDistance(pairs, candidates);
  if (level == SimdLevel::kAvx2) return avx2::MaxSquaredDistance(pairs, candidates);
#endif
  (void)level;
  return scalar::MaxSquaredDistance(pairs, candidates);
}

void DegreeStatistics(absl::Span<const float> xyz, const BucketRule& rule, SimdLevel level,
                      absl::Span<uint64_t> degree_sum, absl::Span<uint64_t> degree_max) {
  std::fill(degree_sum.begin(), degree_sum.end(), 0);
  std::fill(degree_max.begin(), degree_max.end(), 0);
  const size_t n = xyz.size() / 3;
  const uint32_t s = static_cast<uint32_t>(rule.bounds.size());
  if (n == 0 || s == 0) return;
  const float far_away[3] = {kFarAway, kFarAway, kFarAway};
  CacheAligned<float> storage(3 * PaddedLength(n));
  const PairData pairs = Transpose(xyz, far_away, storage);

  std::vector<float> bound(std::max<size_t>(s + 1, kPackedBuckets),
                           std::numeric_limits<float>::infinity());
  std::copy(rule.bounds.begin(), rule.bounds.end(), bound.begin());
  uint32_t subs = kMaxLanes;
  while (subs > 1 && subs * (s + 1) > kHistogramBudget) subs /= 2;
  const BucketTables tables{s, bound.data(), rule.scale, rule.offset, s + 1, subs - 1};
  ChooseDegrees(s, rule.approximate ? level : SimdLevel::kScalar)(pairs, tables, degree_sum.data(),
                                                                  degree_max.data());
}

size_t PairPassBytes(size_t n, size_t num_thresholds) {
  const size_t storage = (3 * PaddedLength(n) + kMaxLanes) * sizeof(float);  // CacheAligned
  const size_t max_pass = n * sizeof(double) + 3 * n * sizeof(float) + storage;
  const size_t buckets = num_thresholds + 1;
  const size_t end = (n + kMaxLanes - 1) / kMaxLanes * kMaxLanes;
  size_t kernel;
  if (buckets <= kPackedBuckets) {
    const size_t words = (buckets + 7) / 8;
    const size_t packed = (11 * words * end + 4 * kMaxLanes) * sizeof(uint32_t);
    const size_t scalar = (n + kMaxLanes) * buckets * sizeof(uint32_t);
    kernel = std::max(packed, scalar);
  } else {
    kernel = (std::max<size_t>(kHistogramBudget, buckets) + 2 * kMaxLanes) * sizeof(uint32_t);
  }
  const size_t bound = std::max<size_t>(buckets, kPackedBuckets) * sizeof(float);
  return std::max(max_pass, storage + bound + kernel);
}

}  // namespace shapeid::cnsd_internal
