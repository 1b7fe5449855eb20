#ifndef SHAPEID_CORE_VIEWS_PERTURB_H_
#define SHAPEID_CORE_VIEWS_PERTURB_H_

// Seeded perturbations of a point cloud: random yaw, random 3D rotation, Gaussian noise,
// random subsampling and single-view partial views. They make robustness test sets
// (bench/accuracy_grid.cc) and training-time view augmentation.
//
// Every function is pure (the input is never modified) and deterministic: the same cloud,
// parameters and seed give the same bits on every platform. The random numbers come from
// SplitMix64 (core/random.h) and are turned into angles, directions and normal deviates with
// IEEE-exact operations only (+ - * / and sqrt; no sin, cos or log from the C library, whose
// last bits differ between implementations). Geometry is done in double, rounded to float
// once per coordinate. Thread-safe.
//
// Seeds: to perturb a data set reproducibly whatever the thread order, give each cloud its
// own seed from DeriveSeed(base_seed, a stable key such as its relative path).

#include <cstddef>
#include <cstdint>
#include <string>

#include "Eigen/Core"
#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "core/point_cloud.h"
#include "core/random.h"

namespace shapeid {

// A seed for one item of a run: FNV-1a (64-bit) of `key`, combined with `base_seed` through
// splitmix64. Different keys or base seeds give unrelated seeds.
uint64_t DeriveSeed(uint64_t base_seed, absl::string_view key);

// The object's extent: the diagonal of its axis-aligned bounding box (0 for fewer than 2
// distinct points). Noise levels are fractions of it.
double CloudExtent(const PointCloud& cloud);

// Mean of the points, accumulated in double; zero for an empty cloud.
Eigen::Vector3d CloudCentroid(const PointCloud& cloud);

// Rotation by an angle uniform in [0, 2 pi) about the unit axis `up` (a right-handed turn).
// The angle's cosine and sine come from a point drawn uniformly in the unit disc and
// normalized. `up` must be finite and non-zero (normalized here).
Eigen::Matrix3d RandomYawMatrix(const Eigen::Vector3d& up, SplitMix64& rng);

// A rotation uniform over SO(3) (Haar measure), by Shoemake's method ("Uniform random
// rotations", Graphics Gems III, 1992): u1 uniform in [0, 1) and two angles t2, t3 uniform in
// [0, 2 pi) give the unit quaternion (sqrt(1 - u1) sin t2, sqrt(1 - u1) cos t2,
// sqrt(u1) sin t3, sqrt(u1) cos t3); each angle's sine and cosine are drawn as in
// RandomYawMatrix.
Eigen::Matrix3d RandomRotationMatrix(SplitMix64& rng);

// p -> R (p - c) + c about the centroid c, so the centroid stays where it is.
PointCloud RotateAboutCentroid(const PointCloud& cloud, const Eigen::Matrix3d& rotation);

// The cloud turned about its centroid by a random yaw about `up` (RandomYawMatrix): the
// coordinate along `up` of every point is unchanged (up to rounding). InvalidArgument for a
// zero or non-finite `up`.
absl::StatusOr<PointCloud> RandomYaw(const PointCloud& cloud, const Eigen::Vector3d& up,
                                     uint64_t seed);

// The cloud turned about its centroid by a uniformly random 3D rotation
// (RandomRotationMatrix). Pairwise distances are preserved (up to float rounding).
PointCloud RandomRotation(const PointCloud& cloud, uint64_t seed);

// Every coordinate of every point plus an independent normal deviate of standard deviation
// sigma = sigma_fraction * CloudExtent(cloud) (so a point moves by sigma * sqrt(3) on
// average in 3D). Deviates by Marsaglia's polar method. InvalidArgument unless
// sigma_fraction is finite and >= 0; 0 returns the cloud unchanged.
absl::StatusOr<PointCloud> AddGaussianNoise(const PointCloud& cloud, double sigma_fraction,
                                            uint64_t seed);

// `points` of the cloud's points chosen uniformly without replacement (every subset of that
// size equally likely), in their input order (selection sampling, Knuth's algorithm S). A
// cloud with at most `points` points is returned whole.
PointCloud RandomSubsample(const PointCloud& cloud, size_t points, uint64_t seed);

struct PartialViewOptions {
  // The vertical. The view direction (from the object towards the camera) is drawn uniformly
  // over the area of the band of the unit sphere whose component along `up` lies in
  // [min_up, max_up]: the component uniform in that range (Archimedes), the azimuth uniform.
  // The defaults, [-1, 1], draw uniformly over the whole sphere; e.g. [sin 10deg, sin 60deg]
  // is a camera looking down at a table from 10 to 60 degrees of elevation.
  Eigen::Vector3d up = Eigen::Vector3d::UnitZ();
  double min_up = -1.0;
  double max_up = 1.0;
  // Camera distance from the bounding box's center, in half box diagonals, > 1: as
  // ScanOptions::distance (nearer sees less of a round object).
  double distance = 3.0;
};

// A unit view direction drawn as PartialViewOptions says. InvalidArgument for a zero or
// non-finite `up` or a band outside -1 <= min_up <= max_up <= 1.
absl::StatusOr<Eigen::Vector3d> RandomViewDirection(const PartialViewOptions& options,
                                                    uint64_t seed);

// The points of the cloud that one depth camera sees from RandomViewDirection(options, seed),
// by ScanSimulator (scan_simulator.h; the cloud is taken as a sampling of the object's
// surface) without depth noise, in a square 45-degree image whose pixels are a third of the
// sample spacing wide at the object's center (64 to 2,048 pixels a side), so that
// visibility, not the camera's resolution, decides what is kept. The result is a
// non-empty subset of the input points, exact, in input order (duplicate points: at most the
// first copy). Errors (InvalidArgument): the options, as RandomViewDirection and
// distance not in (1, 1e6]; the cloud as ScanSimulator::Create (fewer than 3 points,
// non-finite or all identical).
absl::StatusOr<PointCloud> PartialView(const PointCloud& cloud, const PartialViewOptions& options,
                                       uint64_t seed);

// The points on the camera's side of a plane, a crude partial view that owes nothing to
// visibility (a table's edge, a depth cut-off, the near half of a wall of points): the plane's
// normal d is drawn as RandomViewDirection(options, seed) and its offset uniformly in
// [-max_offset, max_offset] half box diagonals from the centroid c; the points p with
// (p - c) . d >= offset are kept, in input order. When that keeps fewer than a tenth of the
// points (a thin object cut far out) the plane goes through the centroid instead, which keeps
// at least one point. Errors (InvalidArgument): as RandomViewDirection; max_offset not in
// [0, 1]; an empty cloud.
absl::StatusOr<PointCloud> PlaneCutView(const PointCloud& cloud, const PartialViewOptions& options,
                                        double max_offset, uint64_t seed);

// PartialView, then an occluder between the camera and the object (a pole, another object's
// edge): the visible points whose position across the line of sight, along a random direction
// perpendicular to it, falls in a band as wide as 10 to 30 % of the view's extent, placed
// uniformly within the view, are removed. The occlusion is skipped when it would leave fewer
// than a third of the visible points. The errors of PartialView.
absl::StatusOr<PointCloud> OccludedView(const PointCloud& cloud, const PartialViewOptions& options,
                                        uint64_t seed);

// How a SensorView decides what the sensor sees.
enum class Visibility {
  kCamera,          // PartialView: a depth camera's visible surface
  kPlaneCut,        // PlaneCutView with max_offset 0.3
  kOccludedCamera,  // OccludedView
};

// What one depth sensor on a robot sees of an object (the robot protocol of docs/accuracy.md,
// and the views of training-time augmentation): the side facing one random viewpoint, with noise,
// as sparse as a distant object, in any pose.
struct SensorViewOptions {
  // Where the camera may be (PartialView).
  PartialViewOptions view;
  // Which points the sensor sees from there.
  Visibility visibility = Visibility::kCamera;
  // Gaussian noise, sigma as a fraction of the WHOLE object's extent (CloudExtent of the
  // input, not of the visible part): 0.01 is 1 % of the object's size.
  double noise_fraction = 0.01;
  // The view keeps a number of points drawn uniformly in [min_points, max_points] (all of
  // them when it has fewer).
  size_t min_points = 300;
  size_t max_points = 500;
  // Turn the result by a uniformly random 3D rotation about its centroid: the object lies
  // in any pose. Off for gravity-aligned data or a frame-invariant descriptor that gains
  // nothing from it.
  bool random_pose = true;
};

// The visibility model (PartialView, PlaneCutView or OccludedView), then AddGaussianNoise, then
// RandomSubsample, then (random_pose) RandomRotation, each with its own seed drawn from `seed`.
// InvalidArgument for options out of range (noise_fraction finite and >= 0, 1 <= min_points <=
// max_points) and the errors of PartialView.
absl::StatusOr<PointCloud> SensorView(const PointCloud& cloud, const SensorViewOptions& options,
                                      uint64_t seed);

// A perturbation by name, for command lines and configuration:
//   clean (or none)  the cloud unchanged
//   yaw              RandomYaw about view.up
//   rot3d            RandomRotation
//   noise<P>         AddGaussianNoise, sigma P % of the extent, 0 < P <= 100 (noise1, noise0.5)
//   sub<N>           RandomSubsample to N >= 1 points (sub256)
//   partial          PartialView with `view`
//   robot            SensorView with `sensor` (defaults: one viewpoint, 1 % noise, 300-500
//                    points, random pose)
struct Perturbation {
  enum class Kind { kNone, kYaw, kRotation, kNoise, kSubsample, kPartialView, kSensorView };
  Kind kind = Kind::kNone;
  double noise_fraction = 0.0;  // kNoise: sigma / extent (noise1: 0.01)
  size_t points = 0;            // kSubsample
  // kYaw turns about view.up; kPartialView uses all of `view`.
  PartialViewOptions view;
  // kSensorView.
  SensorViewOptions sensor;
  std::string name;  // canonical: "clean", "yaw", "rot3d", "noise1", "sub256", "partial", "robot"
};

// InvalidArgument for an unknown name, listing the forms above.
absl::StatusOr<Perturbation> ParsePerturbation(absl::string_view name);

// Applies `perturbation` with `seed`; the errors of the function it calls.
absl::StatusOr<PointCloud> ApplyPerturbation(const PointCloud& cloud,
                                             const Perturbation& perturbation, uint64_t seed);

}  // namespace shapeid

#endif  // SHAPEID_CORE_VIEWS_PERTURB_H_
