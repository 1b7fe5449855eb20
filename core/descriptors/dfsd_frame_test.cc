#include "core/descriptors/dfsd_frame.h"

#include <cmath>
#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

#include "Eigen/LU"
#include "core/descriptors/dfsd_golden_clouds.h"
#include "gtest/gtest.h"

namespace shapeid::dfsd_internal {
namespace {

bool SameBits(const double* a, const double* b, size_t n) {
  return std::memcmp(a, b, n * sizeof(double)) == 0;
}

Eigen::Matrix3Xd RandomColumns(size_t n, uint64_t seed) {
  dfsd_golden::Rng rng(seed);
  Eigen::Matrix3Xd d(3, static_cast<Eigen::Index>(n));
  for (size_t p = 0; p < n; ++p) {
    for (int a = 0; a < 3; ++a) d(a, static_cast<Eigen::Index>(p)) = (a + 1) * rng.Symmetric();
  }
  return d;
}

TEST(DfsdFrameTest, ScatterSumIsEigensProductBitForBit) {
  // Both sides of the coefficient/GEMM switch (14 columns) and of Eigen's depth blocks.
  for (size_t n :
       {3, 4, 13, 14, 15, 47, 48, 49, 400, 503, 504, 505, 1007, 1008, 1009, 5000, 65537}) {
    const Eigen::Matrix3Xd d = RandomColumns(n, n);
    const Eigen::Matrix3d want = d * d.transpose();
    for (size_t chunk : {size_t{1}, size_t{7}, kFramePassPoints}) {
      ScatterSum sum(n);
      for (size_t first = 0; first < n; first += chunk) {
        const size_t count = std::min(chunk, n - first);
        const Eigen::Matrix3Xd columns =
            d.middleCols(static_cast<Eigen::Index>(first), static_cast<Eigen::Index>(count));
        sum.Add(columns);
      }
      const Eigen::Matrix3d got = sum.Sum();
      EXPECT_TRUE(SameBits(got.data(), want.data(), 9)) << n << " points in chunks of " << chunk;
    }
  }
}

TEST(DfsdFrameTest, EigenOrderSumIsEigensSumBitForBit) {
  for (size_t n = 0; n < 70; ++n) {
    for (size_t big : {size_t{0}, size_t{4097}, size_t{100003}}) {
      const size_t size = n + big;
      const Eigen::Matrix3Xd d = RandomColumns(size, 3 * size + 1);
      const Eigen::RowVectorXd c = d.row(1);
      const double want2 = c.array().square().sum(), want3 = c.array().cube().sum();
      EigenOrderSum sum2(size), sum3(size);
      for (Eigen::Index p = 0; p < c.size(); ++p) {
        sum2.Add(c[p] * c[p]);
        sum3.Add(c[p] * c[p] * c[p]);
      }
      const double got2 = sum2.Sum(), got3 = sum3.Sum();
      EXPECT_TRUE(SameBits(&got2, &want2, 1)) << size;
      EXPECT_TRUE(SameBits(&got3, &want3, 1)) << size;
    }
  }
}

TEST(DfsdFrameTest, BoxFrameOfABoxIsItsAxesLargestFirst) {
  // A 4 x 2 x 1.2 box with an ellipsoid on it, turned off the input axes: the frame finds its
  // extents, largest first.
  const PointCloud cloud = dfsd_golden::MakeCloud("surface_rotated", 2000);
  const CloudFrame frame = CloudFrame::Find(cloud, *ValidateCloud(cloud), DfsdOptions());
  EXPECT_GE(frame.half_extent()[0], frame.half_extent()[1]);
  EXPECT_GE(frame.half_extent()[1], frame.half_extent()[2]);
  EXPECT_NEAR(frame.half_extent()[0], 2.0, 0.1);
  EXPECT_NEAR(std::abs(frame.axes().determinant()), 1.0, 1e-9);
}

TEST(DfsdFrameTest, CoordinatesAreTheFramedPointsAboutTheBoxCenter) {
  const PointCloud cloud = dfsd_golden::MakeCloud("surface_rotated", 1000);
  const CloudStats stats = *ValidateCloud(cloud);
  for (DfsdOptions::Frame kind : {DfsdOptions::Frame::kAxes, DfsdOptions::Frame::kBox}) {
    DfsdOptions options;
    options.frame = kind;
    const CloudFrame frame = CloudFrame::Find(cloud, stats, options);
    std::vector<double> x(cloud.size()), y(cloud.size()), z(cloud.size());
    double* const coord[3] = {x.data(), y.data(), z.data()};
    frame.Coordinates(cloud, 0, cloud.size(), coord);
    Eigen::Vector3d lo = Eigen::Vector3d::Constant(1e300), hi = -lo;
    for (size_t p = 0; p < cloud.size(); ++p) {
      const Eigen::Vector3d q(x[p], y[p], z[p]);
      lo = lo.cwiseMin(q);
      hi = hi.cwiseMax(q);
      // A chunk of one point gives the same bits.
      double one[3];
      double* const single[3] = {&one[0], &one[1], &one[2]};
      frame.Coordinates(cloud, p, 1, single);
      EXPECT_TRUE(SameBits(one, q.data(), 3));
      const Eigen::Vector3d back =
          frame.axes() * (q + frame.center()) +
          (kind == DfsdOptions::Frame::kAxes ? Eigen::Vector3d::Zero() : stats.centroid);
      EXPECT_LT((back - cloud.point(p).cast<double>()).norm(), 1e-5);
    }
    for (int a = 0; a < 3; ++a) {
      EXPECT_NEAR(hi[a], frame.half_extent()[a], 1e-12);
      EXPECT_NEAR(lo[a], -frame.half_extent()[a], 1e-12);
    }
  }
}

// The frame of a cloud does not depend on how its hulls were sorted: in memory, or in slabs
// of any size, over shapes whose projections put every point on the hull's candidates.
TEST(DfsdFrameTest, FramesDoNotDependOnTheHullSlabs) {
  for (const std::string& shape : dfsd_golden::Shapes()) {
    const PointCloud cloud = dfsd_golden::MakeCloud(shape, 1500);
    const auto stats = ValidateCloud(cloud);
    if (!stats.ok()) continue;
    for (const char* up : {"z", "y"}) {
      for (DfsdOptions::Frame kind : {DfsdOptions::Frame::kBox, DfsdOptions::Frame::kUpright}) {
        if (kind == DfsdOptions::Frame::kBox && std::string(up) != "z") continue;
        DfsdOptions options;
        options.frame = kind;
        options.up = std::string(up) == "z" ? DfsdOptions::Up::kPlusZ : DfsdOptions::Up::kPlusY;
        const CloudFrame want = CloudFrame::Find(cloud, *stats, options);
        for (size_t slab : {3, 9, 250}) {
          const CloudFrame got = CloudFrame::Find(cloud, *stats, options, slab);
          const std::string what = shape + " up=" + up + " slab " + std::to_string(slab);
          EXPECT_EQ(got.axes(), want.axes()) << what;
          EXPECT_EQ(got.center(), want.center()) << what;
          EXPECT_EQ(got.half_extent(), want.half_extent()) << what;
          EXPECT_EQ(got.skewness(), want.skewness()) << what;
        }
      }
    }
  }
}

}  // namespace
}  // namespace shapeid::dfsd_internal
