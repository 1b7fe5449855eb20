#include "core/views/perturb.h"

#include <cmath>
#include <cstring>
#include <vector>

#include "Eigen/LU"
#include "core/random.h"
#include "core/views/test_surfaces.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"

namespace shapeid {
namespace {

using ::testing::HasSubstr;

// Points from SplitMix64 only, so that the golden values below hold on every platform (the
// std:: distributions of test_surfaces.h differ between standard libraries).
PointCloud PortableCloud(size_t n, uint64_t seed) {
  SplitMix64 rng(seed);
  PointCloud cloud;
  for (size_t i = 0; i < n; ++i) {
    const double x = rng.Uniform(), y = rng.Uniform(), z = rng.Uniform();
    cloud.Add(static_cast<float>(10 + 4 * x), static_cast<float>(-3 + 2 * y),
              static_cast<float>(7 + z));
  }
  return cloud;
}

uint64_t Fingerprint(const PointCloud& cloud) {
  uint64_t hash = 0xcbf29ce484222325ull;
  for (float f : cloud.xyz()) {
    uint32_t bits;
    std::memcpy(&bits, &f, sizeof bits);
    for (int b = 0; b < 4; ++b) {
      hash ^= (bits >> (8 * b)) & 0xffu;
      hash *= 0x100000001b3ull;
    }
  }
  return hash;
}

bool SameBits(const PointCloud& a, const PointCloud& b) {
  return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * 3 * sizeof(float)) == 0;
}

double Distance(const PointCloud& c, size_t i, size_t j) {
  return (c.point(i).cast<double>() - c.point(j).cast<double>()).norm();
}

// True when `sub` is `cloud`'s points at increasing indices.
bool IsOrderedSubset(const PointCloud& sub, const PointCloud& cloud) {
  size_t i = 0;
  for (size_t j = 0; j < sub.size(); ++j) {
    while (i < cloud.size() && !(cloud.point(i) == sub.point(j))) ++i;
    if (i == cloud.size()) return false;
    ++i;
  }
  return true;
}

TEST(PerturbTest, DeriveSeedDependsOnBaseAndKey) {
  EXPECT_EQ(DeriveSeed(7, "chair/test/chair_0890.pcd"), DeriveSeed(7, "chair/test/chair_0890.pcd"));
  EXPECT_NE(DeriveSeed(7, "chair/test/chair_0890.pcd"), DeriveSeed(7, "chair/test/chair_0891.pcd"));
  EXPECT_NE(DeriveSeed(7, "chair/test/chair_0890.pcd"), DeriveSeed(8, "chair/test/chair_0890.pcd"));
  EXPECT_NE(DeriveSeed(0, ""), 0u);
}

TEST(PerturbTest, ExtentIsTheBoxDiagonalAndCentroidTheMean) {
  const PointCloud cloud{{0, 0, 0}, {3, 0, 0}, {0, 4, 0}, {0, 0, 12}};
  EXPECT_DOUBLE_EQ(CloudExtent(cloud), 13.0);
  EXPECT_TRUE(CloudCentroid(cloud).isApprox(Eigen::Vector3d(0.75, 1, 3)));
  EXPECT_EQ(CloudExtent(PointCloud()), 0.0);
}

TEST(PerturbTest, RotationMatricesAreProperRotations) {
  SplitMix64 rng(3);
  for (int i = 0; i < 100; ++i) {
    for (const Eigen::Matrix3d& r :
         {RandomRotationMatrix(rng), RandomYawMatrix(Eigen::Vector3d(1, 2, 3), rng)}) {
      EXPECT_TRUE((r * r.transpose()).isApprox(Eigen::Matrix3d::Identity(), 1e-14));
      EXPECT_NEAR(r.determinant(), 1.0, 1e-14);
    }
  }
}

TEST(PerturbTest, RandomRotationsAreSpreadUniformly) {
  // The image of a fixed axis under a Haar-random rotation is uniform on the sphere: each
  // coordinate has mean 0 and mean square 1/3, and half of them point up.
  SplitMix64 rng(11);
  const int n = 20000;
  double sum = 0, sum_sq = 0;
  int up = 0;
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector3d v = RandomRotationMatrix(rng) * Eigen::Vector3d::UnitX();
    sum += v.z();
    sum_sq += v.z() * v.z();
    up += v.z() > 0;
  }
  EXPECT_NEAR(sum / n, 0.0, 0.02);
  EXPECT_NEAR(sum_sq / n, 1.0 / 3, 0.01);
  EXPECT_NEAR(static_cast<double>(up) / n, 0.5, 0.02);
}

