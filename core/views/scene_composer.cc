#include "core/views/scene_composer.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <unordered_map>
#include <utility>
#include <vector>

#include "absl/strings/str_cat.h"
#include "core/random.h"
#include "core/views/sample_spacing.h"
#include "core/views/scan_simulator.h"

namespace shapeid {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr int kAttempts = 100;
constexpr double kContactTolerance = 0.02;  // of max_contact_gap: where sliding stops
constexpr double kMaxTableSamples = 20e6;

absl::Status ValidateOptions(const SceneComposerOptions& o) {
  const auto positive = [](double v) { return std::isfinite(v) && v > 0; };
  if (!positive(o.table_width) || !positive(o.table_depth)) {
    return absl::InvalidArgumentError(absl::StrCat("table ", o.table_width, " x ", o.table_depth,
                                                   " m must be finite and positive"));
  }
  if (!positive(o.min_size) || !(o.max_size >= o.min_size) || !std::isfinite(o.max_size)) {
    return absl::InvalidArgumentError(absl::StrCat("object sizes [", o.min_size, ", ", o.max_size,
                                                   "] m must satisfy 0 < min <= max"));
  }
  if (!(o.edge_margin >= 0) || !std::isfinite(o.edge_margin)) {
    return absl::InvalidArgumentError(absl::StrCat("edge margin ", o.edge_margin, " must be >= 0"));
  }
  if (!(o.touch_probability >= 0 && o.touch_probability <= 1)) {
    return absl::InvalidArgumentError(
        absl::StrCat("touch probability ", o.touch_probability, " must be in [0, 1]"));
  }
  if (!positive(o.min_gap) || !positive(o.max_contact_gap) || !(o.max_contact_gap < o.min_gap)) {
    return absl::InvalidArgumentError(absl::StrCat(
        "gaps: need 0 < max_contact_gap (", o.max_contact_gap, ") < min_gap (", o.min_gap, ")"));
  }
  if (!(o.table_spacing >= 0) || !std::isfinite(o.table_spacing)) {
    return absl::InvalidArgumentError(
        absl::StrCat("table spacing ", o.table_spacing, " must be >= 0 (0: the objects')"));
  }
  if (!(o.min_elevation_degrees > 0 && o.min_elevation_degrees <= o.max_elevation_degrees &&
        o.max_elevation_degrees < 90)) {
    return absl::InvalidArgumentError(absl::StrCat("camera elevation [", o.min_elevation_degrees,
                                                   ", ", o.max_elevation_degrees,
                                                   "] degrees must satisfy 0 < min <= max < 90"));
  }
  if (!(o.depth_noise >= 0) || !std::isfinite(o.depth_noise)) {
    return absl::InvalidArgumentError(
        absl::StrCat("depth noise ", o.depth_noise, " m must be finite and >= 0"));
  }
  return absl::OkStatus();  // distance, image and lens: ScanOptions' checks, at the scan
}

// A model upright (its up along +z), centered in x and y, its lowest point at z = 0, and
// scaled so that its largest extent is 1.
struct UprightModel {
  std::vector<Eigen::Vector3d> points;
  Eigen::Matrix3d rotation;  // the model's coordinates into the upright ones, before scaling
  Eigen::Vector3d offset;    // then this is added, then the scale applied
  double unit_scale = 1;
  double spacing = 0;  // at unit size
};

absl::StatusOr<UprightModel> MakeUpright(const SceneObjectModel& model, size_t index) {
  const absl::StatusOr<CloudStats> stats = ValidateCloud(model.surface);
  if (!stats.ok()) {
    return absl::InvalidArgumentError(
        absl::StrCat("scene model ", index, " (", model.label, "): ", stats.status().message()));
  }
  if (!model.up.allFinite() || model.up.squaredNorm() == 0) {
    return absl::InvalidArgumentError(absl::StrCat("scene model ", index, " (", model.label,
                                                   "): up must be finite and non-zero"));
  }
  UprightModel upright;
  upright.rotation =
      Eigen::Quaterniond::FromTwoVectors(model.up.normalized(), Eigen::Vector3d::UnitZ())
          .toRotationMatrix();
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
  Eigen::Vector3d hi = -lo;
  upright.points.reserve(model.surface.size());
  for (size_t i = 0; i < model.surface.size(); ++i) {
    upright.points.push_back(upright.rotation * model.surface.point(i).cast<double>());
    lo = lo.cwiseMin(upright.points.back());
    hi = hi.cwiseMax(upright.points.back());
  }
  upright.unit_scale = 1 / (hi - lo).maxCoeff();
  upright.offset = -Eigen::Vector3d(0.5 * (lo.x() + hi.x()), 0.5 * (lo.y() + hi.y()), lo.z());
  for (Eigen::Vector3d& p : upright.points) p = (p + upright.offset) * upright.unit_scale;
  // The spacing scales with the model; the rotation does not change it.
  upright.spacing = EstimateSampleSpacing(model.surface, *stats) * upright.unit_scale;
  return upright;
}

// Footprints: the xy projections of an object's points, bucketed in square cells of side
// `cell`, so that the distance to another footprint is found up to `cell`.
class Footprint {
 public:
  Footprint(std::vector<Eigen::Vector2d> points, double cell)
      : points_(std::move(points)), cell_(cell) {
    lo_ = hi_ = points_.front();
    for (uint32_t i = 0; i < points_.size(); ++i) {
      cells_[Key(points_[i])].push_back(i);
      lo_ = lo_.cwiseMin(points_[i]);
      hi_ = hi_.cwiseMax(points_[i]);
    }
  }

