#ifndef SHAPEID_CORE_DESCRIPTORS_DFSD_FRAME_H_
#define SHAPEID_CORE_DESCRIPTORS_DFSD_FRAME_H_

// The frame DFSD lays its grid in (docs/descriptors.md section 5): the plane geometry of the
// box and upright frames (convex hull, smallest rectangle) and the four frames themselves.
// Internal to core; exposed for dfsd.cc and tests.

#include <vector>

#include "Eigen/Core"
#include "core/descriptors/dfsd.h"
#include "core/point_cloud.h"

namespace shapeid {
namespace dfsd_internal {

// The cloud in the descriptor's frame, relative to the centre of its bounding box there:
// structure-of-arrays doubles, and the box's half extents.
struct FramedCloud {
  std::vector<double> coord[3];
  Eigen::Vector3d half_extent = Eigen::Vector3d::Zero();
  // frame=box and upright: |third moment| / second moment^1.5 of the points along each axis,
  // about their centroid (0 for an axis without spread). Near 0, the axis's sign is a guess.
  Eigen::Vector3d skewness = Eigen::Vector3d::Zero();
};

// The cloud (validated; `stats` from ValidateCloud) in the frame `options.frame` chooses.
FramedCloud Frame(const PointCloud& cloud, const CloudStats& stats, const DfsdOptions& options);

// The convex hull of 2D points, counter-clockwise, without collinear points (Andrew's
// monotone chain). Reorders and shrinks `points`.
std::vector<Eigen::Vector2d> ConvexHull(std::vector<Eigen::Vector2d>& points);

// The direction (unit 2D vector) of the smallest-area rectangle around a convex polygon:
// some side of that rectangle lies along a polygon edge (Freeman and Shapira 1975), so
// trying every edge direction is exact. Returns false for fewer than 3 hull points.
bool MinAreaRectangle(const std::vector<Eigen::Vector2d>& hull, Eigen::Vector2d* direction,
                      double* area);

}  // namespace dfsd_internal
}  // namespace shapeid

#endif  // SHAPEID_CORE_DESCRIPTORS_DFSD_FRAME_H_