TEST(PerturbTest, RotationKeepsDistancesAndCentroid) {
  const PointCloud cloud = PortableCloud(500, 1);
  const PointCloud rotated = RandomRotation(cloud, 42);
  ASSERT_EQ(rotated.size(), cloud.size());
  EXPECT_TRUE(CloudCentroid(rotated).isApprox(CloudCentroid(cloud), 1e-6));
  for (size_t i = 0; i + 7 < cloud.size(); i += 7) {
    EXPECT_NEAR(Distance(rotated, i, i + 7), Distance(cloud, i, i + 7), 1e-5);
  }
  EXPECT_FALSE(SameBits(rotated, cloud));
}

TEST(PerturbTest, YawKeepsTheUpCoordinateAndDistances) {
  const PointCloud cloud = PortableCloud(500, 2);
  for (const Eigen::Vector3d& up : {Eigen::Vector3d(0, 0, 1), Eigen::Vector3d(1, -2, 0.5)}) {
    const auto yawed = RandomYaw(cloud, up, 5);
    ASSERT_TRUE(yawed.ok()) << yawed.status();
    const Eigen::Vector3d u = up.normalized();
    for (size_t i = 0; i < cloud.size(); ++i) {
      EXPECT_NEAR(yawed->point(i).cast<double>().dot(u), cloud.point(i).cast<double>().dot(u),
                  2e-5);
    }
    for (size_t i = 0; i + 3 < cloud.size(); i += 3) {
      EXPECT_NEAR(Distance(*yawed, i, i + 3), Distance(cloud, i, i + 3), 1e-5);
    }
    EXPECT_TRUE(CloudCentroid(*yawed).isApprox(CloudCentroid(cloud), 1e-6));
  }
  // The angle is uniform: cos has mean 0 and mean square 1/2 over many seeds.
  double sum = 0, sum_sq = 0;
  const int n = 20000;
  SplitMix64 rng(9);
  for (int i = 0; i < n; ++i) {
    const double c = RandomYawMatrix(Eigen::Vector3d::UnitZ(), rng)(0, 0);
    sum += c;
    sum_sq += c * c;
  }
  EXPECT_NEAR(sum / n, 0.0, 0.02);
  EXPECT_NEAR(sum_sq / n, 0.5, 0.01);
  EXPECT_THAT(RandomYaw(cloud, Eigen::Vector3d::Zero(), 1).status().message(),
              HasSubstr("non-zero"));
}

TEST(PerturbTest, NoiseHasTheAskedSigma) {
  const PointCloud cloud = PortableCloud(20000, 3);
  const double extent = CloudExtent(cloud);
  for (double fraction : {0.01, 0.03}) {
    const auto noisy = AddGaussianNoise(cloud, fraction, 4);
    ASSERT_TRUE(noisy.ok()) << noisy.status();
    ASSERT_EQ(noisy->size(), cloud.size());
    double sum = 0, sum_sq = 0;
    for (size_t i = 0; i < 3 * cloud.size(); ++i) {
      const double d = static_cast<double>(noisy->xyz()[i]) - cloud.xyz()[i];
      sum += d;
      sum_sq += d * d;
    }
    const double n = 3.0 * cloud.size();
    const double sigma = fraction * extent;
    EXPECT_NEAR(sum / n, 0.0, 0.02 * sigma);
    EXPECT_NEAR(std::sqrt(sum_sq / n), sigma, 0.02 * sigma);
  }
  EXPECT_TRUE(SameBits(*AddGaussianNoise(cloud, 0, 4), cloud));
  EXPECT_FALSE(AddGaussianNoise(cloud, -0.01, 4).ok());
  EXPECT_FALSE(AddGaussianNoise(cloud, std::nan(""), 4).ok());
}

TEST(PerturbTest, SubsampleKeepsNPointsInInputOrder) {
  const PointCloud cloud = PortableCloud(1024, 5);
  const PointCloud sub = RandomSubsample(cloud, 256, 6);
  EXPECT_EQ(sub.size(), 256u);
  EXPECT_TRUE(IsOrderedSubset(sub, cloud));
  EXPECT_TRUE(SameBits(RandomSubsample(cloud, 1024, 6), cloud));
  EXPECT_TRUE(SameBits(RandomSubsample(cloud, 5000, 6), cloud));
  EXPECT_EQ(RandomSubsample(cloud, 0, 6).size(), 0u);
}

