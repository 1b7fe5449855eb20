#ifndef SHAPEID_CORE_VIEWS_VIEW_DIRECTIONS_H_
#define SHAPEID_CORE_VIEWS_VIEW_DIRECTIONS_H_

#include <cstddef>
#include <vector>

#include "Eigen/Core"
#include "absl/status/statusor.h"

namespace shapeid {

// `n` unit viewpoint directions (for ScanOptions::direction) spread evenly over the band of
// elevations [min_elevation_deg, max_elevation_deg] above the plane perpendicular to `up`:
// e.g. 10 to 60 for a robot looking down at objects on a table, -90 to 90 for the whole
// sphere. A Fibonacci lattice: direction i has sin(elevation) at the middle of the i-th of n
// equal steps from the band's bottom to its top (equal areas), and azimuth i times the golden
// angle (137.5 degrees) plus `azimuth_offset_deg`, turning right-handedly about `up` from
// +z made perpendicular to `up` (from +x when `up` is along z).
//
// Two calls with the same n and band whose offsets differ (mod 360) share no direction:
// direction i of each has the same elevation and a different azimuth (except at elevation
// +-90 degrees, where azimuth means nothing). So offset 0 gives training views and e.g.
// offset 180 / n interleaved test views.
//
// InvalidArgument for `up` zero or non-finite; elevations not within -90 <= min <= max <= 90;
// a non-finite offset. n = 0 gives an empty vector.
absl::StatusOr<std::vector<Eigen::Vector3d>> ViewDirections(size_t n, const Eigen::Vector3d& up,
                                                            double min_elevation_deg,
                                                            double max_elevation_deg,
                                                            double azimuth_offset_deg = 0);

}  // namespace shapeid

#endif  // SHAPEID_CORE_VIEWS_VIEW_DIRECTIONS_H_
