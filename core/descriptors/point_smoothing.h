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
// Fewest neighbours a point is averaged with when smoothing is on.
inline constexpr size_t kMinSmoothingNeighbours = 8;

// The cloud smoothed: each point replaced by the mean of its k nearest points (itself
// included), k = share x the number of points, rounded, but at least
// kMinSmoothingNeighbours (and at most all of them); share 0 leaves the cloud as it is.
// A share rather than a count or a radius, so that the neighbourhood covers the same part of
// the object however densely it was sampled and whatever its units (the floor, because a
// sparse object of 150 points has 2 in its share: too few to average noise); nearest points rather
// than a ball, so that a point that noise threw off the surface is pulled back too (a ball
// around it would hold nothing else). A cloud of more than kSmoothingReferencePoints points
// is first reduced to that many of its points, chosen uniformly by a fixed seed
// (cnsd_internal::RandomDownsample: the same places whatever the coordinates, so a turned
// cloud keeps them), and those are smoothed and returned: at a descriptor's resolution they
// are the same surface, and memory and time stay bounded whatever the cloud's size.
// (Box-grid centroids would not do: a sparse cell off the surface counts as much as a full
// one, so they amplify noise.) Needs `stats` from ValidateCloud(cloud), share in [0, 1].
// Deterministic.
PointCloud SmoothPoints(const PointCloud& cloud, const CloudStats& stats, double share);

// The most heap SmoothPoints allocates for a cloud of n points, the returned cloud included.
size_t SmoothPointsBytes(size_t n);

}  // namespace shapeid

#endif  // SHAPEID_CORE_DESCRIPTORS_POINT_SMOOTHING_H_
