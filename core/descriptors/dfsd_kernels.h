#ifndef SHAPEID_CORE_DESCRIPTORS_DFSD_KERNELS_H_
#define SHAPEID_CORE_DESCRIPTORS_DFSD_KERNELS_H_

// The DFSD hot loop: the squared distance from every cell center of a G^3 grid to the nearest
// point of the cloud. Internal to core; exposed for tests and benchmarks that compare SIMD
// levels.

#include <cstddef>
#include <memory>
#include <new>

#include "core/simd.h"

namespace shapeid::dfsd_internal {

// Points are stored structure-of-arrays, padded to a multiple of this many lanes so every SIMD
// level loads whole vectors. Padding entries hold kFarSquared, which no real point exceeds
// (coordinates are normalized to [-1, 1]), so padding never wins a minimum.
inline constexpr size_t kPointLanes = 16;
inline constexpr float kFarSquared = 1e30f;

// Float buffers for the tables and the kernel's own row, starting on a cache line: with the
// stride a multiple of kPointLanes (64 bytes), every row then starts on one, and no vector
// load straddles two lines. malloc's 16-byte alignment leaves three chances in four that
// every AVX-512 load does, and the kernel then runs 5-15 % slower (docs/performance.md,
// "DFSD"). The kernel takes any alignment and gives the same minima.
inline constexpr std::align_val_t kRowAlignment{64};
struct AlignedFloatsFree {
  void operator()(float* p) const { ::operator delete(p, kRowAlignment); }
};
using AlignedFloats = std::unique_ptr<float[], AlignedFloatsFree>;
// n floats, uninitialized.
inline AlignedFloats MakeAlignedFloats(size_t n) {
  return AlignedFloats(static_cast<float*>(::operator new(n * sizeof(float), kRowAlignment)));
}

// The grid is separable: |c - p|^2 = (c_x - p_x)^2 + (c_y - p_y)^2 + (c_z - p_z)^2, and the
// cell centers take only G values per axis. So the caller tabulates, per axis a and center
// coordinate u_i, the squared differences to every point once (G * n values per axis), and
// a cell costs two additions and a minimum per point instead of a full distance.
struct FieldInput {
  // Row i (0 <= i < grid) of each table starts at i * stride: (u_i - p_a)^2 for every point
  // p, then kFarSquared up to the stride.
  const float* dx2 = nullptr;
  const float* dy2 = nullptr;
  const float* dz2 = nullptr;
  size_t stride = 0;  // padded point count, a positive multiple of kPointLanes
  int grid = 0;       // G
  // false: `out` is overwritten. true: each out value is lowered to the minimum over these
  // points when that is smaller, so a cloud can be fed in chunks whose tables stay in cache;
  // minima are exact, so the result has the same bits as one pass over every point.
  bool accumulate = false;
};

// out[(i * G + j) * G + k] = min over points p of (dx2[i][p] + dy2[j][p]) + dz2[k][p], in
// that float order on every level (and of the old out value when accumulating). Minima are
// exact, so all levels give identical bits.
// `level` must not exceed DetectedSimdLevel().
void NearestSquaredDistances(const FieldInput& input, float* out, SimdLevel level);

}  // namespace shapeid::dfsd_internal

#endif  // SHAPEID_CORE_DESCRIPTORS_DFSD_KERNELS_H_
