#ifndef SHAPEID_CORE_DESCRIPTORS_POINT_SMOOTHING_H_
#define SHAPEID_CORE_DESCRIPTORS_POINT_SMOOTHING_H_

// Noise suppression before describing (docs/descriptors.md section 5, "Smoothing"): every
// point moved to the mean of the points around it, so a surface that sensor noise has
// blurred into a shell is drawn back to the shell's middle before its distance field is taken.

#include <cstddef>

#include "core/point_cloud.h"

namespace shapeid {

// Clouds up to this size are smoothed point by point; larger ones are first reduced to this
// many of their points.
inline constexpr size_t kSmoothingReferencePoints = 4096;
// Fewest neighbors a point is averaged with when smoothing is on.
inline constexpr size_t kMinSmoothingNeighbors = 8;

// The cloud smoothed: each point replaced by the mean of its k nearest points (itself
// included), k = round(share x points) but at least kMinSmoothingNeighbors and at most all;
// share 0 leaves it as it is. A cloud over kSmoothingReferencePoints is first reduced to that
// many of its points (cnsd_internal::RandomDownsample, fixed seed), which are smoothed and
// returned, so memory and time stay bounded. Ties at the k-th distance go to a fixed order.
// Deterministic. Why nearest points, a share and this reduction: docs/descriptors.md
// section 5, step 0.
PointCloud SmoothPoints(const PointCloud& cloud, double share);

// The most heap SmoothPoints allocates for a cloud of n points, the returned cloud included.
size_t SmoothPointsBytes(size_t n);

}  // namespace shapeid

#endif  // SHAPEID_CORE_DESCRIPTORS_POINT_SMOOTHING_H_
