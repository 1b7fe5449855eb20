#include "core/views/scan_simulator.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <utility>
#include <vector>

#include "Eigen/Geometry"
#include "absl/strings/str_cat.h"
#include "core/random.h"
#include "core/views/sample_spacing.h"

namespace shapeid {
namespace {

// How visibility works. Lengths are in sample spacings (sample_spacing.h); a length in the
// image is measured at the range of the point it belongs to.
//
// Each point is drawn into a depth buffer as a cone: over the buffer cells whose centers lie
// within kSplatSpacings of it in x and in y, its range (distance from the camera) plus kSlope
// times the distance from it. A point is hidden when, at the center of any of the 3 x 3
// cells around it, the buffer holds less than its mirror cone: its range minus kSlope times
// its distance to that center. Each pixel then shows its nearest visible point.
//
// Why cones: two points of one surface tilted by t from their rays differ in range by at most
// tan(t) times their distance, so by the triangle inequality no point of a surface with
// tan(t) <= kSlope hides another of it: surfaces keep all their points up to atan(4) = 76
// degrees, and lose some beyond, as real sensors do. (Flat splats with a depth tolerance must
// trade grazing surfaces against hidden ones: a tolerance that keeps 76 degrees lets through
// anything less than 8 spacings behind.) A point `gap` behind a nearer surface is hidden
// when that surface has a sample within about gap / kSlope of it, less its distance to a cell
// center, so only the back of a thin wall, or a surface just behind an occluding edge, shows
// through, for a few spacings.
//
// Why that splat size: a sampling as uniform and random as the mesh readers' leaves the
// square of half-width 2 (area 16) around a spot of a front surface empty with probability
// exp(-16) = 1e-7, and only through such a hole can a far hidden point show. The price is
// that the visible surface just behind an occluding edge loses a band up to 2 wide.
//
// Cells are kCellSpacings wide at the object's center, whatever the pixels: small enough that
// the 3 x 3 test comes close to the distance to the nearest hider, large enough that a cone
// covers few cells (4 to 9).

constexpr double kSplatSpacings = 2.0;
constexpr double kSlope = 4.0;
constexpr double kCellSpacings = 2.0;
constexpr double kPi = 3.14159265358979323846;
constexpr int kMaxImageSide = 4096;
constexpr double kMaxDistance = 1e6;
constexpr double kMaxCells = 1 << 24;
constexpr uint32_t kNoPoint = std::numeric_limits<uint32_t>::max();

// Euclidean length of (dx, dy), dx, dy >= 0, from above, within 8.3 %: max + (sqrt 2 - 1) min.
// An upper bound keeps the cone test's guarantee, without a square root.
float Distance(float dx, float dy) { return std::max(dx, dy) + 0.41421356f * std::min(dx, dy); }

bool AllFinite(const Eigen::Vector3d& v) { return v.allFinite(); }

absl::Status ValidateScanOptions(const ScanOptions& o) {
  if (!AllFinite(o.direction) || o.direction.squaredNorm() == 0) {
    return absl::InvalidArgumentError(absl::StrCat("scan direction (", o.direction.x(), ", ",
                                                   o.direction.y(), ", ", o.direction.z(),
                                                   ") must be finite and non-zero"));
  }
  if (!AllFinite(o.up) || o.up.squaredNorm() == 0 ||
      o.up.normalized().cross(o.direction.normalized()).norm() < 1e-6) {
    return absl::InvalidArgumentError(
        absl::StrCat("scan up vector (", o.up.x(), ", ", o.up.y(), ", ", o.up.z(),
                     ") must be finite, non-zero and not parallel to the direction (",
                     o.direction.x(), ", ", o.direction.y(), ", ", o.direction.z(), ")"));
  }
  if (!(o.distance > 1 && o.distance <= kMaxDistance)) {
    return absl::InvalidArgumentError(absl::StrCat("scan distance ", o.distance,
                                                   " must be > 1 (object radii), outside the "
                                                   "object, and at most ",
                                                   kMaxDistance));
  }
  if (o.width < 1 || o.width > kMaxImageSide || o.height < 1 || o.height > kMaxImageSide) {
    return absl::InvalidArgumentError(absl::StrCat("scan image ", o.width, " x ", o.height,
                                                   " must be 1 to ", kMaxImageSide,
                                                   " pixels on each side"));
  }
  if (!(o.fov_degrees > 0 && o.fov_degrees < 170)) {
    return absl::InvalidArgumentError(
        absl::StrCat("scan field of view ", o.fov_degrees, " degrees must be in (0, 170)"));
  }
  if (!(o.depth_noise >= 0) || !std::isfinite(o.depth_noise)) {
    return absl::InvalidArgumentError(absl::StrCat("scan depth noise ", o.depth_noise,
                                                   " must be finite and >= 0 (object radii)"));
  }
  return absl::OkStatus();
}

// A pinhole camera: the point eye + x right + y down + z forward images at pixel coordinates
// (cx + focal x / z, cy + focal y / z); pixel (i, j) spans [i, i + 1) x [j, j + 1).
struct Camera {
  Eigen::Vector3d eye, right, down, forward;
  double focal, cx, cy;
};

// Looks from center + distance * radius * direction at the center of the box [lo, hi].
Camera MakeCamera(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi, const ScanOptions& o) {
  Camera cam;
  const Eigen::Vector3d center = 0.5 * (lo + hi);
  const Eigen::Vector3d dir = o.direction.normalized();
  cam.eye = center + o.distance * 0.5 * (hi - lo).norm() * dir;
  cam.forward = -dir;
  cam.right = cam.forward.cross(o.up).normalized();
  cam.down = cam.forward.cross(cam.right);
  cam.cx = 0.5 * o.width;
  cam.cy = 0.5 * o.height;
  cam.focal = 0.5 * o.height / std::tan(0.5 * o.fov_degrees * kPi / 180);
  // Keep the box in view. Its corners lie on the bounding sphere, which the camera is outside
  // of, so all are in front of it, and the box, being convex, images inside their images.
  for (int corner = 0; corner < 8; ++corner) {
    const Eigen::Vector3d p((corner & 1) ? hi.x() : lo.x(), (corner & 2) ? hi.y() : lo.y(),
                            (corner & 4) ? hi.z() : lo.z());
    const Eigen::Vector3d rel = p - cam.eye;
    const double z = rel.dot(cam.forward);
    cam.focal = std::min({cam.focal, cam.cx * z / std::abs(rel.dot(cam.right)),
                          cam.cy * z / std::abs(rel.dot(cam.down))});
  }
  return cam;
}

// Standard normal deviates from SplitMix64 uniforms (Box-Muller, both values used).
class Gaussian {
 public:
  explicit Gaussian(uint64_t seed) : rng_(seed) {}
  double Next() {
    if (has_spare_) {
      has_spare_ = false;
      return spare_;
    }
    const double r = std::sqrt(-2 * std::log(1 - rng_.Uniform()));  // 1 - U is in (0, 1]
    const double angle = 2 * kPi * rng_.Uniform();
    spare_ = r * std::sin(angle);
    has_spare_ = true;
    return r * std::cos(angle);
  }

