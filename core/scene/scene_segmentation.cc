#include "core/scene/scene_segmentation.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <iterator>
#include <limits>
#include <numeric>
#include <optional>
#include <tuple>
#include <utility>

#include "Eigen/Eigenvalues"
#include "absl/container/flat_hash_map.h"
#include "absl/strings/str_cat.h"
#include "core/random.h"

namespace shapeid {
namespace {

constexpr int kMaxPlanes = 16;
constexpr int kMaxPlaneIterations = 10000;
// Each hypothesis is scored on this many of the candidate points, not all: the count's
// relative error is then about 2 % for a plane holding a quarter of the points, and the
// winner is refitted and recounted on every point.
constexpr size_t kPlaneScoringPoints = 4096;
constexpr double kPlaneConfidence = 0.999;
constexpr double kRadiansPerDegree = 3.14159265358979323846 / 180;
// Grid cells per axis for clustering: coordinates are packed 21 bits each into one key.
constexpr int64_t kGridCells = int64_t{1} << 20;

absl::Status CheckOptions(const SceneSegmentationOptions& o) {
  const auto bad = [](auto&&... parts) {
    return absl::InvalidArgumentError(absl::StrCat(parts...));
  };
  if (o.max_planes < 0 || o.max_planes > kMaxPlanes) {
    return bad("max_planes is ", o.max_planes, "; it must be in [0, ", kMaxPlanes, "]");
  }
  if (!(o.plane_distance > 0) || !std::isfinite(o.plane_distance)) {
    return bad("plane_distance is ", o.plane_distance, "; it must be a positive number");
  }
  if (!(o.min_plane_share > 0 && o.min_plane_share <= 1)) {
    return bad("min_plane_share is ", o.min_plane_share, "; it must be in (0, 1]");
  }
  if (o.plane_iterations < 1 || o.plane_iterations > kMaxPlaneIterations) {
    return bad("plane_iterations is ", o.plane_iterations, "; it must be in [1, ",
               kMaxPlaneIterations, "]");
  }
  if (!(o.cluster_tolerance > 0) || !std::isfinite(o.cluster_tolerance)) {
    return bad("cluster_tolerance is ", o.cluster_tolerance, "; it must be a positive number");
  }
  if (o.min_cluster_points < 1 || o.min_cluster_points > o.max_cluster_points) {
    return bad("min_cluster_points is ", o.min_cluster_points, " and max_cluster_points ",
               o.max_cluster_points, ": need 1 <= min <= max");
  }
  if (o.up.has_value() && (!o.up->allFinite() || !(o.up->norm() > 0))) {
    return bad("up is (", o.up->x(), ", ", o.up->y(), ", ", o.up->z(),
               "); it must be finite and not zero");
  }
  if (!(o.max_plane_tilt_degrees > 0 && o.max_plane_tilt_degrees <= 90)) {
    return bad("max_plane_tilt_degrees is ", o.max_plane_tilt_degrees, "; it must be in (0, 90]");
  }
  if (o.region.has_value()) {
    const auto& r = *o.region;
    if (r.min.hasNaN() || r.max.hasNaN() || (r.min.array() > r.max.array()).any()) {
      return bad("the region's min (", r.min.x(), ", ", r.min.y(), ", ", r.min.z(),
                 ") must be a number and not above its max (", r.max.x(), ", ", r.max.y(), ", ",
                 r.max.z(), ") on any axis");
    }
  }
  return absl::OkStatus();
}

// The plane through three points, unit normal, or nullopt when they are (nearly) collinear.
std::optional<Eigen::Vector4f> PlaneThrough(const Eigen::Vector3f& a, const Eigen::Vector3f& b,
                                            const Eigen::Vector3f& c) {
  const Eigen::Vector3f u = b - a, v = c - a;
  const Eigen::Vector3f n = u.cross(v);
  const float norm = n.norm();
  if (!(norm > 1e-6f * u.norm() * v.norm())) return std::nullopt;
  const Eigen::Vector3f unit = n / norm;
  return Eigen::Vector4f(unit.x(), unit.y(), unit.z(), -unit.dot(a));
}

// Whether (x, y, z) lies closer than `distance` to `plane`: the one test of scoring and
// of the final count, so that both see the same points on a plane.
inline bool OnPlane(const Eigen::Vector4f& plane, float x, float y, float z, float distance) {
  return std::fabs(plane[0] * x + plane[1] * y + plane[2] * z + plane[3]) < distance;
}

// Whether `plane` may be a support: any plane, or one within the tilt of the caller's up.
bool Upright(const Eigen::Vector4f& plane, const SceneSegmentationOptions& options) {
  if (!options.up.has_value() || options.max_plane_tilt_degrees >= 90) return true;
  const double cosine =
      std::fabs(plane.head<3>().cast<double>().dot(options.up->cast<double>().normalized()));
  return cosine >= std::cos(options.max_plane_tilt_degrees * kRadiansPerDegree);
}

// How many of the points (x[i], y[i], z[i]) are on `plane`.
size_t CountNear(const std::vector<float>& x, const std::vector<float>& y,
                 const std::vector<float>& z, const Eigen::Vector4f& plane, float distance) {
  size_t count = 0;
  for (size_t i = 0; i < x.size(); ++i) count += OnPlane(plane, x[i], y[i], z[i], distance);
  return count;
}

// The points of `frame` at `ids` on `plane`, in the order of `ids`.
std::vector<uint32_t> PointsNear(const PointCloud& frame, const std::vector<uint32_t>& ids,
                                 const Eigen::Vector4f& plane, float distance) {
  std::vector<uint32_t> near;
  const float* xyz = frame.data();
  for (const uint32_t i : ids) {
    const float* p = xyz + 3 * static_cast<size_t>(i);
    if (OnPlane(plane, p[0], p[1], p[2], distance)) near.push_back(i);
  }
  return near;
}

// The mean of `ids`' points and the sum of their outer products about it, in double.
std::pair<Eigen::Vector3d, Eigen::Matrix3d> MeanAndScatter(const PointCloud& frame,
                                                           const std::vector<uint32_t>& ids) {
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const uint32_t i : ids) mean += frame.point(i).cast<double>();
  mean /= static_cast<double>(ids.size());
  Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
  for (const uint32_t i : ids) {
    const Eigen::Vector3d d = frame.point(i).cast<double>() - mean;
    scatter.noalias() += d * d.transpose();
  }
  return {mean, scatter};
}

// The least-squares plane of `ids`' points (the normal is the covariance's weakest axis),
// its normal on the same side as `guide`'s.
Eigen::Vector4f FitPlane(const PointCloud& frame, const std::vector<uint32_t>& ids,
                         const Eigen::Vector4f& guide) {
  const auto [mean, scatter] = MeanAndScatter(frame, ids);
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(scatter);
  Eigen::Vector3d normal = solver.eigenvectors().col(0).normalized();
  if (normal.dot(guide.head<3>().cast<double>()) < 0) normal = -normal;
  return Eigen::Vector4f(static_cast<float>(normal.x()), static_cast<float>(normal.y()),
                         static_cast<float>(normal.z()), static_cast<float>(-normal.dot(mean)));
}

// One RANSAC plane over `candidates` (>= 3 points): the hypothesis that holds the most
// scoring points, refitted by least squares to all the points near it. Returns the plane and
// the candidates on it.
std::pair<Eigen::Vector4f, std::vector<uint32_t>> FindPlane(const PointCloud& frame,
                                                            const std::vector<uint32_t>& candidates,
                                                            const SceneSegmentationOptions& options,
                                                            SplitMix64& random) {
  const auto draw = [&random](size_t n) { return static_cast<size_t>(random.Uniform() * n); };
  const size_t m = std::min(kPlaneScoringPoints, candidates.size());
  std::vector<float> x(m), y(m), z(m);
  std::vector<uint32_t> scoring(m);
  for (size_t i = 0; i < m; ++i) {
    scoring[i] = m == candidates.size() ? candidates[i] : candidates[draw(candidates.size())];
    const auto p = frame.point(scoring[i]);
    x[i] = p.x(), y[i] = p.y(), z[i] = p.z();
  }
  Eigen::Vector4f best = Eigen::Vector4f::Zero();
  size_t best_count = 0;
  int needed = options.plane_iterations;
  for (int iteration = 0; iteration < needed; ++iteration) {
    const size_t a = draw(m), b = draw(m), c = draw(m);
    if (a == b || b == c || a == c) continue;
    const std::optional<Eigen::Vector4f> plane =
        PlaneThrough(frame.point(scoring[a]), frame.point(scoring[b]), frame.point(scoring[c]));
    if (!plane.has_value() || !Upright(*plane, options)) continue;
    const size_t count = CountNear(x, y, z, *plane, options.plane_distance);
    if (count <= best_count) continue;
    best_count = count;
    best = *plane;
    // Draws needed to pick three points of a plane this large with kPlaneConfidence.
    const double share = static_cast<double>(count) / static_cast<double>(m);
    const double miss = 1 - share * share * share;
    if (miss <= 0) break;
    const double draws = std::log(1 - kPlaneConfidence) / std::log(miss);
    needed = static_cast<int>(std::min<double>(options.plane_iterations, std::ceil(draws)));
  }
  if (best_count < 3) return {best, {}};
  // The refit is kept even when it holds a few points fewer: a three-point plane tilted by
  // a fraction of a degree also shaves the bases of the objects standing on it.
  const std::vector<uint32_t> on_plane =
      PointsNear(frame, candidates, best, options.plane_distance);
  const Eigen::Vector4f refit = FitPlane(frame, on_plane, best);
  return {refit, PointsNear(frame, candidates, refit, options.plane_distance)};
}

// Union-find over grid cells; the smaller index is the root, so the result does not depend on
// the order of the unions.
class DisjointSets {
 public:
  explicit DisjointSets(size_t n) : parent_(n) { std::iota(parent_.begin(), parent_.end(), 0u); }
  uint32_t Find(uint32_t i) {
    while (parent_[i] != i) {
      parent_[i] = parent_[parent_[i]];
      i = parent_[i];
    }
    return i;
  }
  void Union(uint32_t a, uint32_t b) {
    a = Find(a), b = Find(b);
    if (a < b) std::swap(a, b);
    parent_[a] = b;
  }

