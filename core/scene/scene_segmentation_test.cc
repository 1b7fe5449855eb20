#include "core/scene/scene_segmentation.h"

#include <cmath>
#include <limits>
#include <numeric>
#include <vector>

#include "Eigen/Geometry"
#include "core/random.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"

namespace shapeid {
namespace {

using ::testing::ElementsAre;
using ::testing::HasSubstr;

// Appends a grid of points on the plane z = height, [x0, x1] x [y0, y1], `step` apart.
void AddFloor(PointCloud& cloud, float height, float x0, float x1, float y0, float y1, float step) {
  for (float x = x0; x <= x1; x += step) {
    for (float y = y0; y <= y1; y += step) cloud.Add(x, y, height);
  }
}

// Appends the surface of an axis-aligned box as a grid of points `step` apart, and returns the
// indices it added.
std::vector<uint32_t> AddBox(PointCloud& cloud, const Eigen::Vector3f& low,
                             const Eigen::Vector3f& high, float step) {
  std::vector<uint32_t> added;
  const auto add = [&](const Eigen::Vector3f& p) {
    added.push_back(static_cast<uint32_t>(cloud.size()));
    cloud.Add(p);
  };
  for (float x = low.x(); x <= high.x() + 1e-6f; x += step) {
    for (float y = low.y(); y <= high.y() + 1e-6f; y += step) {
      for (float z = low.z(); z <= high.z() + 1e-6f; z += step) {
        const bool on_surface = x - low.x() < step / 2 || high.x() - x < step / 2 ||
                                y - low.y() < step / 2 || high.y() - y < step / 2 ||
                                z - low.z() < step / 2 || high.z() - z < step / 2;
        if (on_surface) add({x, y, z});
      }
    }
  }
  return added;
}

size_t Accounted(const SceneSegmentation& s) {
  size_t total = s.non_finite_points + s.outside_region + s.in_small_clusters + s.in_large_clusters;
  for (const ScenePlane& plane : s.planes) total += plane.points;
  for (const auto& cluster : s.clusters) total += cluster.size();
  return total;
}

// A table half a metre below the sensor with three boxes standing clear of it.
TEST(SceneSegmentationTest, TableTopObjectsAreTheClusters) {
  PointCloud frame;
  AddFloor(frame, -0.5f, -0.5f, 0.5f, -0.5f, 0.5f, 0.005f);
  const size_t table_points = frame.size();
  const std::vector<uint32_t> a =
      AddBox(frame, {-0.3f, -0.3f, -0.47f}, {-0.2f, -0.2f, -0.37f}, 0.004f);
  const std::vector<uint32_t> b =
      AddBox(frame, {0.1f, 0.0f, -0.47f}, {0.16f, 0.2f, -0.40f}, 0.004f);
  const std::vector<uint32_t> c =
      AddBox(frame, {0.2f, -0.4f, -0.47f}, {0.24f, -0.36f, -0.3f}, 0.004f);
  ASSERT_GT(b.size(), c.size());
  SceneSegmentationOptions options;
  options.min_cluster_points = 50;
  const absl::StatusOr<SceneSegmentation> s = SegmentScene(frame, options);
  ASSERT_TRUE(s.ok()) << s.status();
  ASSERT_EQ(s->planes.size(), 1u);
  EXPECT_EQ(s->planes[0].points, table_points);
  EXPECT_NEAR(s->planes[0].coefficients[2], 1.0f, 1e-4f);  // normal up, towards the sensor
  EXPECT_NEAR(s->planes[0].coefficients[3], 0.5f, 1e-4f);
  // Largest first: a (a 10 cm cube) holds the most points.
  ASSERT_EQ(s->clusters.size(), 3u);
  EXPECT_EQ(s->clusters[0], a);
  EXPECT_EQ(s->clusters[1], b);
  EXPECT_EQ(s->clusters[2], c);
  EXPECT_EQ(Accounted(*s), frame.size());
}

// Clusters are the connected groups of "at most the tolerance apart", as a brute-force search
// over every pair finds them, on clumped random points and several tolerances.
TEST(SceneSegmentationTest, ClustersEqualConnectedGroupsFoundByBruteForce) {
  for (const uint64_t seed : {1u, 2u, 3u}) {
    SplitMix64 random(seed);
    PointCloud frame;
    for (int clump = 0; clump < 12; ++clump) {
      const Eigen::Vector3f center(static_cast<float>(random.Uniform()),
                                   static_cast<float>(random.Uniform()),
                                   static_cast<float>(random.Uniform() * 0.3));
      for (int i = 0; i < 150; ++i) {
        frame.Add(center + 0.06f * Eigen::Vector3f(static_cast<float>(random.Uniform() - 0.5),
                                                   static_cast<float>(random.Uniform() - 0.5),
                                                   static_cast<float>(random.Uniform() - 0.5)));
      }
    }
    for (const float tolerance : {0.005f, 0.012f, 0.03f, 0.1f}) {
      // Brute force: breadth-first search over all pairs.
      const size_t n = frame.size();
      std::vector<int> component(n, -1);
      std::vector<std::vector<uint32_t>> expected;
      for (size_t start = 0; start < n; ++start) {
        if (component[start] >= 0) continue;
        const int id = static_cast<int>(expected.size());
        expected.emplace_back();
        std::vector<size_t> queue = {start};
        component[start] = id;
        while (!queue.empty()) {
          const size_t i = queue.back();
          queue.pop_back();
          expected.back().push_back(static_cast<uint32_t>(i));
          for (size_t j = 0; j < n; ++j) {
            if (component[j] < 0 &&
                (frame.point(i) - frame.point(j)).squaredNorm() < tolerance * tolerance) {
              component[j] = id;
              queue.push_back(j);
            }
          }
        }
        std::sort(expected.back().begin(), expected.back().end());
      }
      std::sort(expected.begin(), expected.end(), [](const auto& a, const auto& b) {
        return a.size() != b.size() ? a.size() > b.size() : a.front() < b.front();
      });
      SceneSegmentationOptions options;
      options.max_planes = 0;
      options.cluster_tolerance = tolerance;
      options.min_cluster_points = 1;
      const absl::StatusOr<SceneSegmentation> s = SegmentScene(frame, options);
      ASSERT_TRUE(s.ok()) << s.status();
      EXPECT_EQ(s->clusters, expected) << "seed " << seed << ", tolerance " << tolerance;
    }
  }
}

// Exactly the tolerance apart does not join (strictly closer, as PCL and Open3D); a little
// less does.
TEST(SceneSegmentationTest, ToleranceIsStrict) {
  SceneSegmentationOptions options;
  options.max_planes = 0;
  options.cluster_tolerance = 0.25f;  // exact in binary, as are the coordinates below
  options.min_cluster_points = 1;
  const PointCloud points = {{0, 0, 0}, {0.25f, 0, 0}, {0.49f, 0, 0}, {1.0f, 0, 0}};
  const absl::StatusOr<SceneSegmentation> s = SegmentScene(points, options);
  ASSERT_TRUE(s.ok()) << s.status();
  EXPECT_THAT(s->clusters, ElementsAre(ElementsAre(1u, 2u), ElementsAre(0u), ElementsAre(3u)));
}

TEST(SceneSegmentationTest, SkipsNonFiniteAndOutsideTheRegionAndCountsEverything) {
  PointCloud frame;
  AddFloor(frame, -0.5f, -0.3f, 0.3f, -0.3f, 0.3f, 0.01f);
  const std::vector<uint32_t> box = AddBox(frame, {0, 0, -0.45f}, {0.05f, 0.05f, -0.4f}, 0.005f);
  const std::vector<uint32_t> far = AddBox(frame, {2, 2, -0.45f}, {2.05f, 2.05f, -0.4f}, 0.005f);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  frame.Add(nan, nan, nan);
  frame.Add(0, std::numeric_limits<float>::infinity(), 0);
  SceneSegmentationOptions options;
  options.region = SceneSegmentationOptions::Box{{-1, -1, -1}, {1, 1, 1}};
  options.min_cluster_points = 10;
  const absl::StatusOr<SceneSegmentation> s = SegmentScene(frame, options);
  ASSERT_TRUE(s.ok()) << s.status();
  EXPECT_EQ(s->non_finite_points, 2u);
  EXPECT_EQ(s->outside_region, far.size());
  ASSERT_EQ(s->clusters.size(), 1u);
  EXPECT_EQ(s->clusters[0], box);
  EXPECT_EQ(Accounted(*s), frame.size());
  // Infinite bounds: everything below x = 1, whatever else.
  const float inf = std::numeric_limits<float>::infinity();
  options.region = SceneSegmentationOptions::Box{{-inf, -inf, -inf}, {1, inf, inf}};
  const absl::StatusOr<SceneSegmentation> open = SegmentScene(frame, options);
  ASSERT_TRUE(open.ok()) << open.status();
  EXPECT_EQ(open->outside_region, far.size());
  EXPECT_EQ(open->clusters, s->clusters);
}

TEST(SceneSegmentationTest, ClusterSizeLimitsDropAndCount) {
  PointCloud frame;
  const std::vector<uint32_t> big = AddBox(frame, {0, 0, 0}, {0.1f, 0.1f, 0.1f}, 0.005f);
  const std::vector<uint32_t> mid = AddBox(frame, {1, 0, 0}, {1.04f, 0.04f, 0.04f}, 0.005f);
  frame.Add(3, 3, 3);  // a stray point
  SceneSegmentationOptions options;
  options.max_planes = 0;
  options.min_cluster_points = 2;
  options.max_cluster_points = mid.size();
  const absl::StatusOr<SceneSegmentation> s = SegmentScene(frame, options);
  ASSERT_TRUE(s.ok()) << s.status();
  ASSERT_EQ(s->clusters.size(), 1u);
  EXPECT_EQ(s->clusters[0], mid);
  EXPECT_EQ(s->in_large_clusters, big.size());
  EXPECT_EQ(s->in_small_clusters, 1u);
  EXPECT_EQ(Accounted(*s), frame.size());
}

TEST(SceneSegmentationTest, RemovesAFloorAndAWallLargestFirst) {
  PointCloud frame;
  AddFloor(frame, -1.0f, -1.0f, 1.0f, 0.0f, 2.0f, 0.01f);  // floor z = -1
  const size_t floor_points = frame.size();
  for (float x = -1.0f; x <= 1.0f; x += 0.01f) {  // wall y = 2.2, smaller
    for (float z = -0.9f; z <= 0.0f; z += 0.01f) frame.Add(x, 2.2f, z);
  }
  const size_t wall_points = frame.size() - floor_points;
  const std::vector<uint32_t> box = AddBox(frame, {0, 1, -0.95f}, {0.1f, 1.1f, -0.85f}, 0.005f);
  SceneSegmentationOptions options;
  options.max_planes = 2;
  const absl::StatusOr<SceneSegmentation> s = SegmentScene(frame, options);
  ASSERT_TRUE(s.ok()) << s.status();
  ASSERT_EQ(s->planes.size(), 2u);
  EXPECT_EQ(s->planes[0].points, floor_points);
  EXPECT_EQ(s->planes[1].points, wall_points);
  EXPECT_NEAR(std::fabs(s->planes[1].coefficients[1]), 1.0f, 1e-4f);
  EXPECT_GT(s->planes[1].coefficients[3], 0);  // the origin on the positive side
  ASSERT_EQ(s->clusters.size(), 1u);
  EXPECT_EQ(s->clusters[0], box);
}

// A wall larger than the floor: without up it is removed first; with up it is never a
// support, and the floor's normal points up whatever side the origin is on.
TEST(SceneSegmentationTest, WithUpOnlyLevelPlanesAreSupports) {
  PointCloud frame;
  AddFloor(frame, -0.5f, -0.5f, 0.5f, 0.0f, 1.0f, 0.01f);  // floor z = -0.5, 101 x 101
  const size_t floor_points = frame.size();
  for (float x = -1.0f; x <= 1.0f; x += 0.01f) {  // wall y = 1.05, 201 x 91
    for (float z = -0.45f; z <= 0.45f; z += 0.01f) frame.Add(x, 1.05f, z);
  }
  const std::vector<uint32_t> box = AddBox(frame, {0, 0.5f, -0.45f}, {0.1f, 0.6f, -0.35f}, 0.005f);
  SceneSegmentationOptions any_plane;
  any_plane.max_planes = 1;
  const absl::StatusOr<SceneSegmentation> wall_first = SegmentScene(frame, any_plane);
  ASSERT_TRUE(wall_first.ok()) << wall_first.status();
  ASSERT_EQ(wall_first->planes.size(), 1u);
  EXPECT_NEAR(std::fabs(wall_first->planes[0].coefficients[1]), 1.0f, 1e-4f);

  SceneSegmentationOptions level = any_plane;
  level.max_planes = 2;
  level.up = Eigen::Vector3f(0, 0.1f, -3);  // any length; 1.9 degrees from -z
  level.max_plane_tilt_degrees = 5;
  const absl::StatusOr<SceneSegmentation> s = SegmentScene(frame, level);
  ASSERT_TRUE(s.ok()) << s.status();
  ASSERT_EQ(s->planes.size(), 1u);  // the wall is no support
  EXPECT_EQ(s->planes[0].points, floor_points);
  EXPECT_NEAR(s->planes[0].coefficients[2], -1.0f, 1e-4f);  // along up, away from the origin
  EXPECT_NEAR(s->planes[0].coefficients[3], -0.5f, 1e-4f);
  // The wall is left to clustering, an object as far as the default size limits can tell.
  ASSERT_EQ(s->clusters.size(), 2u);
  EXPECT_EQ(s->clusters[1], box);

  // 90 degrees: any plane, the exactly perpendicular wall included.
  SceneSegmentationOptions any_tilt = level;
  any_tilt.max_planes = 1;
  any_tilt.max_plane_tilt_degrees = 90;
  const absl::StatusOr<SceneSegmentation> wall = SegmentScene(frame, any_tilt);
  ASSERT_TRUE(wall.ok()) << wall.status();
  ASSERT_EQ(wall->planes.size(), 1u);
  EXPECT_NEAR(std::fabs(wall->planes[0].coefficients[1]), 1.0f, 1e-4f);

  SceneSegmentationOptions bad = level;
  bad.up = Eigen::Vector3f::Zero();
  EXPECT_EQ(SegmentScene(frame, bad).status().code(), absl::StatusCode::kInvalidArgument);
  bad = level;
  bad.max_plane_tilt_degrees = 91;
  EXPECT_EQ(SegmentScene(frame, bad).status().code(), absl::StatusCode::kInvalidArgument);
}

TEST(SceneSegmentationTest, SmallFlatFacesAreNotSupports) {
  PointCloud frame;
  const std::vector<uint32_t> box = AddBox(frame, {0, 0, 0}, {0.2f, 0.2f, 0.02f}, 0.005f);
  SceneSegmentationOptions options;
  options.min_plane_share = 0.6;  // the box's top face is under half of its points
  const absl::StatusOr<SceneSegmentation> s = SegmentScene(frame, options);
  ASSERT_TRUE(s.ok()) << s.status();
  EXPECT_TRUE(s->planes.empty());
  ASSERT_EQ(s->clusters.size(), 1u);
  EXPECT_EQ(s->clusters[0], box);
}

TEST(SceneSegmentationTest, EmptyAndAllPlaneFramesGiveNoObjects) {
  const absl::StatusOr<SceneSegmentation> empty = SegmentScene(PointCloud(), {});
  ASSERT_TRUE(empty.ok()) << empty.status();
  EXPECT_TRUE(empty->planes.empty());
  EXPECT_TRUE(empty->clusters.empty());
  PointCloud floor;
  AddFloor(floor, -0.5f, -0.5f, 0.5f, -0.5f, 0.5f, 0.01f);
  const absl::StatusOr<SceneSegmentation> plane = SegmentScene(floor, {});
  ASSERT_TRUE(plane.ok()) << plane.status();
  ASSERT_EQ(plane->planes.size(), 1u);
  EXPECT_EQ(plane->planes[0].points, floor.size());
  EXPECT_TRUE(plane->clusters.empty());
}

TEST(SceneSegmentationTest, SameSeedSameAnswer) {
  PointCloud frame;
  SplitMix64 random(9);
  AddFloor(frame, -0.5f, -0.5f, 0.5f, -0.5f, 0.5f, 0.01f);
  for (size_t i = 0; i < frame.size(); ++i) {
    frame.mutable_xyz()[3 * i + 2] += static_cast<float>(0.004 * (random.Uniform() - 0.5));
  }
  AddBox(frame, {0, 0, -0.45f}, {0.05f, 0.05f, -0.4f}, 0.005f);
  SceneSegmentationOptions options;
  options.seed = 4;
  const absl::StatusOr<SceneSegmentation> first = SegmentScene(frame, options);
  const absl::StatusOr<SceneSegmentation> second = SegmentScene(frame, options);
  ASSERT_TRUE(first.ok() && second.ok());
  EXPECT_EQ(first->planes[0].coefficients, second->planes[0].coefficients);
  // The least-squares refit: within 0.05 degrees of the true normal despite the noise.
  EXPECT_GT(first->planes[0].coefficients[2], std::cos(0.05 * M_PI / 180));
  EXPECT_EQ(first->clusters, second->clusters);
}

TEST(SceneSegmentationTest, RejectsOptionsOutOfRange) {
  const PointCloud frame = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  const auto message = [&](auto change) {
    SceneSegmentationOptions options;
    change(options);
    const absl::StatusOr<SceneSegmentation> s = SegmentScene(frame, options);
    EXPECT_EQ(s.status().code(), absl::StatusCode::kInvalidArgument);
    return std::string(s.status().message());
  };
  EXPECT_THAT(message([](auto& o) { o.max_planes = 17; }), HasSubstr("max_planes"));
  EXPECT_THAT(message([](auto& o) { o.plane_distance = 0; }), HasSubstr("plane_distance"));
  EXPECT_THAT(message([](auto& o) { o.plane_distance = NAN; }), HasSubstr("plane_distance"));
  EXPECT_THAT(message([](auto& o) { o.min_plane_share = 0; }), HasSubstr("min_plane_share"));
  EXPECT_THAT(message([](auto& o) { o.plane_iterations = 0; }), HasSubstr("plane_iterations"));
  EXPECT_THAT(message([](auto& o) { o.cluster_tolerance = -1; }), HasSubstr("cluster_tolerance"));
  EXPECT_THAT(message([](auto& o) { o.min_cluster_points = 0; }), HasSubstr("min_cluster_points"));
  EXPECT_THAT(message([](auto& o) {
                o.min_cluster_points = 10;
                o.max_cluster_points = 9;
              }),
              HasSubstr("min_cluster_points"));
  EXPECT_THAT(message([](auto& o) {
                o.region = SceneSegmentationOptions::Box{{0, 0, 1}, {1, 1, 0}};
              }),
              HasSubstr("region"));
}

TEST(SceneSegmentationTest, AFrameTooWideForTheGridIsRefusedWithTheRemedy) {
  const PointCloud frame = {{0, 0, 0}, {1000, 0, 0}, {0, 1, 0}};
  SceneSegmentationOptions options;
  options.max_planes = 0;
  options.cluster_tolerance = 0.0001f;
  const absl::StatusOr<SceneSegmentation> s = SegmentScene(frame, options);
  EXPECT_EQ(s.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(s.status().message(), HasSubstr("region of interest"));
  // Coordinates whose span overflows float: the same error, no overflowing conversion.
  const PointCloud huge = {{-3e38f, 0, 0}, {3e38f, 0, 0}, {0, 1, 0}};
  const absl::StatusOr<SceneSegmentation> h = SegmentScene(huge, options);
  EXPECT_EQ(h.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(h.status().message(), HasSubstr("inf cluster tolerances"));
}

// A box rotated and moved: the geometry finds its center, its extents (largest first) and
// axes along its edges.
TEST(ClusterGeometryTest, OrientedBoxOfARotatedBox) {
  PointCloud box;
  const std::vector<uint32_t> ids =
      AddBox(box, {-0.15f, -0.05f, -0.025f}, {0.15f, 0.05f, 0.025f}, 0.005f);
  const Eigen::Matrix3f rotation =
      (Eigen::AngleAxisf(0.6f, Eigen::Vector3f(1, 2, 3).normalized())).toRotationMatrix();
  const Eigen::Vector3f shift(1, -2, 0.5f);
  PointCloud moved;
  for (size_t i = 0; i < box.size(); ++i) moved.Add(rotation * box.point(i) + shift);
  const ClusterGeometry g = DescribeClusterGeometry(moved, ids);
  EXPECT_LT((g.box.center - shift).norm(), 1e-4f);
  EXPECT_NEAR(g.box.size[0], 0.30f, 1e-4f);
  EXPECT_NEAR(g.box.size[1], 0.10f, 1e-4f);
  EXPECT_NEAR(g.box.size[2], 0.05f, 1e-4f);
  for (int axis = 0; axis < 3; ++axis) {
    EXPECT_NEAR(std::fabs(g.box.axes.col(axis).dot(rotation.col(axis))), 1.0f, 1e-4f);
  }
  EXPECT_NEAR(g.box.axes.determinant(), 1.0f, 1e-5f);
}

}  // namespace
}  // namespace shapeid
