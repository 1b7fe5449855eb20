#ifndef SHAPEID_CORE_DESCRIPTORS_COMSD_H_
#define SHAPEID_CORE_DESCRIPTORS_COMSD_H_

// COMSD-3D, the Co-Occurrence Matrices Shape Descriptor (docs/descriptors.md section 2):
// a binary N^3 voxel grid, one 2 x 2 co-occurrence matrix per 13 directions, 7 Haralick-style
// features per matrix: 91 floats, direction-major.

#include <array>
#include <cstdint>
#include <vector>

#include "absl/types/span.h"
#include "core/descriptor_registry.h"
#include "core/point_cloud.h"

namespace shapeid {

// Registry entry: kind "comsd", one parameter `grid` (N, default 50, range [2, 512]).
// Canonical spec "comsd:grid=<N>".
DescriptorKind ComsdKind();

// The pieces of the computation, exposed so tests can check each one (and both popcount
// paths) against a brute-force reference. Not for use outside core/.
namespace comsd_internal {

inline constexpr int kMinGrid = 2;
inline constexpr int kMaxGrid = 512;
inline constexpr int kNumDirections = 13;
inline constexpr int kNumFeatures = 7;
inline constexpr int kDimension = kNumDirections * kNumFeatures;

// One co-occurrence direction. dx moves along x (grid index j), dy along y (index i), dz along
// z (index k). Every direction has dz in {0, 1}, which the packed counting relies on.
struct Direction {
  int dx, dy, dz;
};
// In the spec's order.
inline constexpr std::array<Direction, kNumDirections> kDirections = {{
    {1, 0, 0},
    {1, 1, 0},
    {0, 1, 0},
    {-1, 1, 0},
    {0, 0, 1},
    {1, 0, 1},
    {0, 1, 1},
    {-1, 0, 1},
    {0, -1, 1},
    {1, 1, 1},
    {-1, 1, 1},
    {1, -1, 1},
    {-1, -1, 1},
}};

// Binary n^3 grid packed along z: row (i, j) is `words` = ceil(n / 64) uint64 words starting
// at bits[(i * n + j) * words]; voxel (i, j, k) is bit k % 64 of word k / 64. Bits at k >= n
// are always 0.
struct PackedGrid {
  int n = 0;
  int words = 0;
  std::vector<uint64_t> bits;

  bool Get(int i, int j, int k) const {
    const uint64_t word = bits[(static_cast<size_t>(i) * n + j) * words + k / 64];
    return (word >> (k % 64)) & 1;
  }
};

// Voxelizes a validated cloud (stats from ValidateCloud) into an n^3 grid, n in
// [kMinGrid, kMaxGrid]: index = floor((v - vmin) / (vmax - vmin) * (n - 1)) per axis in
// float arithmetic, i from y, j from x, k from z; an axis of zero extent maps to 0.
PackedGrid Voxelize(const PointCloud& cloud, const CloudStats& stats, int n);

// counts[a][b]: pairs (v, v + d), both inside the grid, with V[v] = a and V[v + d] = b.
struct CooccurrenceCounts {
  int64_t counts[2][2] = {{0, 0}, {0, 0}};
};
using AllCounts = std::array<CooccurrenceCounts, kNumDirections>;

enum class PopcountPath {
  kPortable,  // SWAR bit counting, any CPU
  kHardware,  // the POPCNT instruction; falls back to kPortable where the CPU lacks it
};
// True when kHardware really uses the POPCNT instruction on this CPU.
bool HardwarePopcountAvailable();

// The 13 co-occurrence matrices of `grid`. Both paths give identical counts.
AllCounts CountCooccurrences(const PackedGrid& grid, PopcountPath path);

// The 7 features of each direction's normalized matrix, in double, written as floats into
// `out` (kDimension values, direction-major).
void ComputeFeatures(const AllCounts& counts, absl::Span<float> out);

}  // namespace comsd_internal
}  // namespace shapeid

#endif  // SHAPEID_CORE_DESCRIPTORS_COMSD_H_