TEST(PerturbTest, SubsampleIsUniform) {
  // Each of 10 points is kept 3 times in 10 over many seeds.
  PointCloud cloud;
  for (int i = 0; i < 10; ++i) cloud.Add(static_cast<float>(i), 0, 0);
  std::vector<int> kept(10, 0);
  const int runs = 20000;
  for (int s = 0; s < runs; ++s) {
    const PointCloud sub = RandomSubsample(cloud, 3, static_cast<uint64_t>(s));
    ASSERT_EQ(sub.size(), 3u);
    for (size_t j = 0; j < sub.size(); ++j) ++kept[static_cast<size_t>(sub.point(j).x())];
  }
  for (int k : kept) EXPECT_NEAR(static_cast<double>(k) / runs, 0.3, 0.015);
}

TEST(PerturbTest, PartialViewOfASphereIsTheCapFacingTheCamera) {
  const PointCloud sphere = test_surfaces::SphereSurface(4000, 1);
  PartialViewOptions options;
  for (uint64_t seed = 0; seed < 8; ++seed) {
    const auto view = PartialView(sphere, options, seed);
    ASSERT_TRUE(view.ok()) << view.status();
    ASSERT_FALSE(view->empty());
    EXPECT_TRUE(IsOrderedSubset(*view, sphere));
    const Eigen::Vector3d direction = *RandomViewDirection(options, seed);
    // The camera is 3 sqrt 3 radii away: it sees the cap above 1 / (3 sqrt 3) = 0.19, give
    // or take the simulator's edge band of a few sample spacings (0.056 here) at the rim.
    size_t beyond_rim = 0;
    for (size_t i = 0; i < view->size(); ++i) {
      const double height = view->point(i).cast<double>().dot(direction);
      ASSERT_GT(height, 0.19 - 3 * 0.056);
      beyond_rim += height < 0.19 - 0.02;
    }
    EXPECT_LT(static_cast<double>(beyond_rim), 0.05 * view->size());
    // That cap is 40 % of the sphere; the rim, beyond 76 degrees from the rays, is lost.
    const double kept = static_cast<double>(view->size()) / sphere.size();
    EXPECT_GT(kept, 0.25);
    EXPECT_LT(kept, 0.42);
  }
}

TEST(PerturbTest, PlaneCutKeepsOneSideOfAPlaneNearTheCentroid) {
  const PointCloud sphere = test_surfaces::SphereSurface(4000, 1);
  PartialViewOptions options;
  for (uint64_t seed = 0; seed < 16; ++seed) {
    const auto cut = PlaneCutView(sphere, options, 0.3, seed);
    ASSERT_TRUE(cut.ok()) << cut.status();
    EXPECT_TRUE(IsOrderedSubset(*cut, sphere));
    // Some unit normal n and offset t in [-0.3, 0.3] half diagonals (sqrt 3 for the unit
    // sphere's box) split the sphere: everything kept lies on one side, so the cap's share of
    // the area, (1 - t) / 2, lies in [0.24, 0.76] give or take sampling.
    const double kept = static_cast<double>(cut->size()) / sphere.size();
    EXPECT_GT(kept, 0.2);
    EXPECT_LT(kept, 0.8);
    // The kept points' mean leans away from the center, towards the camera's side.
    EXPECT_GT(CloudCentroid(*cut).norm(), 0.2);
  }
  const auto whole = PlaneCutView(sphere, options, 0.0, 3);
  ASSERT_TRUE(whole.ok());
  EXPECT_NEAR(static_cast<double>(whole->size()) / sphere.size(), 0.5, 0.05);  // through center
  EXPECT_THAT(PlaneCutView(sphere, options, 1.5, 1).status().message(), HasSubstr("[0, 1]"));
  EXPECT_FALSE(PlaneCutView(PointCloud(), options, 0.3, 1).ok());
  // A single repeated point: the plane through the centroid keeps it.
  const auto one = PlaneCutView(PointCloud{{1, 2, 3}, {1, 2, 3}}, options, 0.3, 5);
  ASSERT_TRUE(one.ok());
  EXPECT_EQ(one->size(), 2u);
}

