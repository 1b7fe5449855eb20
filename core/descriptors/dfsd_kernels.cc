#include "core/descriptors/dfsd_kernels.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
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

// The largest squared distance a cell's nearest point can have when the cell's neighbor,
// `spacing` away, has its nearest at squared distance `neighbor` (triangle inequality),
// widened past what float rounding of either can take from it.
float Reach(float neighbor, double spacing) {
  const double radius = std::sqrt(static_cast<double>(neighbor)) + spacing * (1 + 1e-6);
  const double reach = radius * radius * (1 + 1e-5) + 1e-30;
  return reach >= kFarSquared ? kFarSquared : static_cast<float>(reach);
}

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

// Portable path of the pruned kernel: the same block bounds, one cell at a time, its reach
// from the column before only (the minima do not depend on which blocks are skipped).
void PrunedKernelScalar(const FieldInput& in, float* out) {
  const size_t stride = in.stride;
  const size_t block_stride = in.block_stride;
  const size_t blocks = stride / kPointLanes;
  const int g = in.grid;
  for (int i = 0; i < g; ++i) {
    const float* dx2 = in.dx2 + static_cast<size_t>(i) * stride;
    const float* bx2 = in.block_dx2 + static_cast<size_t>(i) * block_stride;
    for (int j = 0; j < g; ++j) {
      const float* dy2 = in.dy2 + static_cast<size_t>(j) * stride;
      const float* by2 = in.block_dy2 + static_cast<size_t>(j) * block_stride;
      float* column = out + (static_cast<size_t>(i) * g + j) * g;
      const float* neighbor = j > 0   ? column - g
                              : i > 0 ? out + static_cast<size_t>(i - 1) * g * g
                                      : nullptr;
      for (int k = 0; k < g; ++k) {
        const float* z = in.dz2 + static_cast<size_t>(k) * stride;
        const float* bz2 = in.block_dz2 + static_cast<size_t>(k) * block_stride;
        float m = in.accumulate ? column[k] : kFarSquared;
        const float limit =
            neighbor == nullptr ? m : std::min(m, Reach(neighbor[k], in.cell_spacing));
        for (size_t b = 0; b < blocks; ++b) {
          if (!((bx2[b] + by2[b]) + bz2[b] <= limit)) continue;
          for (size_t p = b * kPointLanes; p < (b + 1) * kPointLanes; ++p) {
            m = std::min(m, (dx2[p] + dy2[p]) + z[p]);
          }
        }
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
  if (input.block_dx2 != nullptr) {
#if defined(__x86_64__)
    if (level == SimdLevel::kAvx512) return avx512::PrunedKernel(input, out);
    if (level == SimdLevel::kAvx2) return avx2::PrunedKernel(input, out);
#endif
    return PrunedKernelScalar(input, out);
  }
#if defined(__x86_64__)
  if (level == SimdLevel::kAvx512) return avx512::Kernel(input, out);
  if (level == SimdLevel::kAvx2) return avx2::Kernel(input, out);
#endif
  (void)level;
  KernelScalar(input, out);
}

void SpatialOrder(const double* const coord[3], size_t count, const double half[3],
                  std::vector<uint32_t>* order) {
  // 2^bits buckets per axis, about four points to a bucket, at most 2^15 buckets.
  int bits = 1;
  while (bits < 5 && (size_t{1} << (3 * bits)) * 4 < count) ++bits;
  const int side = 1 << bits;
  double scale[3];
  for (int a = 0; a < 3; ++a) scale[a] = half[a] > 0 ? side / (2 * half[a]) : 0;
  std::vector<uint32_t> key(count);
  std::vector<uint32_t> first((size_t{1} << (3 * bits)) + 1, 0);
  for (size_t p = 0; p < count; ++p) {
    uint32_t code = 0;
    for (int a = 0; a < 3; ++a) {
      const int cell =
          std::clamp(static_cast<int>((coord[a][p] + half[a]) * scale[a]), 0, side - 1);
      for (int t = 0; t < bits; ++t) {
        code |= static_cast<uint32_t>((cell >> t) & 1) << (3 * t + a);
      }
    }
    key[p] = code;
    ++first[code + 1];
  }
  for (size_t c = 1; c < first.size(); ++c) first[c] += first[c - 1];
  order->resize(count);
  for (size_t p = 0; p < count; ++p) (*order)[first[key[p]]++] = static_cast<uint32_t>(p);
}

void FillAxisTables(const float* values, size_t count, const float* centers, int grid,
                    size_t stride, size_t block_stride, bool pad, float* rows, float* bounds) {
  // Row by row, so each row is one contiguous loop the compiler vectorizes.
  for (int i = 0; i < grid; ++i) {
    float* row = rows + static_cast<size_t>(i) * stride;
    const float center = centers[i];
    for (size_t p = 0; p < count; ++p) {
      const float d = center - values[p];
      row[p] = d * d;
    }
    if (pad) std::fill(row + count, row + stride, kFarSquared);
  }
  const size_t blocks = (count + kPointLanes - 1) / kPointLanes;
  std::vector<float> lo(blocks), hi(blocks);
  for (size_t b = 0; b < blocks; ++b) {
    const size_t end = std::min(count, (b + 1) * kPointLanes);
    float low = values[b * kPointLanes], high = low;
    for (size_t p = b * kPointLanes + 1; p < end; ++p) {
      low = std::min(low, values[p]);
      high = std::max(high, values[p]);
    }
    lo[b] = low;
    hi[b] = high;
  }
  for (int i = 0; i < grid; ++i) {
    float* row = bounds + static_cast<size_t>(i) * block_stride;
    const float center = centers[i];
    // Rounding is monotonic: a value v >= lo gives |center - v| >= lo - center in float too,
    // and so a square no smaller.
    for (size_t b = 0; b < blocks; ++b) {
      const float gap = std::max({0.0f, lo[b] - center, center - hi[b]});
      row[b] = gap * gap;
    }
    std::fill(row + blocks, row + block_stride, kFarSquared);
  }
}

}  // namespace shapeid::dfsd_internal
