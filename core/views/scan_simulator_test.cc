#include "core/views/scan_simulator.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <set>
#include <tuple>
#include <vector>

#include "Eigen/Geometry"
#include "core/views/test_surfaces.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"

namespace shapeid {
namespace {

using test_surfaces::BoxSurface;
using test_surfaces::SphereSurface;
using ::testing::HasSubstr;

constexpr double kPi = 3.14159265358979323846;

ScanOptions Exact() {
  ScanOptions options;
  options.depth_noise = 0;
  return options;
}

// Where ScanOptions puts the camera for `surface`.
Eigen::Vector3d Eye(const PointCloud& surface, const ScanOptions& options) {
  const CloudStats stats = *ValidateCloud(surface);
  return 0.5 * (stats.min + stats.max) +
         options.distance * 0.5 * (stats.max - stats.min).norm() * options.direction.normalized();
}

PointCloud Join(const PointCloud& a, const PointCloud& b) {
  PointCloud joined = a;
  joined.Append(b.xyz());
  return joined;
}

using Triple = std::tuple<float, float, float>;
std::set<Triple> PointSet(const PointCloud& cloud) {
  std::set<Triple> set;
  for (size_t i = 0; i < cloud.size(); ++i) {
    set.emplace(cloud.point(i).x(), cloud.point(i).y(), cloud.point(i).z());
  }
  return set;
}

TEST(ScanSimulatorTest, ASphereShowsOnlyTheCapFacingTheCamera) {
  const PointCloud sphere = SphereSurface(50000, 1);
  const ScanOptions options = Exact();  // from +z, 160 x 120, 45 degrees, distance 3
  const auto scan = SimulateScan(sphere, options);
  ASSERT_TRUE(scan.ok()) << scan.status();
  const Eigen::Vector3d eye = Eye(sphere, options);
  double widest = 0;
  for (size_t i = 0; i < scan->size(); ++i) {
    const Eigen::Vector3d p = scan->point(i).cast<double>();
    // Seen points face the camera: on a unit sphere the normal is p.
    ASSERT_GT(p.dot(eye - p), -1e-6) << "hidden point (" << p.transpose() << ")";
    widest = std::max(widest, std::hypot(p.x(), p.y()));
  }
  // The camera is 3 radii of the bounding box (3 sqrt 3) from the center, so the visible cap
  // reaches z = 1 / (3 sqrt 3) and images as a disc of focal * tan(asin(1 / (3 sqrt 3)))
  // pixels; each pixel of it shows one point (50,000 points leave ~2.5 per pixel of the
  // cap) save a few where the rim turns beyond 76 degrees.
  const double focal = 60 / std::tan(22.5 * kPi / 180);
  const double disc = kPi * std::pow(focal * std::tan(std::asin(1 / (3 * std::sqrt(3.0)))), 2);
  EXPECT_GT(static_cast<double>(scan->size()), 0.9 * disc);
  EXPECT_LT(static_cast<double>(scan->size()), 1.05 * disc);
  EXPECT_GT(widest, 0.93);  // near the rim (radius 0.98), where the surface turns away
}

TEST(ScanSimulatorTest, ACubeSeenAlongXHidesItsFarFaces) {
  // 60,000 points: a sample spacing of 0.02.
  const PointCloud cube = BoxSurface({0, 0, 0}, {1, 1, 1}, 60000, 2);
  ScanOptions options = Exact();
  options.direction = {1, 0, 0};
  const auto scan = SimulateScan(cube, options);
  ASSERT_TRUE(scan.ok()) << scan.status();
  size_t front = 0;
  for (size_t i = 0; i < scan->size(); ++i) {
    const auto p = scan->point(i);
    // The -x face, and all but a rim of the four side faces (seen edge on, from inside),
    // are hidden behind the +x face. The rim is the few spacings behind an occluding edge
    // that the cone test lets through.
    ASSERT_GT(p.x(), 0.85f) << "hidden point (" << p.transpose() << ")";
    front += p.x() == 1.0f;
  }
  EXPECT_GT(front, 0.95 * static_cast<double>(scan->size()));
  EXPECT_GT(scan->size(), 3000u);
}

TEST(ScanSimulatorTest, ACubeSeenCornerOnShowsThreeFaces) {
  const PointCloud cube = BoxSurface({0, 0, 0}, {1, 1, 1}, 60000, 3);
  ScanOptions options = Exact();
  options.direction = {1, 1, 1};
  const auto scan = SimulateScan(cube, options);
  ASSERT_TRUE(scan.ok()) << scan.status();
  size_t per_face[3] = {0, 0, 0};
  for (size_t i = 0; i < scan->size(); ++i) {
    const auto p = scan->point(i);
    // A point of the -x, -y or -z face may show only beside an edge it shares with a front
    // face, where a front coordinate is near 1.
    ASSERT_GT(p.maxCoeff(), 0.85f) << "hidden point (" << p.transpose() << ")";
    for (int axis = 0; axis < 3; ++axis) per_face[axis] += p[axis] == 1.0f;
  }
  // The three front faces, equally tilted, show about equally.
  for (size_t count : per_face) EXPECT_NEAR(count, scan->size() / 3.0, 0.05 * scan->size());
}

// Is the segment from `from` to `to` through the box center +- half?
bool SegmentHitsBox(const Eigen::Vector3d& from, const Eigen::Vector3d& to,
                    const Eigen::Vector3d& center, const Eigen::Vector3d& half) {
  double enter = 0, leave = 1;
  for (int a = 0; a < 3; ++a) {
    const double d = to[a] - from[a];
    const double lo = center[a] - half[a] - from[a], hi = center[a] + half[a] - from[a];
    if (d == 0) {
      if (lo > 0 || hi < 0) return false;
      continue;
    }
    enter = std::max(enter, std::min(lo / d, hi / d));
    leave = std::min(leave, std::max(lo / d, hi / d));
  }
  return enter <= leave;
}

TEST(ScanSimulatorTest, ASmallBoxInFrontHidesPartOfALargerOne) {
  // A 4 x 4 x 0.5 slab and, above it on the camera's side, a 0.8 cube; the same density on
  // both (areas 40 and 3.84).
  const Eigen::Vector3d occluder(0, 0, 1.5), occluder_half(0.4, 0.4, 0.4);
  const PointCloud slab = BoxSurface({0, 0, 0}, {2, 2, 0.25f}, 80000, 4);
  const PointCloud both =
      Join(slab, BoxSurface(occluder.cast<float>(), occluder_half.cast<float>(), 7680, 5));
  const ScanOptions options = Exact();  // from +z
  const Eigen::Vector3d eye = Eye(both, options);
  // A point of the slab's top is hidden when its ray to the camera crosses the cube; allow
  // one sample spacing (0.022) around the shadow's edge.
  const auto in_shadow = [&](const Eigen::Vector3d& p, double margin) {
    return std::abs(p.z() - 0.25) < 1e-6 &&
           SegmentHitsBox(p, eye, occluder, occluder_half - Eigen::Vector3d::Constant(margin));
  };
  const auto scan = SimulateScan(both, options);
  ASSERT_TRUE(scan.ok()) << scan.status();
  size_t slab_top = 0, cube_top = 0;
  for (size_t i = 0; i < scan->size(); ++i) {
    const Eigen::Vector3d p = scan->point(i).cast<double>();
    ASSERT_FALSE(in_shadow(p, 0.022)) << "hidden point (" << p.transpose() << ")";
    slab_top += std::abs(p.z() - 0.25) < 1e-6;
    cube_top += std::abs(p.z() - 1.9) < 1e-6;
  }
  EXPECT_GT(slab_top, 2000u);
  EXPECT_GT(cube_top, 100u);
  // Without the cube, the shadow is seen: the test above is not empty.
  const auto bare = SimulateScan(slab, options);
  ASSERT_TRUE(bare.ok()) << bare.status();
  size_t would_show = 0;
  for (size_t i = 0; i < bare->size(); ++i) {
    would_show += in_shadow(bare->point(i).cast<double>(), 0.022);
  }
  EXPECT_GT(would_show, 100u);
}

TEST(ScanSimulatorTest, WithoutNoiseEveryPointIsAnInputPointAndAppearsOnce) {
  const PointCloud sphere = SphereSurface(30000, 6);
  ScanOptions options = Exact();
  options.direction = {0.3, -1, 0.2};
  options.width = 320;
  options.height = 240;
  const auto scan = SimulateScan(sphere, options);
  ASSERT_TRUE(scan.ok()) << scan.status();
  const std::set<Triple> input = PointSet(sphere);
  for (size_t i = 0; i < scan->size(); ++i) {
    ASSERT_TRUE(input.count({scan->point(i).x(), scan->point(i).y(), scan->point(i).z()}));
  }
  EXPECT_EQ(PointSet(*scan).size(), scan->size());
}

TEST(ScanSimulatorTest, TheSameSeedGivesTheSameBitsAndAnotherSeedOtherNoise) {
  const PointCloud sphere = SphereSurface(30000, 7);
  ScanOptions options;
  options.seed = 11;
  const auto a = SimulateScan(sphere, options);
  const auto b = SimulateScan(sphere, options);
  options.seed = 12;
  const auto c = SimulateScan(sphere, options);
  ASSERT_TRUE(a.ok() && b.ok() && c.ok());
  EXPECT_EQ(a->xyz(), b->xyz());
  ASSERT_EQ(a->size(), c->size());  // the same pixels see the same points
  EXPECT_NE(a->xyz(), c->xyz());
  // Without noise or subset the seed plays no part.
  options.depth_noise = 0;
  const auto d = SimulateScan(sphere, options);
  options.seed = 11;
  const auto e = SimulateScan(sphere, options);
  ASSERT_TRUE(d.ok() && e.ok());
  EXPECT_EQ(d->xyz(), e->xyz());
}

TEST(ScanSimulatorTest, NoiseMovesPointsAlongTheirRaysWithTheGivenSpread) {
  const PointCloud sphere = SphereSurface(50000, 8);
  ScanOptions options = Exact();
  options.direction = {1, 2, -1};
  options.width = 320;
  options.height = 240;
  const auto exact = SimulateScan(sphere, options);
  options.depth_noise = 0.01;  // in radii: sqrt 3 here
  const auto noisy = SimulateScan(sphere, options);
  ASSERT_TRUE(exact.ok() && noisy.ok());
  ASSERT_EQ(exact->size(), noisy->size());
  const Eigen::Vector3d eye = Eye(sphere, options);
  double sum = 0, sum2 = 0;
  for (size_t i = 0; i < exact->size(); ++i) {
    const Eigen::Vector3d p = exact->point(i).cast<double>();
    const Eigen::Vector3d shift = noisy->point(i).cast<double>() - p;
    const Eigen::Vector3d ray = (p - eye).normalized();
    ASSERT_LT(shift.cross(ray).norm(), 1e-5) << "point " << i << " moved off its ray";
    const double along = shift.dot(ray);
    sum += along;
    sum2 += along * along;
  }
  const double n = static_cast<double>(exact->size());
  const double sigma = 0.01 * std::sqrt(3.0);
  EXPECT_NEAR(sum / n, 0, 4 * sigma / std::sqrt(n));
  EXPECT_NEAR(std::sqrt(sum2 / n), sigma, 0.05 * sigma);
}

TEST(ScanSimulatorTest, MaxPointsKeepsAnOrderedSubsetOfTheFullScan) {
  const PointCloud sphere = SphereSurface(30000, 9);
  ScanOptions options;
  options.seed = 3;
  const auto full = SimulateScan(sphere, options);
  ASSERT_TRUE(full.ok());
  ASSERT_GT(full->size(), 1000u);
  options.max_points = 500;
  const auto part = SimulateScan(sphere, options);
  ASSERT_TRUE(part.ok());
  ASSERT_EQ(part->size(), 500u);
  // Every kept point, noise and all, is in the full scan, in the same order.
  size_t j = 0;
  for (size_t i = 0; i < part->size(); ++i) {
    while (j < full->size() && full->point(j) != part->point(i)) ++j;
    ASSERT_LT(j, full->size()) << "kept point " << i << " is not in the full scan, in order";
  }
  // Spread over the whole scan (rows top to bottom: +y to -y), not its first rows.
  EXPECT_GT(part->point(0).y(), 0.5f);
  EXPECT_LT(part->point(499).y(), -0.5f);
  options.seed = 4;
  const auto other = SimulateScan(sphere, options);
  ASSERT_TRUE(other.ok());
  EXPECT_NE(part->xyz(), other->xyz());
  options.max_points = full->size() + 1;
  options.seed = 3;
  const auto all = SimulateScan(sphere, options);
  ASSERT_TRUE(all.ok());
  EXPECT_EQ(all->xyz(), full->xyz());
}

TEST(ScanSimulatorTest, TheObjectStaysWholeInViewWithANarrowLensOrANearCamera) {
  const PointCloud sphere = SphereSurface(50000, 10);
  const auto widest = [](const PointCloud& scan) {
    double w = 0;
    for (size_t i = 0; i < scan.size(); ++i) {
      w = std::max(w, std::hypot(double{scan.point(i).x()}, double{scan.point(i).y()}));
    }
    return w;
  };
  // A lens too narrow for the object (5 degrees at distance 3, or 45 at distance 1.05, where
  // the box needs 120) is widened to fit it: the scan reaches as far out on the cap as with
  // a lens wide enough (150 degrees), and with at least as many pixels on the object.
  for (const auto& [fov, distance] : {std::pair{5.0, 3.0}, std::pair{45.0, 1.05}}) {
    ScanOptions options = Exact();
    options.distance = distance;
    options.fov_degrees = 150;
    const auto wide = SimulateScan(sphere, options);
    options.fov_degrees = fov;
    const auto narrow = SimulateScan(sphere, options);
    ASSERT_TRUE(wide.ok() && narrow.ok());
    EXPECT_GT(widest(*narrow), 0.97 * widest(*wide)) << fov << " " << distance;
    EXPECT_GT(narrow->size(), wide->size()) << fov << " " << distance;
  }
}

TEST(ScanSimulatorTest, AFarCameraWithALongLensSeesAHemisphere) {
  const PointCloud sphere = SphereSurface(50000, 14);
  ScanOptions options = Exact();
  options.distance = 1e5;
  options.fov_degrees = 0.002;  // the box spans about 0.0007 degrees: it fits
  const auto scan = SimulateScan(sphere, options);
  ASSERT_TRUE(scan.ok()) << scan.status();
  for (size_t i = 0; i < scan->size(); ++i) {
    ASSERT_GT(scan->point(i).z(), -1e-3f) << "hidden point (" << scan->point(i).transpose() << ")";
  }
  // Nearly orthographic: the unit sphere images as a disc of radius focal / range.
  const double focal = 60 / std::tan(0.001 * kPi / 180);
  const double disc = kPi * std::pow(focal / (1e5 * std::sqrt(3.0)), 2);
  EXPECT_GT(static_cast<double>(scan->size()), 0.85 * disc);
  EXPECT_LT(static_cast<double>(scan->size()), 1.05 * disc);
}

TEST(ScanSimulatorTest, ScansScaleWithTheSurfaceBitForBit) {
  const PointCloud sphere = SphereSurface(20000, 11);
  PointCloud doubled = sphere;
  for (float& c : doubled.mutable_xyz()) c *= 2;
  ScanOptions options;
  options.direction = {-1, 0.5, 0.25};
  options.seed = 5;
  const auto scan = SimulateScan(sphere, options);
  const auto scan2 = SimulateScan(doubled, options);
  ASSERT_TRUE(scan.ok() && scan2.ok());
  ASSERT_EQ(scan->size(), scan2->size());
  for (size_t i = 0; i < scan->size(); ++i) {
    ASSERT_EQ(scan2->point(i), 2 * scan->point(i)) << i;
  }
}

TEST(ScanSimulatorTest, ASimulatorGivesTheSameScansAsOneOffCalls) {
  const PointCloud cube = BoxSurface({1, 2, 3}, {0.5f, 1, 2}, 30000, 12);
  auto simulator = ScanSimulator::Create(cube);
  ASSERT_TRUE(simulator.ok()) << simulator.status();
  EXPECT_EQ(simulator->surface().size(), cube.size());
  EXPECT_GT(simulator->sample_spacing(), 0);
  for (const Eigen::Vector3d& direction :
       {Eigen::Vector3d(0, 0, 1), Eigen::Vector3d(1, -1, 0.5), Eigen::Vector3d(0, 1, 0.1)}) {
    ScanOptions options;
    options.direction = direction;
    options.width = direction.x() == 1 ? 640 : 160;  // buffers grow, then are reused
    options.height = direction.x() == 1 ? 480 : 120;
    const auto reused = simulator->Scan(options);
    const auto once = SimulateScan(cube, options);
    ASSERT_TRUE(reused.ok() && once.ok());
    EXPECT_EQ(reused->xyz(), once->xyz()) << direction.transpose();
  }
}

TEST(ScanSimulatorTest, ATinySurfaceStillShowsItsNearestPoint) {
  const PointCloud tiny{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  for (int width : {1, 160}) {
    ScanOptions options = Exact();
    options.width = width;
    options.height = width;
    const auto scan = SimulateScan(tiny, options);
    ASSERT_TRUE(scan.ok()) << scan.status();
    ASSERT_GE(scan->size(), 1u);
    EXPECT_LE(scan->size(), static_cast<size_t>(width) * width);
  }
}

TEST(ScanSimulatorTest, ASurfaceSampledMostlyAtOneSpotIsScannedInBoundedMemory) {
  // The sample spacing comes out tiny, which would ask for billions of buffer cells.
  PointCloud cluster = SphereSurface(2000, 15);
  for (int i = 0; i < 20000; ++i) cluster.Add(0.1f, 0.2f, 1.0f);
  ScanOptions options = Exact();
  options.width = 1024;
  options.height = 768;
  const auto scan = SimulateScan(cluster, options);
  ASSERT_TRUE(scan.ok()) << scan.status();
  EXPECT_GE(scan->size(), 1u);
  EXPECT_TRUE(PointSet(*scan).count({0.1f, 0.2f, 1.0f}));
}

TEST(ScanSimulatorTest, SurfaceIndicesNameTheSurfacePointEachOutputPointShows) {
  const PointCloud surface = Join(BoxSurface({0, 0, 0}, {1, 0.5f, 0.25f}, 20000, 3),
                                  SphereSurface(20000, 4, 0.4f, {0, 0, 0.8f}));
  ScanOptions options = Exact();
  options.direction = {0.3, -0.5, 1};
  std::vector<uint32_t> indices = {7};  // replaced, not appended to
  const auto scan = SimulateScan(surface, options, &indices);
  ASSERT_TRUE(scan.ok()) << scan.status();
  ASSERT_EQ(indices.size(), scan->size());
  ASSERT_GT(scan->size(), 1000u);
  size_t on_sphere = 0;
  for (size_t i = 0; i < scan->size(); ++i) {
    ASSERT_LT(indices[i], surface.size());
    EXPECT_EQ(scan->point(i), surface.point(indices[i])) << i;
    on_sphere += indices[i] >= 20000 ? 1 : 0;
  }
  EXPECT_GT(on_sphere, 500u);
  EXPECT_LT(on_sphere, scan->size() - 500);

  // With noise and a subset: the same bits as without asking, each point on its surface
  // point's ray from the camera, within the noise.
  options.depth_noise = 0.01;
  options.max_points = 700;
  options.seed = 11;
  auto simulator = ScanSimulator::Create(surface);
  ASSERT_TRUE(simulator.ok()) << simulator.status();
  const auto plain = simulator->Scan(options);
  const auto traced = simulator->Scan(options, &indices);
  ASSERT_TRUE(plain.ok() && traced.ok());
  EXPECT_EQ(plain->xyz(), traced->xyz());
  ASSERT_EQ(indices.size(), 700u);
  const Eigen::Vector3d eye = Eye(surface, options);
  const double radius = 0.5 * (ValidateCloud(surface)->max - ValidateCloud(surface)->min).norm();
  for (size_t i = 0; i < traced->size(); ++i) {
    const Eigen::Vector3d p = traced->point(i).cast<double>() - eye;
    const Eigen::Vector3d q = surface.point(indices[i]).cast<double>() - eye;
    EXPECT_LT(p.normalized().cross(q.normalized()).norm(), 1e-5) << i;
    EXPECT_LT(std::abs(p.norm() - q.norm()), 6 * 0.01 * radius) << i;
  }
}

TEST(ScanSimulatorTest, EveryInvalidInputIsRejectedWithItsReason) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  const PointCloud sphere = SphereSurface(1000, 13);
  struct Case {
    const char* what;
    void (*edit)(ScanOptions&);
    const char* message;
  };
  const Case cases[] = {
      {"zero direction",
       [](ScanOptions& o) {
         o.direction = {0, 0, 0};
       },
       "direction"},
      {"nan direction", [](ScanOptions& o) { o.direction.x() = NAN; }, "direction"},
      {"up parallel",
       [](ScanOptions& o) {
         o.up = {0, 0, -2};
       },
       "parallel"},
      {"zero up",
       [](ScanOptions& o) {
         o.up = {0, 0, 0};
       },
       "up vector"},
      {"distance 1", [](ScanOptions& o) { o.distance = 1; }, "distance"},
      {"distance 0.5", [](ScanOptions& o) { o.distance = 0.5; }, "distance"},
      {"distance nan", [](ScanOptions& o) { o.distance = NAN; }, "distance"},
      {"distance inf", [](ScanOptions& o) { o.distance = INFINITY; }, "distance"},
      {"distance 2e6", [](ScanOptions& o) { o.distance = 2e6; }, "distance"},
      {"width 0", [](ScanOptions& o) { o.width = 0; }, "1 to 4096"},
      {"width 4097", [](ScanOptions& o) { o.width = 4097; }, "1 to 4096"},
      {"height 0", [](ScanOptions& o) { o.height = 0; }, "1 to 4096"},
      {"height -5", [](ScanOptions& o) { o.height = -5; }, "1 to 4096"},
      {"fov 0", [](ScanOptions& o) { o.fov_degrees = 0; }, "field of view"},
      {"fov 170", [](ScanOptions& o) { o.fov_degrees = 170; }, "field of view"},
      {"fov nan", [](ScanOptions& o) { o.fov_degrees = NAN; }, "field of view"},
      {"noise -0.1", [](ScanOptions& o) { o.depth_noise = -0.1; }, "noise"},
      {"noise inf", [](ScanOptions& o) { o.depth_noise = INFINITY; }, "noise"},
  };
  auto simulator = ScanSimulator::Create(sphere);
  ASSERT_TRUE(simulator.ok());
  for (const Case& c : cases) {
    ScanOptions options;
    c.edit(options);
    for (const auto& result : {SimulateScan(sphere, options), simulator->Scan(options)}) {
      EXPECT_EQ(result.status().code(), absl::StatusCode::kInvalidArgument) << c.what;
      EXPECT_THAT(result.status().message(), HasSubstr(c.message)) << c.what;
    }
  }
  // Surfaces: empty, too few points, a non-finite coordinate, no extent.
  PointCloud with_nan = sphere;
  with_nan.mutable_xyz()[40] = static_cast<float>(nan);
  PointCloud with_inf = sphere;
  with_inf.mutable_xyz()[0] = static_cast<float>(inf);
  const PointCloud surfaces[] = {PointCloud(), PointCloud{{0, 0, 0}, {1, 1, 1}}, with_nan, with_inf,
                                 PointCloud{{1, 2, 3}, {1, 2, 3}, {1, 2, 3}}};
  for (const PointCloud& surface : surfaces) {
    const auto scan = SimulateScan(surface, ScanOptions());
    EXPECT_EQ(scan.status().code(), absl::StatusCode::kInvalidArgument) << surface.size();
    EXPECT_THAT(scan.status().message(), HasSubstr("scan surface: "));
    EXPECT_EQ(ScanSimulator::Create(surface).status(), scan.status());
  }
}

}  // namespace
}  // namespace shapeid
