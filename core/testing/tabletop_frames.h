#ifndef SHAPEID_CORE_TESTING_TABLETOP_FRAMES_H_
#define SHAPEID_CORE_TESTING_TABLETOP_FRAMES_H_

// Synthetic depth-camera frames of objects on a table, with the truth of every point, for
// tests and benchmarks of scene segmentation. Each pixel's ray is intersected analytically
// with a table top, a floor and the objects (spheres, boxes, upright cylinders): nothing is
// sampled from surfaces, so what is visible follows from the geometry alone, independently
// of core/views' simulator. Seeded with SplitMix64: the same options give the same frame.
// The defaults give about 295,000 finite points of 640 x 480: a table top (no thickness, no
// legs) over half the view, the floor behind and beside it, NaN beyond max_depth.

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <utility>
#include <vector>

#include "Eigen/Core"
#include "core/point_cloud.h"
#include "core/random.h"

namespace shapeid::testing_frames {

// Truth ids of points that are not an object's (objects are 0, 1, ...).
inline constexpr int32_t kTable = -1;
inline constexpr int32_t kNothing = -2;  // the ray hit nothing within range: NaN point
inline constexpr int32_t kFloor = -3;

enum class ObjectKind { kSphere, kBox, kCylinder };

// In the table's frame: origin the table top's center, x along its width (the camera's
// right), y along its depth (away from the camera), z up. Every object stands on the table
// and fills [center - size / 2, center + size / 2] in x and y and [0, size.z] in z: a box
// exactly (sides along the table's edges), an upright cylinder of diameter size.x, a sphere
// of diameter size.x resting on the table.
struct TabletopObject {
  ObjectKind kind = ObjectKind::kBox;
  Eigen::Vector2f center = Eigen::Vector2f::Zero();
  Eigen::Vector3f size = Eigen::Vector3f::Zero();
  size_t points = 0;  // how many of the frame's points are this object's
};

struct TabletopFrameOptions {
  // A pinhole camera with square pixels, ROS optical frame: x right, y down, z forward.
  int width = 640;
  int height = 480;
  double vertical_fov_degrees = 58;
  double pitch_degrees = 45;  // the optical axis below the horizontal
  // The table top: the optical axis meets its center this far from the camera.
  double table_distance = 0.9;
  double table_width = 1.2;  // across the view
  double table_depth = 0.8;  // away from the camera
  // The floor, this far below the table top; <= 0: no floor.
  double floor_drop = 0.75;
  // Rays that hit nothing closer than this depth (z) give NaN, as a depth camera's do.
  double max_depth = 4.0;
  int objects = 5;
  double min_size = 0.04;  // each extent (diameter, height, box side) in [min, max]
  double max_size = 0.20;
  double edge_margin = 0.02;  // footprints stay this far inside the table's edges
  // Separated: every two objects at least min_gap apart (3-D distance between solids).
  // Touching: each object after the first leans on an earlier one, at most max_contact_gap
  // from it, and overlaps none.
  bool touching = false;
  double min_gap = 0.03;
  double max_contact_gap = 0.005;
  // Gaussian depth noise along the ray: sigma = depth_noise * depth^2 (depth z in metres).
  double depth_noise = 0.001;
  // Drop the NaN points (an unorganized frame) instead of keeping one point per pixel.
  bool drop_missing = false;
  uint64_t seed = 1;
};

struct TabletopFrame {
  PointCloud cloud;            // camera frame; organized row by row unless drop_missing
  std::vector<int32_t> truth;  // per point: an object's index, or kTable, kNothing, kFloor
  // Fewer than options.objects when some could not be placed (a crowded table).
  std::vector<TabletopObject> objects;
  size_t width = 0, height = 0;  // width x height == cloud.size()
  // a x + b y + c z + d = 0, (a, b, c) a unit normal, d > 0 (the camera on the positive side).
  Eigen::Vector4f table_plane = Eigen::Vector4f::Zero();
  Eigen::Vector4f floor_plane = Eigen::Vector4f::Zero();  // zero without a floor
  // The table's frame in the camera's: columns x, y, z of the table frame, and its origin.
  Eigen::Matrix3d table_axes = Eigen::Matrix3d::Identity();
  Eigen::Vector3d table_origin = Eigen::Vector3d::Zero();
  size_t count(int32_t id) const {
    return static_cast<size_t>(std::count(truth.begin(), truth.end(), id));
  }
};

namespace internal {

// Signed distance from p to the box |p| <= half (negative inside); 2-D or 3-D.
template <int N>
double BoxSdf(const Eigen::Matrix<double, N, 1>& p, const Eigen::Matrix<double, N, 1>& half) {
  const Eigen::Matrix<double, N, 1> q = p.cwiseAbs() - half;
  return q.cwiseMax(0.0).norm() + std::min(q.maxCoeff(), 0.0);
}

// Signed distance from p (relative to the footprint center) to the solid of `o`.
inline double ObjectSdf(const TabletopObject& o, const Eigen::Vector3d& p) {
  const Eigen::Vector3d s = o.size.cast<double>();
  switch (o.kind) {
    case ObjectKind::kSphere:
      return (p - Eigen::Vector3d(0, 0, s.x() / 2)).norm() - s.x() / 2;
    case ObjectKind::kBox:
      return BoxSdf<3>(p - Eigen::Vector3d(0, 0, s.z() / 2), s / 2);
    case ObjectKind::kCylinder:
      return BoxSdf<2>(Eigen::Vector2d(p.head<2>().norm(), p.z() - s.z() / 2),
                       Eigen::Vector2d(s.x() / 2, s.z() / 2));
  }
  return 0;
}

// Signed 3-D distance between the solids of a and b (negative: they overlap). Exact for every
// pair: both stand on z = 0, so two upright prisms are as far apart as their footprints, and
// a sphere is its center's distance to the other solid less its radius.
inline double SolidDistance(const TabletopObject& a, const TabletopObject& b) {
  if (b.kind == ObjectKind::kSphere) {
    const Eigen::Vector2d c = (b.center - a.center).cast<double>();
    return ObjectSdf(a, Eigen::Vector3d(c.x(), c.y(), b.size.x() / 2.0)) - b.size.x() / 2.0;
  }
  if (a.kind == ObjectKind::kSphere) return SolidDistance(b, a);
  const Eigen::Vector2d c = (b.center - a.center).cast<double>();
  const Eigen::Vector2d ha = a.size.head<2>().cast<double>() / 2;
  const Eigen::Vector2d hb = b.size.head<2>().cast<double>() / 2;
  const bool round_a = a.kind == ObjectKind::kCylinder, round_b = b.kind == ObjectKind::kCylinder;
  if (round_a && round_b) return c.norm() - ha.x() - hb.x();
  if (round_a) return BoxSdf<2>(c, hb) - ha.x();
  if (round_b) return BoxSdf<2>(c, ha) - hb.x();
  return BoxSdf<2>(c, ha + hb);  // the Minkowski sum of two aligned rectangles
}

// The smallest t > 0 at which the ray o + t d enters `o`'s solid (table frame), or infinity.
inline double RayHit(const TabletopObject& obj, const Eigen::Vector3d& origin,
                     const Eigen::Vector3d& d) {
  constexpr double kMiss = std::numeric_limits<double>::infinity();
  const Eigen::Vector3d s = obj.size.cast<double>();
  const Eigen::Vector3d o = origin - Eigen::Vector3d(obj.center.x(), obj.center.y(), 0);
  if (obj.kind == ObjectKind::kSphere) {
    const Eigen::Vector3d m = o - Eigen::Vector3d(0, 0, s.x() / 2);
    const double b = m.dot(d), c = m.squaredNorm() - s.x() * s.x() / 4;
    const double disc = b * b - d.squaredNorm() * c;
    if (disc < 0) return kMiss;
    const double t = (-b - std::sqrt(disc)) / d.squaredNorm();
    return t > 0 ? t : kMiss;
  }
  if (obj.kind == ObjectKind::kBox) {
    const Eigen::Vector3d low(-s.x() / 2, -s.y() / 2, 0), high(s.x() / 2, s.y() / 2, s.z());
    double enter = 0, leave = kMiss;
    for (int k = 0; k < 3; ++k) {
      if (d[k] == 0) {
        if (o[k] < low[k] || o[k] > high[k]) return kMiss;
        continue;
      }
      double t0 = (low[k] - o[k]) / d[k], t1 = (high[k] - o[k]) / d[k];
      if (t0 > t1) std::swap(t0, t1);
      enter = std::max(enter, t0);
      leave = std::min(leave, t1);
    }
    return enter > 0 && enter <= leave ? enter : kMiss;
  }
  // Upright cylinder: the side, then the top cap (the bottom rests on the table).
  double best = kMiss;
  const double r = s.x() / 2;
  const double a = d.x() * d.x() + d.y() * d.y();
  if (a > 0) {
    const double b = o.x() * d.x() + o.y() * d.y();
    const double c = o.x() * o.x() + o.y() * o.y() - r * r;
    const double disc = b * b - a * c;
    if (disc >= 0) {
      const double t = (-b - std::sqrt(disc)) / a;
      const double z = o.z() + t * d.z();
      if (t > 0 && z >= 0 && z <= s.z()) best = t;
    }
  }
  if (d.z() != 0) {
    const double t = (s.z() - o.z()) / d.z();
    const Eigen::Vector3d p = o + t * d;
    if (t > 0 && t < best && p.head<2>().squaredNorm() <= r * r) best = t;
  }
  return best;
}

// A standard normal deviate (Box-Muller; 1 - Uniform() is never 0).
inline double Gaussian(SplitMix64& random) {
  const double u = 1 - random.Uniform(), v = random.Uniform();
  return std::sqrt(-2 * std::log(u)) * std::cos(2 * 3.14159265358979323846 * v);
}

// Places up to options.objects objects; gives up on one after a few hundred tries.
inline std::vector<TabletopObject> PlaceObjects(const TabletopFrameOptions& options,
                                                SplitMix64& random) {
  std::vector<TabletopObject> placed;
  const auto uniform = [&random](double lo, double hi) {
    return static_cast<float>(lo + (hi - lo) * random.Uniform());
  };
  for (int k = 0; k < options.objects; ++k) {
    for (int attempt = 0; attempt < 500; ++attempt) {
      TabletopObject o;
      o.kind = static_cast<ObjectKind>(static_cast<int>(random.Uniform() * 3));
      const float a = uniform(options.min_size, options.max_size);
      if (o.kind == ObjectKind::kSphere) o.size = {a, a, a};
      if (o.kind == ObjectKind::kBox) {
        o.size = {a, uniform(options.min_size, options.max_size),
                  uniform(options.min_size, options.max_size)};
      }
      if (o.kind == ObjectKind::kCylinder) {
        o.size = {a, a, uniform(options.min_size, options.max_size)};
      }
      const Eigen::Vector2f room =
          Eigen::Vector2f(static_cast<float>(options.table_width),
                          static_cast<float>(options.table_depth)) /
              2 -
          o.size.head<2>() / 2 - Eigen::Vector2f::Constant(static_cast<float>(options.edge_margin));
      if ((room.array() < 0).any()) continue;
      double gap_needed = options.min_gap;
      if (options.touching && !placed.empty()) {
        // Slide the new object out from an earlier one's center until the gap is reached:
        // the distance grows monotonically along the way (convex solids), so bisect.
        const TabletopObject& anchor =
            placed[static_cast<size_t>(random.Uniform() * static_cast<double>(placed.size()))];
        const double angle = 2 * 3.14159265358979323846 * random.Uniform();
        const Eigen::Vector2f dir(static_cast<float>(std::cos(angle)),
                                  static_cast<float>(std::sin(angle)));
        const double gap = options.max_contact_gap * random.Uniform();
        double lo = 0, hi = 1;
        for (int i = 0; i < 50; ++i) {
          o.center = anchor.center + static_cast<float>((lo + hi) / 2) * dir;
          (SolidDistance(anchor, o) < gap ? lo : hi) = (lo + hi) / 2;
        }
        o.center = anchor.center + static_cast<float>(hi) * dir;
        gap_needed = 0;
      } else {
        o.center = {uniform(-room.x(), room.x()), uniform(-room.y(), room.y())};
        if (options.touching) gap_needed = 0;
      }
      if ((o.center.cwiseAbs().array() > room.array()).any()) continue;
      bool fits = true;
      for (const TabletopObject& other : placed)
        fits = fits && SolidDistance(other, o) >= gap_needed;
      if (!fits) continue;
      placed.push_back(o);
      break;
    }
  }
  return placed;
}

}  // namespace internal

inline TabletopFrame MakeTabletopFrame(const TabletopFrameOptions& options) {
  SplitMix64 placement(options.seed);
  SplitMix64 noise(options.seed ^ 0x5851f42d4c957f2dull);  // its own stream: noise on or off
                                                           // does not move the objects
  TabletopFrame frame;
  frame.objects = internal::PlaceObjects(options, placement);

  constexpr double kPi = 3.14159265358979323846;
  const double pitch = options.pitch_degrees * kPi / 180;
  const Eigen::Vector3d up(0, -std::cos(pitch), -std::sin(pitch));
  frame.table_axes.col(0) = Eigen::Vector3d(1, 0, 0);
  frame.table_axes.col(1) = Eigen::Vector3d(0, -std::sin(pitch), std::cos(pitch));
  frame.table_axes.col(2) = up;
  frame.table_origin = Eigen::Vector3d(0, 0, options.table_distance);
  const double table_d = -up.dot(frame.table_origin);
  frame.table_plane << up.cast<float>(), static_cast<float>(table_d);
  if (options.floor_drop > 0) {
    frame.floor_plane << up.cast<float>(), static_cast<float>(table_d + options.floor_drop);
  }
  // The camera in the table's frame: rays are cast there and their points mapped back.
  const Eigen::Matrix3d to_table = frame.table_axes.transpose();
  const Eigen::Vector3d origin = -(to_table * frame.table_origin);

  const double focal = options.height / 2.0 / std::tan(options.vertical_fov_degrees * kPi / 360);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  frame.cloud.Reserve(static_cast<size_t>(options.width) * static_cast<size_t>(options.height));
  for (int v = 0; v < options.height; ++v) {
    for (int u = 0; u < options.width; ++u) {
      // Depth z is the ray's parameter: the camera-frame direction has z = 1.
      const Eigen::Vector3d ray((u + 0.5 - options.width / 2.0) / focal,
                                (v + 0.5 - options.height / 2.0) / focal, 1);
      const Eigen::Vector3d d = to_table * ray;
      double t = std::numeric_limits<double>::infinity();
      int32_t id = kNothing;
      if (d.z() < 0) {
        const double t_table = -origin.z() / d.z();
        const Eigen::Vector3d p = origin + t_table * d;
        if (std::abs(p.x()) <= options.table_width / 2 &&
            std::abs(p.y()) <= options.table_depth / 2) {
          t = t_table, id = kTable;
        } else if (options.floor_drop > 0) {
          t = (-options.floor_drop - origin.z()) / d.z(), id = kFloor;
        }
      }
      for (size_t k = 0; k < frame.objects.size(); ++k) {
        const double hit = internal::RayHit(frame.objects[k], origin, d);
        if (hit < t) t = hit, id = static_cast<int32_t>(k);
      }
      if (!(t <= options.max_depth)) id = kNothing;
      if (id == kNothing) {
        if (options.drop_missing) continue;
        frame.cloud.Add(nan, nan, nan);
      } else {
        const double depth = t + options.depth_noise * t * t * internal::Gaussian(noise);
        frame.cloud.Add((depth * ray).cast<float>());
        if (id >= 0) ++frame.objects[static_cast<size_t>(id)].points;
      }
      frame.truth.push_back(id);
    }
  }
  frame.width = options.drop_missing ? frame.cloud.size() : static_cast<size_t>(options.width);
  frame.height = options.drop_missing ? 1 : static_cast<size_t>(options.height);
  return frame;
}

// How a segmentation's clusters (frame indices) meet the frame's objects.
struct ClusterScore {
  int visible = 0;  // objects with at least `min_points` points
  int found = 0;    // a cluster holds >= 50 % of the object's points
  int alone = 0;    // ... and the object is >= 50 % of that cluster
  int other = 0;    // clusters that are mostly not any one object (table, floor, a mix)
};
inline ClusterScore ScoreClusters(const TabletopFrame& frame,
                                  const std::vector<std::vector<uint32_t>>& clusters,
                                  size_t min_points) {
  ClusterScore score;
  // counts[c][k]: points of object k in cluster c.
  std::vector<std::vector<size_t>> counts(clusters.size(),
                                          std::vector<size_t>(frame.objects.size()));
  for (size_t c = 0; c < clusters.size(); ++c) {
    for (const uint32_t i : clusters[c]) {
      if (frame.truth[i] >= 0) ++counts[c][static_cast<size_t>(frame.truth[i])];
    }
    const size_t best =
        counts[c].empty() ? 0 : *std::max_element(counts[c].begin(), counts[c].end());
    score.other += 2 * best < clusters[c].size() ? 1 : 0;
  }
  for (size_t k = 0; k < frame.objects.size(); ++k) {
    if (frame.objects[k].points < min_points) continue;
    ++score.visible;
    bool found = false, alone = false;
    for (size_t c = 0; c < clusters.size(); ++c) {
      if (2 * counts[c][k] < frame.objects[k].points) continue;
      found = true;
      alone = alone || 2 * counts[c][k] >= clusters[c].size();
    }
    score.found += found ? 1 : 0;
    score.alone += alone ? 1 : 0;
  }
  return score;
}

}  // namespace shapeid::testing_frames

#endif  // SHAPEID_CORE_TESTING_TABLETOP_FRAMES_H_