 private:
  std::vector<uint32_t> parent_;
};

uint64_t CellKey(int64_t ix, int64_t iy, int64_t iz) {
  return static_cast<uint64_t>(ix) | static_cast<uint64_t>(iy) << 21 |
         static_cast<uint64_t>(iz) << 42;
}

// The connected groups of `points` (ascending frame indices) under "closer than `tolerance`"
// (squared float distances, strictly less: PCL's kd-tree and Open3D's DBSCAN test). Points are
// binned into cubic cells a little smaller than tolerance / sqrt(3), so the points of one cell are
// all within the tolerance of each other; two cells are joined when some pair of their points is.
// Cells up to two apart on each axis can hold such pairs.
absl::StatusOr<std::vector<std::vector<uint32_t>>> EuclideanClusters(
    const PointCloud& frame, const std::vector<uint32_t>& points, float tolerance) {
  std::vector<std::vector<uint32_t>> clusters;
  if (points.empty()) return clusters;
  Eigen::Vector3f low = frame.point(points[0]), high = low;
  for (const uint32_t i : points) {
    low = low.cwiseMin(frame.point(i));
    high = high.cwiseMax(frame.point(i));
  }
  const double cell = static_cast<double>(tolerance) / std::sqrt(3.0) * (1 - 1e-6);
  const Eigen::Vector3d cells = ((high - low).cast<double>() / cell).array().floor() + 1;
  if (cells.maxCoeff() >= static_cast<double>(kGridCells)) {
    // Printed as doubles: a frame of huge coordinates spans more tolerances than an int holds.
    return absl::InvalidArgumentError(
        absl::StrCat("the frame spans ", std::floor(cells.maxCoeff() * cell / tolerance),
                     " cluster tolerances along one axis, more than the grid's ",
                     std::floor(static_cast<double>(kGridCells) * cell / tolerance),
                     ": widen the cluster tolerance or set a region of interest"));
  }
  const double inverse = 1 / cell;
  const auto cell_of = [&](uint32_t i) {
    const Eigen::Vector3d offset = (frame.point(i) - low).cast<double>() * inverse;
    return std::array<int64_t, 3>{static_cast<int64_t>(offset.x()),
                                  static_cast<int64_t>(offset.y()),
                                  static_cast<int64_t>(offset.z())};
  };

  // Cells in order of first appearance; consecutive points of a scan share cells, so the
  // last key is remembered.
  absl::flat_hash_map<uint64_t, uint32_t> cell_index;
  std::vector<std::array<int64_t, 3>> cell_coords;
  std::vector<uint32_t> cell_of_point(points.size());
  uint64_t last_key = std::numeric_limits<uint64_t>::max();
  uint32_t last_cell = 0;
  for (size_t k = 0; k < points.size(); ++k) {
    const std::array<int64_t, 3> c = cell_of(points[k]);
    const uint64_t key = CellKey(c[0], c[1], c[2]);
    if (key != last_key) {
      const auto [it, inserted] =
          cell_index.try_emplace(key, static_cast<uint32_t>(cell_coords.size()));
      if (inserted) cell_coords.push_back(c);
      last_key = key;
      last_cell = it->second;
    }
    cell_of_point[k] = last_cell;
  }
  // Points grouped by cell (counting sort), with their coordinates side by side.
  const size_t num_cells = cell_coords.size();
  std::vector<uint32_t> start(num_cells + 1, 0);
  for (const uint32_t c : cell_of_point) ++start[c + 1];
  std::partial_sum(start.begin(), start.end(), start.begin());
  std::vector<Eigen::Vector3f> grouped(points.size());
  {
    std::vector<uint32_t> next(start.begin(), start.end() - 1);
    for (size_t k = 0; k < points.size(); ++k)
      grouped[next[cell_of_point[k]]++] = frame.point(points[k]);
  }
  std::vector<Eigen::AlignedBox3f> bounds(num_cells);
  for (size_t c = 0; c < num_cells; ++c) {
    for (uint32_t k = start[c]; k < start[c + 1]; ++k) bounds[c].extend(grouped[k]);
  }

  const float tolerance2 = tolerance * tolerance;
  const auto joined = [&](uint32_t a, uint32_t b) {
    const Eigen::AlignedBox3f& A = bounds[a];
    const Eigen::AlignedBox3f& B = bounds[b];
    if (A.squaredExteriorDistance(B) >= tolerance2) return false;  // no pair is near enough
    const Eigen::Vector3f farthest =
        (A.max() - B.min()).cwiseAbs().cwiseMax((B.max() - A.min()).cwiseAbs());
    if (farthest.squaredNorm() < tolerance2) return true;  // every pair is
    for (uint32_t i = start[a]; i < start[a + 1]; ++i) {
      for (uint32_t j = start[b]; j < start[b + 1]; ++j) {
        if ((grouped[i] - grouped[j]).squaredNorm() < tolerance2) return true;
      }
    }
    return false;
  };
  // The 62 neighbor offsets after (0, 0, 0) in lexicographic order: each pair once.
  std::vector<std::array<int, 3>> offsets;
  for (int dx = -2; dx <= 2; ++dx) {
    for (int dy = -2; dy <= 2; ++dy) {
      for (int dz = -2; dz <= 2; ++dz) {
        if (std::make_tuple(dx, dy, dz) > std::make_tuple(0, 0, 0)) offsets.push_back({dx, dy, dz});
      }
    }
  }
  DisjointSets sets(num_cells);
  for (uint32_t a = 0; a < num_cells; ++a) {
    const std::array<int64_t, 3>& c = cell_coords[a];
    for (const std::array<int, 3>& d : offsets) {
      const int64_t nx = c[0] + d[0], ny = c[1] + d[1], nz = c[2] + d[2];
      if (nx < 0 || ny < 0 || nz < 0 || nx >= kGridCells || ny >= kGridCells || nz >= kGridCells) {
        continue;
      }
      const auto it = cell_index.find(CellKey(nx, ny, nz));
      if (it == cell_index.end()) continue;
      const uint32_t b = it->second;
      if (sets.Find(a) != sets.Find(b) && joined(a, b)) sets.Union(a, b);
    }
  }
  // Each root's cluster, its points in ascending frame order.
  std::vector<int32_t> cluster_of_root(num_cells, -1);
  std::vector<uint32_t> cluster_of_cell(num_cells);
  for (uint32_t c = 0; c < num_cells; ++c) {
    const uint32_t root = sets.Find(c);
    if (cluster_of_root[root] < 0) {
      cluster_of_root[root] = static_cast<int32_t>(clusters.size());
      clusters.emplace_back();
    }
    cluster_of_cell[c] = static_cast<uint32_t>(cluster_of_root[root]);
  }
  for (size_t k = 0; k < points.size(); ++k) {
    clusters[cluster_of_cell[cell_of_point[k]]].push_back(points[k]);
  }
  return clusters;
}

}  // namespace