 private:
  SplitMix64 rng_;
  bool has_spare_ = false;
  double spare_ = 0;
};

}  // namespace

namespace views_internal {

struct ScanBuffers {
  struct ProjectedPoint {
    float cu, cv;  // in cells
    float depth, slope;
    uint32_t pixel;
  };
  std::vector<ProjectedPoint> points;
  std::vector<float> cover;  // the cones' depth per cell
  std::vector<float> nearest_depth;
  std::vector<uint32_t> nearest;  // per pixel, then compacted to the visible points
};

namespace {

// The scan itself, for a valid surface with its bounding box [lo, hi] and sample spacing,
// and valid options.
PointCloud Render(const PointCloud& surface, const Eigen::Vector3d& lo, const Eigen::Vector3d& hi,
                  double spacing, const ScanOptions& options, ScanBuffers& buf,
                  std::vector<uint32_t>* surface_indices) {
  const double radius = 0.5 * (hi - lo).norm();
  const Camera cam = MakeCamera(lo, hi, options);
  const int width = options.width, height = options.height;
  // Cells kCellSpacings wide at the object's center, or larger if there would be more than
  // about 16 per point: only a degenerate surface (most points at one spot) asks for more.
  const double max_cells = std::min(kMaxCells, std::max(65536.0, 16.0 * surface.size()));
  const double pixel_size = options.distance * radius / cam.focal;  // at the center's depth
  const double cell_pixels = std::max(kCellSpacings * spacing / pixel_size,
                                      std::sqrt(static_cast<double>(width) * height / max_cells));
  const int cells_x = static_cast<int>(std::ceil(width / cell_pixels));
  const int cells_y = static_cast<int>(std::ceil(height / cell_pixels));
  const float cells_per_pixel = static_cast<float>(1 / cell_pixels);
  const double slope_per_depth = kSlope * cell_pixels / cam.focal;  // per cell of distance
  const double radius_depth = kSplatSpacings * spacing * cam.focal / cell_pixels;
  const float max_u = std::nextafter(static_cast<float>(width), 0.0f);
  const float max_v = std::nextafter(static_cast<float>(height), 0.0f);
  const float max_cu = std::nextafter(static_cast<float>(cells_x), 0.0f);
  const float max_cv = std::nextafter(static_cast<float>(cells_y), 0.0f);
  // Ranges are kept in floats relative to the nearest a point can be, for full precision
  // however far the camera.
  const double nearest_range = (options.distance - 1) * radius;

  // Pass 1 over the points: project, and splat the cones, each over the cells whose centers
  // lie within its radius in x and y (a square, so no branch per cell; at least half a
  // cell, so that it covers its own).
  constexpr float kFar = std::numeric_limits<float>::infinity();
  buf.cover.assign(static_cast<size_t>(cells_x) * cells_y, kFar);
  buf.points.resize(surface.size());
  const float* xyz = surface.data();
  for (size_t i = 0; i < surface.size(); ++i) {
    const Eigen::Vector3d rel =
        Eigen::Vector3d(xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2]) - cam.eye;
    const double z = rel.dot(cam.forward);  // > 0: the camera is outside the bounding sphere
    const double scale = cam.focal / z;
    // The object fits in the image; clamping only absorbs rounding at its border.
    const float u =
        std::clamp(static_cast<float>(cam.cx + scale * rel.dot(cam.right)), 0.0f, max_u);
    const float v = std::clamp(static_cast<float>(cam.cy + scale * rel.dot(cam.down)), 0.0f, max_v);
    const float cu = std::min(u * cells_per_pixel, max_cu);
    const float cv = std::min(v * cells_per_pixel, max_cv);
    // Range along the ray rather than depth along the view axis: a surface's tilt from its
    // ray bounds how fast the range changes across the image, anywhere in it.
    const double range = rel.norm();
    const float depth = static_cast<float>(range - nearest_range);
    const float slope = static_cast<float>(slope_per_depth * range);
    const float r = std::max(static_cast<float>(radius_depth / z), 0.5f);
    // Cells c whose center c + 0.5 may be within r (truncation is floor for values >= 0);
    // r >= 0.5 takes in the point's own cell.
    const int x0 = std::max(0, static_cast<int>(cu - r + 0.5f));
    const int x1 = std::min(cells_x - 1, static_cast<int>(cu + r - 0.5f));
    const int y0 = std::max(0, static_cast<int>(cv - r + 0.5f));
    const int y1 = std::min(cells_y - 1, static_cast<int>(cv + r - 0.5f));
    for (int y = y0; y <= y1; ++y) {
      const float dy = std::abs(static_cast<float>(y) + 0.5f - cv);
      float* row = buf.cover.data() + static_cast<size_t>(y) * cells_x;
      for (int x = x0; x <= x1; ++x) {
        const float dx = std::abs(static_cast<float>(x) + 0.5f - cu);
        row[x] = std::min(row[x], depth + slope * Distance(dx, dy));
      }
    }
    buf.points[i] = ScanBuffers::ProjectedPoint{
        cu, cv, depth, slope,
        static_cast<uint32_t>(static_cast<int>(v) * width + static_cast<int>(u))};
  }

