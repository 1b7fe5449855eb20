#include "core/views/sample_spacing.h"

#include <cmath>

#include "core/views/test_surfaces.h"
#include "gtest/gtest.h"

namespace shapeid {
namespace {

using test_surfaces::BoxSurface;
using test_surfaces::SphereSurface;
using test_surfaces::SquareSurface;

constexpr double kPi = 3.14159265358979323846;

double Spacing(const PointCloud& cloud) {
  const auto stats = ValidateCloud(cloud);
  EXPECT_TRUE(stats.ok()) << stats.status();
  return EstimateSampleSpacing(cloud, *stats);
}

TEST(SampleSpacingTest, MatchesTheAreaPerPointOfASphere) {
  for (size_t n : {3000, 30000, 100000}) {
    const double truth = std::sqrt(4 * kPi / static_cast<double>(n));
    EXPECT_NEAR(Spacing(SphereSurface(n, 1)), truth, 0.08 * truth) << n << " points";
  }
}

TEST(SampleSpacingTest, MatchesTheAreaPerPointOfABoxWithEdgesAndCorners) {
  // 2 x 4 x 0.5: area 2 (8 + 1 + 2) = 22.
  const PointCloud box = BoxSurface({5, -3, 1}, {1, 2, 0.25f}, 60000, 2);
  const double truth = std::sqrt(22.0 / 60000);
  EXPECT_NEAR(Spacing(box), truth, 0.1 * truth);
}

TEST(SampleSpacingTest, OpenEdgesOnlyOverestimate) {
  const double truth = std::sqrt(4.0 / 40000);
  const double spacing = Spacing(SquareSurface(1, 40000, 3));
  EXPECT_GE(spacing, 0.95 * truth);
  EXPECT_LE(spacing, 1.15 * truth);
}

TEST(SampleSpacingTest, ScalesWithTheCloud) {
  PointCloud sphere = SphereSurface(20000, 4);
  const double unit = Spacing(sphere);
  for (float& c : sphere.mutable_xyz()) c *= 1000;
  EXPECT_NEAR(Spacing(sphere), 1000 * unit, 1e-3 * unit);
}

TEST(SampleSpacingTest, SparseAndDegenerateCloudsGiveAPositiveSpacing) {
  PointCloud cluster;  // one spot sampled 10,000 times, and two points elsewhere
  for (int i = 0; i < 10000; ++i) cluster.Add(1, 1, 1);
  cluster.Add(0, 0, 0);
  cluster.Add(2, 0, 0);
  const PointCloud tiny{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  for (const PointCloud& cloud : {cluster, tiny}) {
    const double spacing = Spacing(cloud);
    EXPECT_TRUE(std::isfinite(spacing)) << cloud.size();
    EXPECT_GT(spacing, 0) << cloud.size();
  }
  EXPECT_GT(Spacing(tiny), 0.3);  // three points a unit apart
}

TEST(SampleSpacingTest, LargeCloudsCountAmongEveryKthPoint) {
  // 200,000 points: neighbors are counted among every 7th; the estimate is as good.
  const double truth = std::sqrt(4 * kPi / 200000);
  EXPECT_NEAR(Spacing(SphereSurface(200000, 5)), truth, 0.08 * truth);
}

}  // namespace
}  // namespace shapeid