TEST(PerturbTest, OccludedViewRemovesABandOfTheCamerasView) {
  const PointCloud sphere = test_surfaces::SphereSurface(4000, 1);
  PartialViewOptions options;
  for (uint64_t seed = 0; seed < 8; ++seed) {
    const auto seen = OccludedView(sphere, options, seed);
    ASSERT_TRUE(seen.ok()) << seen.status();
    // The first seed of OccludedView's generator is the camera's.
    SplitMix64 rng(seed);
    const auto camera = PartialView(sphere, options, rng.Next());
    ASSERT_TRUE(camera.ok());
    EXPECT_TRUE(IsOrderedSubset(*seen, *camera));
    // A band of 10-30 % of the view's width is gone: between 5 and 40 % of its points.
    const double kept = static_cast<double>(seen->size()) / camera->size();
    EXPECT_GT(kept, 0.6) << seed;
    EXPECT_LT(kept, 0.95) << seed;
  }
}

TEST(PerturbTest, SensorViewTakesItsVisibilityModel) {
  const PointCloud box = test_surfaces::BoxSurface({0, 0, 0}, {1, 0.5, 2}, 3000, 1);
  SensorViewOptions options;
  options.noise_fraction = 0;
  options.random_pose = false;
  options.min_points = options.max_points = 100000;  // keep all
  SplitMix64 rng(9);
  const uint64_t view_seed = rng.Next();
  options.visibility = Visibility::kPlaneCut;
  const auto cut = SensorView(box, options, 9);
  const auto direct = PlaneCutView(box, options.view, 0.3, view_seed);
  ASSERT_TRUE(cut.ok() && direct.ok());
  EXPECT_TRUE(SameBits(*cut, *direct));
  options.visibility = Visibility::kOccludedCamera;
  const auto occluded = SensorView(box, options, 9);
  const auto direct_occluded = OccludedView(box, options.view, view_seed);
  ASSERT_TRUE(occluded.ok() && direct_occluded.ok());
  EXPECT_TRUE(SameBits(*occluded, *direct_occluded));
}

TEST(PerturbTest, ViewDirectionsStayInTheirBand) {
  PartialViewOptions options;
  options.up = {0, 2, 0};
  options.min_up = 0.2;
  options.max_up = 0.8;
  double sum_x = 0;
  for (uint64_t seed = 0; seed < 2000; ++seed) {
    const auto d = RandomViewDirection(options, seed);
    ASSERT_TRUE(d.ok());
    EXPECT_NEAR(d->norm(), 1.0, 1e-12);
    EXPECT_GE(d->y(), 0.2 - 1e-12);
    EXPECT_LE(d->y(), 0.8 + 1e-12);
    sum_x += d->x();
  }
  EXPECT_NEAR(sum_x / 2000, 0.0, 0.05);  // azimuth uniform
  options.min_up = 0.9;
  EXPECT_THAT(RandomViewDirection(options, 1).status().message(), HasSubstr("-1 <= min"));
  options = PartialViewOptions();
  options.distance = 1;
  EXPECT_FALSE(PartialView(test_surfaces::SphereSurface(100, 1), options, 1).ok());
  EXPECT_FALSE(PartialView(PointCloud{{0, 0, 0}, {1, 1, 1}}, PartialViewOptions(), 1).ok());
}

TEST(PerturbTest, ParsesNamesToCanonicalForms) {
  for (const auto& [text, name] :
       std::vector<std::pair<std::string, std::string>>{{"clean", "clean"},
                                                        {"none", "clean"},
                                                        {" YAW ", "yaw"},
                                                        {"rot3d", "rot3d"},
                                                        {"noise1", "noise1"},
                                                        {"noise3", "noise3"},
                                                        {"noise0.5", "noise0.5"},
                                                        {"sub256", "sub256"},
                                                        {"partial", "partial"},
                                                        {"Robot", "robot"}}) {
    const auto p = ParsePerturbation(text);
    ASSERT_TRUE(p.ok()) << text << ": " << p.status();
    EXPECT_EQ(p->name, name);
  }
  EXPECT_DOUBLE_EQ(ParsePerturbation("noise3")->noise_fraction, 0.03);
  EXPECT_EQ(ParsePerturbation("sub128")->points, 128u);
  for (const char* bad : {"", "noise", "noise0", "noise-1", "sub", "sub0", "subx", "twist"}) {
    EXPECT_THAT(ParsePerturbation(bad).status().message(), HasSubstr("known:")) << bad;
  }
}