  // Pass 2 over the points: the mirror-cone test at the centers of the 3 x 3 cells around
  // each (the triangle inequality holds at any center, and the more centers, the closer the
  // test comes to the distance between a hidden point and the nearest hider); then each
  // pixel keeps its nearest visible point (ties: the first).
  const size_t num_pixels = static_cast<size_t>(width) * static_cast<size_t>(height);
  buf.nearest_depth.assign(num_pixels, kFar);
  buf.nearest.assign(num_pixels, kNoPoint);
  for (size_t i = 0; i < surface.size(); ++i) {
    const ScanBuffers::ProjectedPoint& p = buf.points[i];
    if (!(p.depth < buf.nearest_depth[p.pixel])) continue;
    const int cx = static_cast<int>(p.cu), cy = static_cast<int>(p.cv);
    bool hidden = false;
    for (int y = std::max(0, cy - 1); y <= std::min(cells_y - 1, cy + 1); ++y) {
      const float dy = std::abs(static_cast<float>(y) + 0.5f - p.cv);
      const float* row = buf.cover.data() + static_cast<size_t>(y) * cells_x;
      for (int x = std::max(0, cx - 1); x <= std::min(cells_x - 1, cx + 1); ++x) {
        const float dx = std::abs(static_cast<float>(x) + 0.5f - p.cu);
        hidden |= p.depth - p.slope * Distance(dx, dy) > row[x];
      }
    }
    if (hidden) continue;
    buf.nearest_depth[p.pixel] = p.depth;
    buf.nearest[p.pixel] = static_cast<uint32_t>(i);
  }
  size_t visible = 0;  // compact the visible points' indices, in scan order
  for (size_t k = 0; k < num_pixels; ++k) {
    if (buf.nearest[k] != kNoPoint) buf.nearest[visible++] = buf.nearest[k];
  }

