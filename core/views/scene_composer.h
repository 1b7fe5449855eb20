#ifndef SHAPEID_CORE_VIEWS_SCENE_COMPOSER_H_
#define SHAPEID_CORE_VIEWS_SCENE_COMPOSER_H_

// Tabletop test scenes with the truth of every point: objects (sampled surfaces) scaled to
// real sizes, turned about their up axis and set on a sampled table top, then seen in one
// scan of the depth-camera simulator (scan_simulator.h). For accuracy runs of scene
// recognition; an independent ray-caster of primitives is core/testing/tabletop_frames.h.

#include <cstdint>
#include <string>
#include <vector>

#include "Eigen/Core"
#include "Eigen/Geometry"
#include "absl/status/statusor.h"
#include "absl/types/span.h"
#include "core/point_cloud.h"

namespace shapeid {

// Whether an object's class is in the gallery under test, or must be answered unknown.
enum class SceneRole { kGallery, kClutter };

// One object to place: a dense enough, uniform sampling of its surface (a hidden surface
// shows through holes wider than the sampling), in any units and pose.
struct SceneObjectModel {
  std::string label;
  SceneRole role = SceneRole::kGallery;
  PointCloud surface;
  // The model's up in its own coordinates (any finite non-zero length): it stands on the
  // table with this axis vertical.
  Eigen::Vector3d up = Eigen::Vector3d::UnitZ();
};

// Lengths in metres. In the table's frame the top is z = 0, centered on the origin, x along
// its width, z up.
struct SceneComposerOptions {
  double table_width = 1.0;
  double table_depth = 0.7;
  // Each object is scaled uniformly so that its largest extent (upright, axis-aligned box)
  // is drawn uniformly in [min_size, max_size]. 0 < min_size <= max_size.
  double min_size = 0.10;
  double max_size = 0.35;
  // Objects' footprints stay this far inside the table's edges. >= 0.
  double edge_margin = 0.02;
  // Each object after the first leans on an earlier one (its footprint max_contact_gap or
  // less from it, overlapping no other) with this probability, else stands at least min_gap
  // from every other. In [0, 1]. Gaps are between the footprints' sample points.
  double touch_probability = 0.0;
  double min_gap = 0.05;           // > 0
  double max_contact_gap = 0.005;  // > 0, < min_gap
  // The table's sample spacing; 0: the sparsest object's, after scaling (the simulator's
  // visibility works at one spacing, the whole surface's). >= 0.
  double table_spacing = 0;
  // The camera looks at the scene's bounding box center from an elevation drawn in
  // [min, max] degrees above the table and any azimuth, at `distance` radii of the scene's
  // bounding sphere (ScanOptions::distance): near enough that the table fills the view.
  double min_elevation_degrees = 30;
  double max_elevation_degrees = 60;
  double distance = 1.6;
  int width = 640;
  int height = 480;
  double fov_degrees = 55;
  double depth_noise = 0.002;  // standard deviation along each ray, metres, >= 0
  uint64_t seed = 1;
};

struct ComposedObject {
  size_t model = 0;  // index into the models given
  std::string label;
  SceneRole role = SceneRole::kGallery;
  // The model's coordinates into the table's: scale, then the rotation, then the translation.
  double scale = 1;
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();
  Eigen::Vector3d size = Eigen::Vector3d::Zero();  // axis-aligned extent, table frame
  // No other object's footprint within min_gap.
  bool separated = true;
  size_t points = 0;  // frame points that are this object's
};

struct ComposedScene {
  // The scan in the camera's optical frame (x right, y down, z forward, the camera at the
  // origin), unorganized: what a depth camera driver gives after dropping empty pixels.
  PointCloud frame;
  // Per frame point: 0 the table, i the object objects[i - 1].
  std::vector<uint16_t> truth;
  // The objects placed, in placement order; models that found no room are left out.
  std::vector<ComposedObject> objects;
  Eigen::Isometry3d camera_to_table = Eigen::Isometry3d::Identity();
  double table_spacing = 0;
};

// Places the models (all that fit; fewer when the table is crowded) and scans the scene.
// Seeded: the same models, options and seed give the same bits.
// Errors (InvalidArgument): options out of range; no models, or more than 65,534; a model
// whose surface is invalid (ValidateCloud) or whose up is zero or not finite; a table that
// would need more than 20,000,000 samples.
absl::StatusOr<ComposedScene> ComposeScene(absl::Span<const SceneObjectModel> models,
                                           const SceneComposerOptions& options);

}  // namespace shapeid

#endif  // SHAPEID_CORE_VIEWS_SCENE_COMPOSER_H_