TEST(PerturbTest, SameSeedSameBitsDifferentSeedDifferent) {
  const PointCloud cloud = test_surfaces::BoxSurface({1, 2, 3}, {1, 0.5, 2}, 3000, 7);
  for (const char* name : {"yaw", "rot3d", "noise1", "sub256", "partial", "robot"}) {
    const Perturbation p = *ParsePerturbation(name);
    const auto a = ApplyPerturbation(cloud, p, 100);
    const auto b = ApplyPerturbation(cloud, p, 100);
    const auto c = ApplyPerturbation(cloud, p, 101);
    ASSERT_TRUE(a.ok() && b.ok() && c.ok()) << name;
    EXPECT_TRUE(SameBits(*a, *b)) << name;
    EXPECT_FALSE(SameBits(*a, *c)) << name;
  }
  EXPECT_TRUE(SameBits(*ApplyPerturbation(cloud, *ParsePerturbation("clean"), 1), cloud));
}

TEST(PerturbTest, SensorViewIsOneSparseNoisySideInAnyPose) {
  const PointCloud sphere = test_surfaces::SphereSurface(4000, 3);
  SensorViewOptions options;  // 1 % noise, 300-500 points, random pose
  SensorViewOptions upright = options;
  upright.random_pose = false;
  std::vector<size_t> sizes;
  for (uint64_t seed = 1; seed <= 20; ++seed) {
    const auto view = SensorView(sphere, upright, seed);
    ASSERT_TRUE(view.ok()) << view.status();
    ASSERT_GE(view->size(), 300u);
    ASSERT_LE(view->size(), 500u);
    sizes.push_back(view->size());
    // One side: the visible cap's centroid is well off the sphere's center, and the points
    // stay near the surface (sigma = 1 % of the extent 2 sqrt 3, so 5 sigma = 0.17).
    EXPECT_GT(CloudCentroid(*view).norm(), 0.3);
    for (size_t i = 0; i < view->size(); ++i) {
      EXPECT_NEAR(view->point(i).cast<double>().norm(), 1.0, 0.18);
    }
    // The random pose turns that same view: same points, same pairwise distances.
    const auto posed = SensorView(sphere, options, seed);
    ASSERT_TRUE(posed.ok());
    ASSERT_EQ(posed->size(), view->size());
    EXPECT_NEAR(Distance(*posed, 0, view->size() - 1), Distance(*view, 0, view->size() - 1), 1e-5);
    EXPECT_GT((posed->point(0) - view->point(0)).norm(), 1e-3);
  }
  // The counts spread over the range rather than sitting at one end.
  EXPECT_LT(*std::min_element(sizes.begin(), sizes.end()), 380u);
  EXPECT_GT(*std::max_element(sizes.begin(), sizes.end()), 420u);

  // Without noise, subsampling or a pose the view is PartialView's, exactly.
  SensorViewOptions plain;
  plain.noise_fraction = 0;
  plain.min_points = plain.max_points = 1'000'000;
  plain.random_pose = false;
  const PointCloud view = *SensorView(sphere, plain, 5);
  const PointCloud cap = *PartialView(sphere, plain.view, [] {
    SplitMix64 rng(5);
    return rng.Next();  // SensorView's first draw is the viewpoint's seed
  }());
  EXPECT_TRUE(SameBits(view, cap));

  SensorViewOptions bad;
  bad.min_points = 10;
  bad.max_points = 5;
  EXPECT_THAT(SensorView(sphere, bad, 1).status().message(), HasSubstr("min <= max"));
  bad = SensorViewOptions();
  bad.noise_fraction = -1;
  EXPECT_THAT(SensorView(sphere, bad, 1).status().message(), HasSubstr("noise"));
}

TEST(PerturbTest, GoldenBitsHoldOnEveryPlatform) {
  // Only SplitMix64 and IEEE-exact arithmetic feed these: a change here is a change of the
  // perturbations (and of every robustness figure made with them), not a platform quirk.
  const PointCloud cloud = PortableCloud(300, 12);
  const auto fingerprint = [&](const char* name) {
    return Fingerprint(*ApplyPerturbation(cloud, *ParsePerturbation(name), 1));
  };
  EXPECT_EQ(fingerprint("yaw"), 0x5b96b90c090d7d50u);
  EXPECT_EQ(fingerprint("rot3d"), 0xe73ff52fb0d74d45u);
  EXPECT_EQ(fingerprint("noise3"), 0x9503ffdbcf47bd67u);
  EXPECT_EQ(fingerprint("sub128"), 0x755e306c0bc75588u);
}

}  // namespace
}  // namespace shapeid
