#ifndef SHAPEID_CORE_DESCRIPTORS_POINT_NETWORK_KERNELS_H_
#define SHAPEID_CORE_DESCRIPTORS_POINT_NETWORK_KERNELS_H_

// The point network's hot loop: one shared per-point layer, max(0, W x + b) for every point,
// vectorised across points. Internal to core; exposed for point_network.cc and its tests.

#include <cstddef>

#include "core/simd.h"

namespace shapeid::point_network_internal {

// Points are processed in blocks of this many (4 AVX-512 vectors); a padded point count, the
// stride of every activation row, is a multiple of it.
inline constexpr size_t kPointBlock = 64;

struct LayerInput {
  const float* weight = nullptr;  // units x inputs, row-major
  const float* bias = nullptr;    // units
  int inputs = 0;
  int units = 0;
  // Row i (0 <= i < inputs) of the activations starts at i * stride; every column is a point
  // (padding columns are copies of real points, so they change no maximum).
  const float* activations = nullptr;
  size_t stride = 0;  // a positive multiple of kPointBlock
};

// For every unit u and point p: r = ((0 + w[u][0] x[0][p]) + w[u][1] x[1][p]) + ... summed in
// input order, then r + b[u], then r if r > 0 else +0: the same IEEE operations in the same
// order on every level, so every level gives identical bits. Writes r to out[u * stride + p]
// when `out` is not null; writes the maximum of r over all stride points to pooled[u] when
// `pooled` is not null. `level` must not exceed DetectedSimdLevel().
void DenseReluLayer(const LayerInput& input, float* out, float* pooled, SimdLevel level);

}  // namespace shapeid::point_network_internal

#endif  // SHAPEID_CORE_DESCRIPTORS_POINT_NETWORK_KERNELS_H_