  // The least distance from any of `query`'s points (with box [lo, hi]) to this
  // footprint's, or `cell` when it is at least that; the search stops at the first distance
  // below `stop` and returns it (a yes-or-no question answered early).
  double Gap(const std::vector<Eigen::Vector2d>& query, const Eigen::Vector2d& lo,
             const Eigen::Vector2d& hi, double stop = 0) const {
    if ((lo.array() - cell_ > hi_.array()).any() || (hi.array() + cell_ < lo_.array()).any()) {
      return cell_;
    }
    double best = cell_ * cell_;
    const double stop2 = stop * stop;
    for (const Eigen::Vector2d& q : query) {
      const int64_t cx = Cell(q.x()), cy = Cell(q.y());
      for (int64_t y = cy - 1; y <= cy + 1; ++y) {
        for (int64_t x = cx - 1; x <= cx + 1; ++x) {
          const auto found = cells_.find(Key(x, y));
          if (found == cells_.end()) continue;
          for (const uint32_t i : found->second) {
            best = std::min(best, (points_[i] - q).squaredNorm());
          }
        }
      }
      if (best < stop2) break;
    }
    return std::sqrt(best);
  }

 private:
  int64_t Cell(double v) const { return static_cast<int64_t>(std::floor(v / cell_)); }
  // Unsigned: cells left of or below the origin are negative, and shifting those is undefined.
  static int64_t Key(int64_t x, int64_t y) {
    return static_cast<int64_t>(static_cast<uint64_t>(x) << 32 ^
                                (static_cast<uint64_t>(y) & 0xffffffffu));
  }
  int64_t Key(const Eigen::Vector2d& p) const { return Key(Cell(p.x()), Cell(p.y())); }

  std::vector<Eigen::Vector2d> points_;
  double cell_;
  Eigen::Vector2d lo_, hi_;
  std::unordered_map<int64_t, std::vector<uint32_t>> cells_;
};

// One placement being tried: the model's points turned and scaled, about the origin in xy.
struct Candidate {
  double scale = 1;
  Eigen::Matrix3d yaw = Eigen::Matrix3d::Identity();
  std::vector<Eigen::Vector2d> local;  // footprint about the origin
  Eigen::Vector2d lo, hi;              // its box
  std::vector<Eigen::Vector2d> at;     // footprint at the current center
  Eigen::Vector2d center = Eigen::Vector2d::Zero();

  void MoveTo(const Eigen::Vector2d& c) {
    center = c;
    at.resize(local.size());
    for (size_t i = 0; i < local.size(); ++i) at[i] = local[i] + c;
  }
  double Gap(const Footprint& other, double stop = 0) const {
    return other.Gap(at, lo + center, hi + center, stop);
  }
};

struct Placed {
  Footprint footprint;
  Eigen::Vector2d center;
  double reach;  // largest distance of a footprint point from the center
};

}  // namespace

