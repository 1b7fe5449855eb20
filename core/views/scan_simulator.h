#ifndef SHAPEID_CORE_VIEWS_SCAN_SIMULATOR_H_
#define SHAPEID_CORE_VIEWS_SCAN_SIMULATOR_H_

// Simulated depth-camera scans: what one sensor sees of an object from one viewpoint, made
// from a dense sampling of the object's surface. Turns 3D models into labeled single-view
// partial clouds with noise, for training, testing and the demo. Viewpoints for a set of
// scans: view_directions.h.

#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>

#include "Eigen/Core"
#include "absl/status/statusor.h"
#include "core/point_cloud.h"

namespace shapeid {
namespace views_internal {
struct ScanBuffers;
}  // namespace views_internal

struct ScanOptions {
  // Where the camera stands, seen from the object: at the center of the surface's bounding
  // box plus distance * radius * direction, where radius is half the box's diagonal (so the
  // object lies inside the sphere of that radius), looking at the center. Need not be unit
  // length; must be finite and non-zero.
  Eigen::Vector3d direction = {0, 0, 1};
  // In object radii, in (1, 1e6]: > 1 so that the camera is outside the object. A nearer
  // camera sees the object larger (more points) and in stronger perspective (less of a round
  // object).
  double distance = 3.0;
  // Roll: the image's up is `up` made perpendicular to the viewing direction. Any finite
  // vector not parallel to `direction`. Changes only the order of the output points.
  Eigen::Vector3d up = {0, 1, 0};
  // Depth image size in pixels, 1 to 4096 each. Each pixel yields at most one point, so the
  // resolution bounds the output: at the defaults an object that fills its bounding sphere
  // covers about 8,000 pixels.
  int width = 160;
  int height = 120;
  // Vertical field of view in degrees, in (0, 170); pixels are square. The object is always
  // whole in view: when the surface's bounding box would not fit in the image, the field of
  // view is widened just enough that it does (the camera does not move), so a narrow lens or
  // a near camera frames the object tightly instead of cropping it. At the defaults (45
  // degrees, 160 x 120, distance 3) any box fits and the lens is as given.
  double fov_degrees = 45;
  // Standard deviation of Gaussian noise added to each point along its viewing ray, in object
  // radii, >= 0: depth sensors err mostly along the ray. 0.005 is 0.5 mm on an object of
  // 10 cm radius, a good sensor at close range (consumer depth cameras err by 1 to 3 mm at
  // 1 m). With 0 the output points are exact input points.
  double depth_noise = 0.005;
  // If non-zero and the scan sees more points, keep a seeded uniform random subset of this
  // many, in scan order, e.g. to give a descriptor a fixed budget. The subset draws from its
  // own stream: with the same seed it is a subset of the full scan, with the same noise.
  size_t max_points = 0;
  // Seeds the noise and the subset: the same surface, options and seed give the same bits.
  uint64_t seed = 0;
};

// Scans of one surface (a dense, uniform sampling of an object's surface, e.g. 30,000 to
// 100,000 points sampled area-weighted from a mesh), from as many viewpoints as wanted. It
// measures the surface once (bounding box, sample spacing) and keeps its buffers from scan
// to scan, so use one per surface for a set of views. Movable, not copyable; Scan is not
// thread-safe (its buffers), distinct simulators are independent.
//
// How it sees (details in scan_simulator.cc): each point is drawn into a depth buffer as a
// cone over a square of +-2 sample spacings (sample_spacing.h) around it, its range from the
// camera rising 4 times as fast as the distance from it; a point is hidden when, at the
// center of a buffer cell next to it, some cone is nearer than its own mirror cone; each
// pixel shows its nearest visible point. So a surface facing the camera hides what lies
// behind it: a spot of it with no sample in that square, through which a hidden point could
// show, turns up with probability exp(-16) = 1e-7. A surface seen at up to atan(4) = 76
// degrees from its rays keeps all its points; steeper ones lose some, as real sensors'
// returns do. The costs: a surface less than about 4 times its distance to the nearest
// sample of a nearer one behind it shows a few points (the back of a wall a few spacings
// thin; on cubes, side faces up to 7 spacings behind an edge), and a surface just behind
// an occluding edge loses a band about 2 spacings wide.
class ScanSimulator {
 public:
  // Errors (InvalidArgument): fewer than 3 points, a non-finite coordinate or zero extent,
  // as ValidateCloud; more than 2^32 - 2 points.
  static absl::StatusOr<ScanSimulator> Create(PointCloud surface);

  ScanSimulator(ScanSimulator&&);
  ScanSimulator& operator=(ScanSimulator&&);
  ~ScanSimulator();

  const PointCloud& surface() const { return surface_; }
  // 1 / sqrt(samples per unit area), as EstimateSampleSpacing (sample_spacing.h): the unit
  // of the visibility rules above.
  double sample_spacing() const { return spacing_; }

  // The points the camera described by `options` sees, in the surface's frame, in scan order
  // (image rows top to bottom, each left to right), at most one per pixel. Never empty: the
  // point nearest the camera is always seen. Which point a pixel shows does not depend on
  // the noise, the subset or the seed.
  //
  // Errors (InvalidArgument): a zero or non-finite direction; `up` zero, non-finite or
  // parallel to the direction; distance not in (1, 1e6]; width or height outside
  // [1, 4096]; fov_degrees outside (0, 170); depth_noise negative or not finite.
  //
  // When `surface_indices` is not null it is set to one entry per output point, in the same
  // order: the index in surface() of the point it shows (the ground truth of a scan of a
  // surface made of several objects). Asking for it changes nothing else.
  //
  // Work: two passes over the surface and one over the pixels, about 3 ms per 100,000
  // points on one 2 GHz core at the default resolution.
  absl::StatusOr<PointCloud> Scan(const ScanOptions& options,
                                  std::vector<uint32_t>* surface_indices = nullptr);

 private:
  ScanSimulator(PointCloud surface, const CloudStats& stats, double spacing);

  PointCloud surface_;
  Eigen::Vector3d box_min_, box_max_;
  double spacing_;
  std::unique_ptr<views_internal::ScanBuffers> buffers_;  // reused, grown to the largest scan
};

// One scan: ScanSimulator::Create(surface) and Scan(options), with both functions' errors,
// without copying the surface, `surface_indices` as Scan's. Thread-safe. For several views of one
// surface a ScanSimulator does less work (no spacing estimate, no allocation).
absl::StatusOr<PointCloud> SimulateScan(const PointCloud& surface, const ScanOptions& options,
                                        std::vector<uint32_t>* surface_indices = nullptr);

}  // namespace shapeid

#endif  // SHAPEID_CORE_VIEWS_SCAN_SIMULATOR_H_
