#ifndef SHAPEID_CORE_VIEWS_SAMPLE_SPACING_H_
#define SHAPEID_CORE_VIEWS_SAMPLE_SPACING_H_

#include "core/point_cloud.h"

namespace shapeid {

// The mean spacing of a surface sampling: 1 / sqrt(points per unit of surface area), so that
// a disc of radius k * spacing holds pi * k^2 samples on average. For the uniform, area-weighted
// samplings the mesh readers make, the chance that a spot of the surface has no sample within
// k * spacing is exp(-pi k^2); the scan simulator sizes its splats from this.
//
// Estimated from ball counts: 256 probe points (a fixed stride through the cloud, so the
// answer does not depend on any seed) count their neighbors within a radius g among every
// k-th point (k = 1 up to 32,768 points, 4 for 100,000); the density is the total count
// times k over 256 * pi * g^2. A ball of radius g on a smooth surface holds about
// pi * g^2 of area (exactly so on a sphere, at any radius up to its diameter); g is grown or
// shrunk until the probes see about 8 to 256 neighbors each. One pass over those points per
// try (usually one try), through a hash of the probes' neighbor cells; no per-point
// allocation.
//
// Open edges and thin parts (rods narrower than g) lower the counts, so the spacing comes out
// larger than the truth there: the safe side for occlusion. `stats` must be ValidateCloud's
// result for `surface`. Always positive and finite.
double EstimateSampleSpacing(const PointCloud& surface, const CloudStats& stats);

}  // namespace shapeid

#endif  // SHAPEID_CORE_VIEWS_SAMPLE_SPACING_H_