absl::StatusOr<ComposedScene> ComposeScene(absl::Span<const SceneObjectModel> models,
                                           const SceneComposerOptions& options) {
  if (absl::Status status = ValidateOptions(options); !status.ok()) return status;
  if (models.empty() || models.size() > 65534) {
    return absl::InvalidArgumentError(
        absl::StrCat("a scene takes 1 to 65534 models, not ", models.size()));
  }
  std::vector<UprightModel> upright;
  for (size_t m = 0; m < models.size(); ++m) {
    absl::StatusOr<UprightModel> u = MakeUpright(models[m], m);
    if (!u.ok()) return u.status();
    upright.push_back(std::move(*u));
  }

  SplitMix64 streams(options.seed);
  SplitMix64 placement(streams.Next()), table_draws(streams.Next()), camera(streams.Next());
  const auto uniform = [](SplitMix64& rng, double lo, double hi) {
    return lo + (hi - lo) * rng.Uniform();
  };
  const Eigen::Vector2d room(0.5 * options.table_width - options.edge_margin,
                             0.5 * options.table_depth - options.edge_margin);

  ComposedScene scene;
  std::vector<Placed> placed;
  std::vector<std::vector<Eigen::Vector3d>> object_points;
  double sparsest = 0;
  for (size_t m = 0; m < models.size(); ++m) {
    for (int attempt = 0; attempt < kAttempts; ++attempt) {
      Candidate c;
      c.scale = uniform(placement, options.min_size, options.max_size);
      const double yaw = uniform(placement, 0, 2 * kPi);
      c.yaw = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
      c.lo = Eigen::Vector2d::Constant(std::numeric_limits<double>::infinity());
      c.hi = -c.lo;
      c.local.reserve(upright[m].points.size());
      double reach = 0;
      for (const Eigen::Vector3d& p : upright[m].points) {
        c.local.push_back((c.yaw * (c.scale * p)).head<2>());
        c.lo = c.lo.cwiseMin(c.local.back());
        c.hi = c.hi.cwiseMax(c.local.back());
        reach = std::max(reach, c.local.back().norm());
      }
      const Eigen::Vector2d low = -room - c.lo, high = room - c.hi;  // where the center may be
      if ((low.array() > high.array()).any()) continue;
      const bool touch = !placed.empty() && placement.Uniform() < options.touch_probability;
      if (touch) {
        // Slide in from afar along a random direction towards an earlier object until the
        // footprints are `gap` apart: each step is the gap less the target, which cannot
        // overshoot, as no point moves farther than the center.
        const size_t a =
            std::min(placed.size() - 1,
                     static_cast<size_t>(placement.Uniform() * static_cast<double>(placed.size())));
        const double angle = uniform(placement, 0, 2 * kPi);
        const Eigen::Vector2d dir(std::cos(angle), std::sin(angle));
        const double gap = uniform(placement, 0.3, 0.9) * options.max_contact_gap;
        double t = placed[a].reach + reach + options.min_gap;
        bool touched = false;
        for (int step = 0; step < 200 && t >= 0 && !touched; ++step) {
          c.MoveTo(placed[a].center + t * dir);
          const double now = c.Gap(placed[a].footprint);
          touched = now < gap + kContactTolerance * options.max_contact_gap;
          t -= now - gap;
        }
        if (!touched) continue;
      } else {
        c.MoveTo({uniform(placement, low.x(), high.x()), uniform(placement, low.y(), high.y())});
      }
      if ((c.center.array() < low.array()).any() || (c.center.array() > high.array()).any()) {
        continue;
      }
      // Separated objects keep min_gap from all; a leaning one overlaps none.
      const double needed = touch ? 0.3 * options.max_contact_gap : options.min_gap;
      bool fits = true;
      for (const Placed& p : placed) fits = fits && c.Gap(p.footprint, needed) >= needed;
      if (!fits) continue;

      ComposedObject object;
      object.model = m;
      object.label = models[m].label;
      object.role = models[m].role;
      object.scale = c.scale * upright[m].unit_scale;
      object.rotation = c.yaw * upright[m].rotation;
      const Eigen::Vector3d center3(c.center.x(), c.center.y(), 0);
      object.translation = c.yaw * (c.scale * upright[m].unit_scale * upright[m].offset) + center3;
      std::vector<Eigen::Vector3d> points;
      points.reserve(upright[m].points.size());
      Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
      Eigen::Vector3d hi = -lo;
      for (const Eigen::Vector3d& p : upright[m].points) {
        points.push_back(c.yaw * (c.scale * p) + center3);
        lo = lo.cwiseMin(points.back());
        hi = hi.cwiseMax(points.back());
      }
      object.size = hi - lo;
      sparsest = std::max(sparsest, c.scale * upright[m].spacing);
      placed.push_back(Placed{Footprint(c.at, options.min_gap), c.center, reach});
      object_points.push_back(std::move(points));
      scene.objects.push_back(std::move(object));
      break;
    }
  }
  for (size_t i = 0; i < placed.size(); ++i) {
    std::vector<Eigen::Vector2d> footprint;
    for (const Eigen::Vector3d& p : object_points[i]) footprint.push_back(p.head<2>());
    Eigen::Vector2d lo = footprint.front(), hi = footprint.front();
    for (const Eigen::Vector2d& p : footprint) lo = lo.cwiseMin(p), hi = hi.cwiseMax(p);
    for (size_t j = 0; j < placed.size(); ++j) {
      if (j != i && placed[j].footprint.Gap(footprint, lo, hi, options.min_gap) < options.min_gap) {
        scene.objects[i].separated = false;
      }
    }
  }

  // The table, uniformly sampled at the sparsest object's spacing, then the objects.
  scene.table_spacing = options.table_spacing > 0 ? options.table_spacing : sparsest;
  if (scene.table_spacing == 0) scene.table_spacing = 0.01;  // no object placed
  const double table_samples =
      std::ceil(options.table_width * options.table_depth / std::pow(scene.table_spacing, 2));
  if (table_samples > kMaxTableSamples) {
    return absl::InvalidArgumentError(absl::StrCat("a table sampled every ", scene.table_spacing,
                                                   " m needs ", table_samples, " points; at most ",
                                                   kMaxTableSamples));
  }
  PointCloud surface;
  std::vector<uint32_t> first_index;  // of each object in the surface; table from 0
  for (double i = 0; i < table_samples; ++i) {
    surface.Add(static_cast<float>(uniform(table_draws, -0.5, 0.5) * options.table_width),
                static_cast<float>(uniform(table_draws, -0.5, 0.5) * options.table_depth), 0.0f);
  }
  for (const std::vector<Eigen::Vector3d>& points : object_points) {
    first_index.push_back(static_cast<uint32_t>(surface.size()));
    for (const Eigen::Vector3d& p : points) surface.Add(p.cast<float>());
  }

  const absl::StatusOr<CloudStats> stats = ValidateCloud(surface);
  if (!stats.ok()) return stats.status();
  const double radius = 0.5 * (stats->max - stats->min).norm();
  const double elevation =
      uniform(camera, options.min_elevation_degrees, options.max_elevation_degrees) * kPi / 180;
  const double azimuth = uniform(camera, 0, 2 * kPi);
  ScanOptions scan;
  scan.direction = {std::cos(azimuth) * std::cos(elevation),
                    std::sin(azimuth) * std::cos(elevation), std::sin(elevation)};
  scan.up = Eigen::Vector3d::UnitZ();
  scan.distance = options.distance;
  scan.width = options.width;
  scan.height = options.height;
  scan.fov_degrees = options.fov_degrees;
  scan.depth_noise = options.depth_noise / radius;
  scan.seed = camera.Next();
  std::vector<uint32_t> indices;
  absl::StatusOr<PointCloud> seen = SimulateScan(surface, scan, &indices);
  if (!seen.ok()) return seen.status();

  // The camera as the simulator places it: at the box center + distance radii along the
  // direction, looking back, the image's up along +z.
  const Eigen::Vector3d dir = scan.direction.normalized();
  const Eigen::Vector3d eye = 0.5 * (stats->min + stats->max) + scan.distance * radius * dir;
  Eigen::Matrix3d axes;
  axes.col(2) = -dir;
  axes.col(0) = axes.col(2).cross(scan.up).normalized();
  axes.col(1) = axes.col(2).cross(axes.col(0));
  scene.camera_to_table.linear() = axes;
  scene.camera_to_table.translation() = eye;
  const Eigen::Isometry3d table_to_camera = scene.camera_to_table.inverse();
  scene.frame.Reserve(seen->size());
  scene.truth.reserve(seen->size());
  for (size_t i = 0; i < seen->size(); ++i) {
    scene.frame.Add((table_to_camera * seen->point(i).cast<double>()).cast<float>());
    const size_t object = static_cast<size_t>(
        std::upper_bound(first_index.begin(), first_index.end(), indices[i]) - first_index.begin());
    scene.truth.push_back(static_cast<uint16_t>(object));
    if (object > 0) ++scene.objects[object - 1].points;
  }
  return scene;
}

}  // namespace shapeid