absl::Status ValidateSceneSegmentationOptions(const SceneSegmentationOptions& options) {
  return CheckOptions(options);
}

absl::StatusOr<SceneSegmentation> SegmentScene(const PointCloud& frame,
                                               const SceneSegmentationOptions& options) {
  if (absl::Status s = CheckOptions(options); !s.ok()) return s;
  if (frame.size() >= std::numeric_limits<uint32_t>::max()) {
    return absl::InvalidArgumentError(
        absl::StrCat("the frame has ", frame.size(), " points; at most 2^32 - 2 are segmented"));
  }
  SceneSegmentation result;
  std::vector<uint32_t> candidates;
  candidates.reserve(frame.size());
  for (size_t i = 0; i < frame.size(); ++i) {
    const auto p = frame.point(i);
    if (!p.allFinite()) {
      ++result.non_finite_points;
    } else if (options.region.has_value() && ((p.array() < options.region->min.array()).any() ||
                                              (p.array() > options.region->max.array()).any())) {
      ++result.outside_region;
    } else {
      candidates.push_back(static_cast<uint32_t>(i));
    }
  }

  const size_t min_plane_points = std::max<size_t>(
      3, static_cast<size_t>(std::ceil(options.min_plane_share * candidates.size())));
  SplitMix64 random(options.seed);
  const auto interrupted = [&options] {
    return options.interrupt ? options.interrupt() : absl::OkStatus();
  };
  for (int p = 0; p < options.max_planes && candidates.size() >= min_plane_points; ++p) {
    if (absl::Status stop = interrupted(); !stop.ok()) return stop;
    auto [plane, on_plane] = FindPlane(frame, candidates, options, random);
    if (on_plane.size() < min_plane_points || !Upright(plane, options)) break;
    // The normal's sign: up, else the frame's origin (the sensor, in its own frame) on the
    // positive side.
    if (options.up.has_value() ? plane.head<3>().dot(*options.up) < 0 : plane[3] < 0) {
      plane = -plane;
    }
    result.planes.push_back({plane, on_plane.size()});
    // Both lists ascend: keep the candidates not on the plane.
    std::vector<uint32_t> rest;
    rest.reserve(candidates.size() - on_plane.size());
    std::set_difference(candidates.begin(), candidates.end(), on_plane.begin(), on_plane.end(),
                        std::back_inserter(rest));
    candidates = std::move(rest);
  }

  if (absl::Status stop = interrupted(); !stop.ok()) return stop;
  absl::StatusOr<std::vector<std::vector<uint32_t>>> clusters =
      EuclideanClusters(frame, candidates, options.cluster_tolerance);
  if (!clusters.ok()) return clusters.status();
  for (std::vector<uint32_t>& cluster : *clusters) {
    if (cluster.size() < options.min_cluster_points) {
      result.in_small_clusters += cluster.size();
    } else if (cluster.size() > options.max_cluster_points) {
      result.in_large_clusters += cluster.size();
    } else {
      result.clusters.push_back(std::move(cluster));
    }
  }
  std::sort(result.clusters.begin(), result.clusters.end(),
            [](const std::vector<uint32_t>& a, const std::vector<uint32_t>& b) {
              return a.size() != b.size() ? a.size() > b.size() : a.front() < b.front();
            });
  return result;
}

ClusterGeometry DescribeClusterGeometry(const PointCloud& frame,
                                        const std::vector<uint32_t>& indices) {
  ClusterGeometry geometry;
  const auto [mean, scatter] = MeanAndScatter(frame, indices);
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(scatter);
  Eigen::Matrix3d axes;  // largest spread first; eigenvalues come in increasing order
  axes.col(0) = solver.eigenvectors().col(2).normalized();
  axes.col(1) = solver.eigenvectors().col(1).normalized();
  axes.col(2) = axes.col(0).cross(axes.col(1));
  Eigen::Vector3d low = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
  Eigen::Vector3d high = -low;
  for (const uint32_t i : indices) {
    const Eigen::Vector3d along = axes.transpose() * (frame.point(i).cast<double>() - mean);
    low = low.cwiseMin(along);
    high = high.cwiseMax(along);
  }
  geometry.centroid = mean.cast<float>();
  geometry.box.axes = axes.cast<float>();
  geometry.box.center = (mean + axes * (low + high) / 2).cast<float>();
  geometry.box.size = (high - low).cast<float>();
  return geometry;
}

}  // namespace shapeid
