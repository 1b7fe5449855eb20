#ifndef SHAPEID_CORE_SCENE_SCENE_SEGMENTATION_H_
#define SHAPEID_CORE_SCENE_SCENE_SEGMENTATION_H_

// A sensor frame into the objects on it: the tabletop chain of PCL's tutorials and ROS's
// tabletop detector (dominant planes removed by RANSAC, the rest split into Euclidean
// clusters), in one pass and without a kd-tree. Distances are in the frame's units (metres
// for ROS and most depth cameras); the defaults assume metres.

#include <cstddef>
#include <cstdint>
#include <functional>
#include <optional>
#include <vector>

#include "Eigen/Core"
#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "core/point_cloud.h"

namespace shapeid {

struct SceneSegmentationOptions {
  // Supporting planes to remove, largest first (a table, a floor, a wall), in [0, 16].
  int max_planes = 1;
  // A point closer than this to a plane lies on it (strictly, as PCL's SACSegmentation). > 0.
  float plane_distance = 0.01f;
  // A plane is removed only if it holds at least this share of the frame's usable points
  // (finite, in the region): an object's flat face is not a support. In (0, 1].
  double min_plane_share = 0.05;
  // Plane hypotheses tried at most per plane. RANSAC stops earlier once it is 99.9 % sure
  // that a better plane would have been drawn. In [1, 10000].
  int plane_iterations = 1000;
  // Two points closer than this belong to the same object (strictly less, as PCL's
  // EuclideanClusterExtraction and Open3D's cluster_dbscan with min_points 1); objects are
  // the connected groups, the same partition those give. > 0.
  float cluster_tolerance = 0.02f;
  // Clusters with fewer points are dropped as noise; with more, as background (a wall the
  // planes missed). 1 <= min <= max.
  size_t min_cluster_points = 100;
  size_t max_cluster_points = 1'000'000;
  // Points outside this axis-aligned box (inclusive) are ignored: the work area in front of
  // a robot. Bounds may be infinite (everything above a height). Unset: the whole frame.
  struct Box {
    Eigen::Vector3f min;
    Eigen::Vector3f max;
  };
  std::optional<Box> region;
  // Which way is up in the frame (any finite length > 0), when the caller knows it (a
  // sensor's mounting, an IMU): only planes whose normal is within max_plane_tilt_degrees of
  // it are removed, so a wall or a tall object's side is never taken for the support (PCL's
  // SACMODEL_PERPENDICULAR_PLANE), and their normals point up. Unset: any plane, its normal
  // towards the frame's origin.
  std::optional<Eigen::Vector3f> up;
  double max_plane_tilt_degrees = 15;  // in (0, 90]
  // Seeds RANSAC's draws: the same frame, options and seed give the same planes and clusters.
  uint64_t seed = 0;
  // Asked before each plane and before clustering: a non-OK status (a caller's deadline, a
  // cancelled call) stops the segmentation and is returned. Empty: never stop.
  std::function<absl::Status()> interrupt;
};

// A removed plane: a x + b y + c z + d = 0 with (a, b, c) a unit normal, refitted by least
// squares to its points (PCL's optimizeCoefficients). The normal points up when `up` was
// given, else to the frame's origin's side (d >= 0: the sensor's side, in a sensor's frame;
// either side for a plane through the origin).
struct ScenePlane {
  Eigen::Vector4f coefficients = Eigen::Vector4f::Zero();
  size_t points = 0;  // how many of the frame's points were removed with it
};

struct SceneSegmentation {
  std::vector<ScenePlane> planes;  // in the order removed
  // The objects: indices into the frame, ascending within a cluster; clusters largest first
  // (ties: the one with the smaller first index first; PCL leaves ties in no set order).
  std::vector<std::vector<uint32_t>> clusters;
  // Where the other points went. Together with the planes' and the clusters' points they
  // account for every point of the frame.
  size_t non_finite_points = 0;  // NaN or infinite coordinates: skipped (organized frames)
  size_t outside_region = 0;
  size_t in_small_clusters = 0;  // fewer than min_cluster_points
  size_t in_large_clusters = 0;  // more than max_cluster_points
};

// Removes up to max_planes planes and clusters the remaining points. Non-finite points are
// skipped, never an error: depth cameras mark missing pixels with NaN. A frame with no
// usable point, or whose every point lies on planes, gives no clusters (not an error).
// Errors: InvalidArgument for options out of their ranges, a frame more than about 605,000
// cluster tolerances across (2^20 grid cells of tolerance / sqrt(3): widen the tolerance or
// set a region), or more than 2^32 - 2 points; options.interrupt's.
absl::StatusOr<SceneSegmentation> SegmentScene(const PointCloud& frame,
                                               const SceneSegmentationOptions& options);
// SegmentScene's check of its options alone (InvalidArgument naming the field), for callers
// that refuse bad options before they have a frame.
absl::Status ValidateSceneSegmentationOptions(const SceneSegmentationOptions& options);

// The smallest box along the principal axes of `indices`' points (their covariance's
// eigenvectors; extents from the points' projections).
struct OrientedBox {
  Eigen::Vector3f center = Eigen::Vector3f::Zero();
  // Columns: the box's axes, a right-handed rotation; the first along the largest spread.
  Eigen::Matrix3f axes = Eigen::Matrix3f::Identity();
  Eigen::Vector3f size = Eigen::Vector3f::Zero();  // extent along each axis
};
struct ClusterGeometry {
  Eigen::Vector3f centroid = Eigen::Vector3f::Zero();  // mean of the points
  OrientedBox box;
};
// `indices` must be non-empty and index finite points of `frame`.
ClusterGeometry DescribeClusterGeometry(const PointCloud& frame,
                                        const std::vector<uint32_t>& indices);

}  // namespace shapeid

#endif  // SHAPEID_CORE_SCENE_SCENE_SEGMENTATION_H_
