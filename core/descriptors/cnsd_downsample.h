#ifndef SHAPEID_CORE_DESCRIPTORS_CNSD_DOWNSAMPLE_H_
#define SHAPEID_CORE_DESCRIPTORS_CNSD_DOWNSAMPLE_H_

// The two ways CNSD-3D shrinks a cloud over max_points before its O(n^2) pair pass
// (docs/descriptors.md section 3, "Downsampling"). Internal to core; exposed for tests.

#include <cstddef>
#include <cstdint>

#include "core/point_cloud.h"

namespace shapeid::cnsd_internal {

// Box-grid filter: the centroid (summed in double) of the points in each occupied cell of a
// grid of cubic cells anchored at the bounding-box minimum. The cell size is found by 20
// steps of geometric bisection between extent / 2^20 and the largest extent, keeping the
// smallest size tried whose grid has at most `max_points` occupied cells. Cells come out
// sorted by (x, y, z) cell index. Needs max_points >= 8 (at the largest extent at most 8
// cells are occupied, and the two ends of the widest axis are in different cells, so at
// least 2 points come out). Returns the cloud unchanged when it already fits.
PointCloud VoxelDownsample(const PointCloud& cloud, size_t max_points);

// Exactly `max_points` points chosen uniformly without replacement (partial Fisher-Yates
// driven by splitmix64 seeded with `seed`), in their original order. Memory O(max_points),
// whatever the cloud's size. Returns the cloud unchanged when it already fits.
PointCloud RandomDownsample(const PointCloud& cloud, size_t max_points, uint64_t seed);

// The most heap VoxelDownsample or RandomDownsample allocates for a cloud of n points,
// the returned cloud included.
size_t VoxelDownsampleBytes(size_t n, size_t max_points);
size_t RandomDownsampleBytes(size_t n, size_t max_points);

}  // namespace shapeid::cnsd_internal

#endif  // SHAPEID_CORE_DESCRIPTORS_CNSD_DOWNSAMPLE_H_
