#ifndef SHAPEID_CORE_DESCRIPTORS_DFSD_KERNELS_H_
#define SHAPEID_CORE_DESCRIPTORS_DFSD_KERNELS_H_

// The DFSD hot loop: the squared distance from every cell center of a G^3 grid to the nearest
// point of the cloud. Internal to core; exposed for tests and benchmarks that compare SIMD
// levels.

#include <cstddef>
#include <cstdint>
#include <memory>
#include <new>
#include <vector>

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
  // Optional pruning, for tables that are geometry: row i of dx2 holds (u_i - x_p)^2 computed
  // in float as (u_i - x_p) * (u_i - x_p), with neighboring cell centers u_i at most
  // `cell_spacing` apart (the same for dy2, dz2), and the points grouped into blocks of
  // kPointLanes that lie close together (SpatialOrder). Row i of block_dx2 holds, per block, a
  // value no larger than dx2[i][p] for any of the block's points, `block_stride` apart, and
  // kFarSquared past the last block (FillAxisTables writes both). A cell then reads only the
  // blocks that can hold its nearest point: those whose bound is within reach of a finished
  // neighboring cell's distance (triangle inequality). The minima are those of reading every
  // point, bit for bit.
  const float* block_dx2 = nullptr;
  const float* block_dy2 = nullptr;
  const float* block_dz2 = nullptr;
  size_t block_stride = 0;  // a multiple of kPointLanes, at least stride / kPointLanes
  double cell_spacing = 0;
  // false: `out` is overwritten. true: each out value is lowered to the minimum over these
  // points when that is smaller, so a cloud can be fed in chunks whose tables stay in cache;
  // minima are exact, so the result has the same bits as one pass over every point.
  bool accumulate = false;
};

// The input over one buffer of tables, axis a's row i at (a * grid + i) * stride, and, when
// `bounds` is given, its block bounds laid out alike, block_stride apart (as ComputeFramed and
// FillAxisTables lay them).
inline FieldInput LaidOutInput(const float* tables, int grid, size_t stride,
                               const float* bounds = nullptr, size_t block_stride = 0,
                               double cell_spacing = 0) {
  const size_t rows = static_cast<size_t>(grid);
  FieldInput in;
  in.dx2 = tables;
  in.dy2 = tables + rows * stride;
  in.dz2 = tables + 2 * rows * stride;
  in.stride = stride;
  in.grid = grid;
  if (bounds != nullptr) {
    in.block_dx2 = bounds;
    in.block_dy2 = bounds + rows * block_stride;
    in.block_dz2 = bounds + 2 * rows * block_stride;
    in.block_stride = block_stride;
    in.cell_spacing = cell_spacing;
  }
  return in;
}

// out[(i * G + j) * G + k] = min over points p of (dx2[i][p] + dy2[j][p]) + dz2[k][p], in
// that float order on every level (and of the old out value when accumulating). Minima are
// exact, so all levels give identical bits.
// `level` must not exceed DetectedSimdLevel().
void NearestSquaredDistances(const FieldInput& input, float* out, SimdLevel level);

// Blocks of the pruned kernel for `count` points.
inline size_t BlockStride(size_t count) {
  const size_t blocks = (count + kPointLanes - 1) / kPointLanes;
  return (blocks + kPointLanes - 1) / kPointLanes * kPointLanes;
}

// A permutation of points [0, count) (coordinates coord[a][p], within [-half[a], half[a]])
// that puts points close in space close in order: buckets of a regular grid over the box, in
// Morton order, by a counting sort (O(count)). Each run of kPointLanes points is then a
// compact block for the pruned kernel.
void SpatialOrder(const double* const coord[3], size_t count, const double half[3],
                  std::vector<uint32_t>* order);

// One axis of the kernel's input for `count` points, `values` their normalized coordinates in
// the order the tables are to hold them: rows i < grid of `rows` (stride apart) get
// (centers[i] - v)^2 in float, and past `count` kFarSquared when `pad` (a first chunk; a later
// one keeps what is there). Rows i < grid of `bounds` (block_stride apart) get, per block of
// kPointLanes values (a last short block counts its own only), the smallest such square any
// of them can give, computed from the block's extremes with the same rounding; kFarSquared
// past the last block.
void FillAxisTables(const float* values, size_t count, const float* centers, int grid,
                    size_t stride, size_t block_stride, bool pad, float* rows, float* bounds);

}  // namespace shapeid::dfsd_internal

#endif  // SHAPEID_CORE_DESCRIPTORS_DFSD_KERNELS_H_