  // Noise for every visible point in scan order, then the subset (selection sampling, Knuth's
  // algorithm S, which keeps the order), each from its own stream of the seed.
  SplitMix64 streams(options.seed);
  Gaussian noise(streams.Next());
  SplitMix64 subset(streams.Next());
  const double sigma = options.depth_noise * radius;
  size_t wanted = options.max_points == 0 ? visible : std::min(options.max_points, visible);
  PointCloud scan;
  scan.Reserve(wanted);
  if (surface_indices != nullptr) {
    surface_indices->clear();
    surface_indices->reserve(wanted);
  }
  for (size_t j = 0; j < visible && wanted > 0; ++j) {
    const double offset = sigma > 0 ? sigma * noise.Next() : 0;
    const size_t remaining = visible - j;
    if (wanted < remaining &&
        !(subset.Uniform() * static_cast<double>(remaining) < static_cast<double>(wanted))) {
      continue;
    }
    --wanted;
    if (surface_indices != nullptr) surface_indices->push_back(buf.nearest[j]);
    const auto p = surface.point(buf.nearest[j]);
    if (offset == 0) {
      scan.Add(p);
    } else {
      const Eigen::Vector3d q = p.cast<double>();
      scan.Add((q + offset * (q - cam.eye).normalized()).cast<float>());
    }
  }
  return scan;
}

// ValidateCloud's error, said to be about the scan's surface.
absl::Status SurfaceError(const absl::Status& status) {
  return absl::Status(status.code(), absl::StrCat("scan surface: ", status.message()));
}

absl::Status CheckSize(const PointCloud& surface) {
  if (surface.size() >= kNoPoint) {
    return absl::InvalidArgumentError(absl::StrCat(
        "scan surface has ", surface.size(), " points; at most ", kNoPoint - 1, " are supported"));
  }
  return absl::OkStatus();
}

}  // namespace
}  // namespace views_internal

using views_internal::Render;

absl::StatusOr<ScanSimulator> ScanSimulator::Create(PointCloud surface) {
  const absl::StatusOr<CloudStats> stats = ValidateCloud(surface);
  if (!stats.ok()) return views_internal::SurfaceError(stats.status());
  if (absl::Status status = views_internal::CheckSize(surface); !status.ok()) return status;
  const double spacing = EstimateSampleSpacing(surface, *stats);
  return ScanSimulator(std::move(surface), *stats, spacing);
}

ScanSimulator::ScanSimulator(PointCloud surface, const CloudStats& stats, double spacing)
    : surface_(std::move(surface)),
      box_min_(stats.min),
      box_max_(stats.max),
      spacing_(spacing),
      buffers_(std::make_unique<views_internal::ScanBuffers>()) {}

ScanSimulator::ScanSimulator(ScanSimulator&&) = default;
ScanSimulator& ScanSimulator::operator=(ScanSimulator&&) = default;
ScanSimulator::~ScanSimulator() = default;

absl::StatusOr<PointCloud> ScanSimulator::Scan(const ScanOptions& options,
                                               std::vector<uint32_t>* surface_indices) {
  if (absl::Status status = ValidateScanOptions(options); !status.ok()) return status;
  return Render(surface_, box_min_, box_max_, spacing_, options, *buffers_, surface_indices);
}

absl::StatusOr<PointCloud> SimulateScan(const PointCloud& surface, const ScanOptions& options,
                                        std::vector<uint32_t>* surface_indices) {
  // As Create and Scan, without copying the surface.
  if (absl::Status status = ValidateScanOptions(options); !status.ok()) return status;
  const absl::StatusOr<CloudStats> stats = ValidateCloud(surface);
  if (!stats.ok()) return views_internal::SurfaceError(stats.status());
  if (absl::Status status = views_internal::CheckSize(surface); !status.ok()) return status;
  views_internal::ScanBuffers buffers;
  return Render(surface, stats->min, stats->max, EstimateSampleSpacing(surface, *stats), options,
                buffers, surface_indices);
}

}  // namespace shapeid
