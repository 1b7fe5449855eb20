#include "core/descriptors/dfsd_frame.h"

#include <cmath>
#include <vector>

#include "core/descriptors/dfsd_golden_clouds.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"

namespace shapeid::dfsd_internal {
namespace {

TEST(DfsdFrameTest, ConvexHullIsCounterClockwiseWithoutInteriorOrCollinearPoints) {
  // A 4 x 4 lattice square: the hull is its four corners, from the lowest-leftmost one.
  std::vector<Eigen::Vector2d> points;
  for (int i = 0; i < 4; ++i) {
    for (int j = 0; j < 4; ++j) points.emplace_back(i, j);
  }
  const std::vector<Eigen::Vector2d> hull = ConvexHull(points);
  ASSERT_EQ(hull.size(), 4u);
  EXPECT_EQ(hull[0], Eigen::Vector2d(0, 0));
  EXPECT_EQ(hull[1], Eigen::Vector2d(3, 0));
  EXPECT_EQ(hull[2], Eigen::Vector2d(3, 3));
  EXPECT_EQ(hull[3], Eigen::Vector2d(0, 3));
}

TEST(DfsdFrameTest, MinAreaRectangleFindsATurnedRectangle) {
  // A 4 x 1 rectangle turned by 30 degrees: its long side's direction and area come back.
  const double angle = 30 * 3.14159265358979323846 / 180;
  const Eigen::Vector2d u(std::cos(angle), std::sin(angle)), v(-u.y(), u.x());
  std::vector<Eigen::Vector2d> points = {2 * u + 0.5 * v, -2 * u + 0.5 * v, -2 * u - 0.5 * v,
                                         2 * u - 0.5 * v};
  Eigen::Vector2d direction;
  double area = 0;
  ASSERT_TRUE(MinAreaRectangle(ConvexHull(points), &direction, &area));
  EXPECT_NEAR(area, 4.0, 1e-12);
  EXPECT_NEAR(std::abs(direction.dot(u)) + std::abs(direction.dot(v)), 1.0, 1e-12);
}

TEST(DfsdFrameTest, MinAreaRectangleNeedsThreeHullPoints) {
  Eigen::Vector2d direction;
  double area = 0;
  EXPECT_FALSE(MinAreaRectangle({{0, 0}, {1, 1}}, &direction, &area));
}

TEST(DfsdFrameTest, BoxFrameOfABoxIsItsAxesLargestFirst) {
  // A 4 x 2 x 1 box surface turned off the input axes: the frame finds its extents.
  PointCloud cloud = dfsd_golden::MakeCloud("surface_rotated", 2000);
  DfsdOptions options;
  const FramedCloud framed = Frame(cloud, *ValidateCloud(cloud), options);
  EXPECT_GE(framed.half_extent[0], framed.half_extent[1]);
  EXPECT_GE(framed.half_extent[1], framed.half_extent[2]);
  ASSERT_EQ(framed.coord[0].size(), cloud.size());
}

}  // namespace
}  // namespace shapeid::dfsd_internal
