#include "core/descriptors/point_smoothing.h"

#include <algorithm>
#include <cmath>
#include <random>
#include <utility>
#include <vector>

#include "Eigen/Geometry"
#include "core/testing/test_clouds.h"
#include "gtest/gtest.h"

namespace shapeid {
namespace {

using testing_clouds::SphereCloud;

// A unit square in z = 0 sampled on a jittered grid, with Gaussian noise of `sigma` in z.
PointCloud NoisySquare(int side, float sigma, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> jitter(0.0f, 1.0f / side);
  std::normal_distribution<float> noise(0.0f, sigma);
  PointCloud cloud;
  for (int i = 0; i < side; ++i) {
    for (int j = 0; j < side; ++j) {
      cloud.Add(static_cast<float>(i) / side + jitter(rng),
                static_cast<float>(j) / side + jitter(rng), noise(rng));
    }
  }
  return cloud;
}

// Root mean square z of the points at least `margin` inside the square's edges.
double InnerRmsZ(const PointCloud& cloud, float margin) {
  double sum = 0;
  size_t count = 0;
  for (size_t i = 0; i < cloud.size(); ++i) {
    const Eigen::Vector3f p = cloud.point(i);
    if (p.x() < margin || p.x() > 1 - margin || p.y() < margin || p.y() > 1 - margin) continue;
    sum += static_cast<double>(p.z()) * p.z();
    ++count;
  }
  return std::sqrt(sum / static_cast<double>(count));
}

TEST(PointSmoothingTest, DrawsANoisySurfaceBackToItsMiddle) {
  // Each point averages its 31 nearest: a disc of radius ~0.1.
  const PointCloud noisy = NoisySquare(32, 0.02f, 5);
  const PointCloud smoothed = SmoothPoints(noisy, 0.03);
  ASSERT_EQ(smoothed.size(), noisy.size());
  const double before = InnerRmsZ(noisy, 0.15f);
  EXPECT_NEAR(before, 0.02, 0.003);
  EXPECT_LT(InnerRmsZ(smoothed, 0.15f), before / 3);
  // In the plane, inner points move little (the mean of a disc around a point is near it);
  // points at the edges move inwards, by less than the disc's radius.
  for (size_t i = 0; i < noisy.size(); ++i) {
    const Eigen::Vector3f p = noisy.point(i);
    const bool inner = p.x() > 0.15f && p.x() < 0.85f && p.y() > 0.15f && p.y() < 0.85f;
    EXPECT_LT((smoothed.point(i) - p).head<2>().norm(), inner ? 0.04f : 0.15f) << i;
  }
}

// Each point's k nearest by brute force, mean in double: the definition.
PointCloud BruteForceSmoothed(const PointCloud& cloud, size_t k) {
  PointCloud out;
  std::vector<std::pair<float, size_t>> order(cloud.size());
  for (size_t i = 0; i < cloud.size(); ++i) {
    for (size_t j = 0; j < cloud.size(); ++j) {
      order[j] = {(cloud.point(j) - cloud.point(i)).squaredNorm(), j};
    }
    std::nth_element(order.begin(), order.begin() + (k - 1), order.end());
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    for (size_t c = 0; c < k; ++c) sum += cloud.point(order[c].second).cast<double>();
    out.Add((sum / static_cast<double>(k)).cast<float>());
  }
  return out;
}

TEST(PointSmoothingTest, IsTheMeanOfTheTrueNearestPoints) {
  // A sphere's surface (the grid's rings expand where a cap is sparse), a noisy square, a
  // clustered cloud whose clusters are far apart (rings run to the whole grid) and strays.
  PointCloud clusters;
  for (int c = 0; c < 5; ++c) {
    const PointCloud ball = SphereCloud(60, 20 + c);
    for (size_t i = 0; i < ball.size(); ++i) {
      clusters.Add(0.1f * ball.point(i) + Eigen::Vector3f(7.0f * c, 3.0f * (c % 2), 0));
    }
  }
  // A sphere with a few stray points far away (searched by brute force beyond the grid).
  PointCloud strays = SphereCloud(600, 8);
  strays.Add(40, 0, 0);
  strays.Add(40, 0.5f, 0);
  strays.Add(-3, -90, 7);
  for (const PointCloud& cloud :
       {SphereCloud(700, 4), NoisySquare(24, 0.02f, 6), clusters, strays}) {
    for (double share : {0.005, 0.03, 0.2}) {
      const size_t k = std::max<size_t>(
          kMinSmoothingNeighbors,
          static_cast<size_t>(std::lround(share * static_cast<double>(cloud.size()))));
      const PointCloud expected = BruteForceSmoothed(cloud, k);
      const PointCloud smoothed = SmoothPoints(cloud, share);
      ASSERT_EQ(smoothed.size(), expected.size());
      size_t differing = 0;
      for (size_t i = 0; i < cloud.size(); ++i) {
        // Only an exact tie at the k-th distance may pick another point.
        if ((smoothed.point(i) - expected.point(i)).norm() > 1e-5f) ++differing;
      }
      EXPECT_EQ(differing, 0u) << cloud.size() << " points, share " << share;
    }
  }
}

TEST(PointSmoothingTest, AnyScaleGivesTheScaledResult) {
  // Distances are taken in grid cells, so neither 1e25 (squares overflow float) nor 1e-25
  // (squares underflow) changes which points are nearest.
  const PointCloud cloud = SphereCloud(1500, 12);
  const PointCloud reference = SmoothPoints(cloud, 0.02);
  for (float scale : {1e25f, 1e-25f}) {
    PointCloud scaled;
    for (size_t i = 0; i < cloud.size(); ++i) scaled.Add(scale * cloud.point(i));
    const PointCloud smoothed = SmoothPoints(scaled, 0.02);
    size_t differing = 0;
    for (size_t i = 0; i < cloud.size(); ++i) {
      if ((smoothed.point(i) / scale - reference.point(i)).norm() > 1e-4f) ++differing;
    }
    EXPECT_LE(differing, cloud.size() / 100) << "scale " << scale;
  }
}

TEST(PointSmoothingTest, ALargeCloudIsReducedThenSmoothedAsFar) {
  // 40,000 points: kSmoothingReferencePoints of them come back, smoothed over the same share
  // of the square as the small cloud (and so more points).
  const PointCloud noisy = NoisySquare(200, 0.02f, 5);
  const PointCloud smoothed = SmoothPoints(noisy, 0.03);
  EXPECT_EQ(smoothed.size(), kSmoothingReferencePoints);
  EXPECT_LT(InnerRmsZ(smoothed, 0.15f), InnerRmsZ(noisy, 0.15f) / 4);
  EXPECT_EQ(smoothed.xyz(), SmoothPoints(noisy, 0.03).xyz());
}

TEST(PointSmoothingTest, TurnsWithTheCloud) {
  // Nearest points do not depend on the axes, so smoothing a turned cloud gives the turned
  // smoothed cloud (to rounding).
  const PointCloud cloud = SphereCloud(2000, 3);
  const Eigen::Matrix3f turn =
      Eigen::AngleAxisf(0.7f, Eigen::Vector3f(1, 2, 3).normalized()).toRotationMatrix();
  PointCloud turned;
  for (size_t i = 0; i < cloud.size(); ++i) turned.Add(turn * cloud.point(i));
  const PointCloud a = SmoothPoints(cloud, 0.02);
  const PointCloud b = SmoothPoints(turned, 0.02);
  size_t differing = 0;
  for (size_t i = 0; i < a.size(); ++i) {
    // Two neighbors at nearly equal distances may swap ranks after rounding.
    if ((turn * a.point(i) - b.point(i)).norm() > 1e-4f) ++differing;
  }
  EXPECT_LE(differing, a.size() / 100);
  // Points on a sphere move inwards, towards the center of the cap around them.
  for (size_t i = 0; i < a.size(); ++i) EXPECT_LT(a.point(i).norm(), 1.0f);
}

TEST(PointSmoothingTest, EachPointAveragesItsNearestAtLeastTheFloor) {
  // Two clusters of kMinSmoothingNeighbors points, far apart: a small share still averages
  // the floor's 8 points, which are exactly a point's own cluster.
  PointCloud cloud;
  for (size_t i = 0; i < kMinSmoothingNeighbors; ++i) {
    cloud.Add(0.01f * static_cast<float>(i), 0, 0);
    cloud.Add(10 + 0.01f * static_cast<float>(i), 0, 0);
  }
  const PointCloud smoothed = SmoothPoints(cloud, 0.01);
  for (size_t i = 0; i < cloud.size(); ++i) {
    EXPECT_FLOAT_EQ(smoothed.point(i).x(), i % 2 == 0 ? 0.035f : 10.035f) << i;
  }
  // Fewer points than the floor: every point goes to the centroid.
  const PointCloud three = {{0, 0, 0}, {3, 0, 0}, {0, 3, 0}};
  const PointCloud centroid = SmoothPoints(three, 0.01);
  for (size_t i = 0; i < 3; ++i) EXPECT_EQ(centroid.point(i), Eigen::Vector3f(1, 1, 0));
  // Share 0: nothing moves.
  EXPECT_EQ(SmoothPoints(cloud, 0).xyz(), cloud.xyz());
}

TEST(PointSmoothingTest, AnOutlierIsPulledInAndCostsNoNeighbor) {
  // One point 1e6 away stretches the box, so the grid's cells grow far wider than the
  // neighborhoods: the points of the square still find their nearest, and the outlier,
  // whose nearest are all on the square, moves towards it.
  PointCloud cloud = NoisySquare(32, 0.02f, 9);
  cloud.Add(1e6f, 0, 0);
  const PointCloud smoothed = SmoothPoints(cloud, 0.03);
  EXPECT_LT(smoothed.point(cloud.size() - 1).x(), 1e6f / 20);
  const PointCloud square = NoisySquare(32, 0.02f, 9);
  EXPECT_LT(InnerRmsZ(smoothed, 0.15f), InnerRmsZ(square, 0.15f) / 3);
}

TEST(PointSmoothingTest, BytesStopGrowingPastTheReferencePoints) {
  EXPECT_GE(SmoothPointsBytes(1000), 1000 * 3 * sizeof(float));
  EXPECT_GT(SmoothPointsBytes(4000), SmoothPointsBytes(1000));
  EXPECT_EQ(SmoothPointsBytes(100000), SmoothPointsBytes(100000000));
  EXPECT_LT(SmoothPointsBytes(100000000), size_t{2} << 20);
}

}  // namespace
}  // namespace shapeid
