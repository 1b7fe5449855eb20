#include "core/point_cloud.h"

#include <limits>

#include "gmock/gmock.h"
#include "gtest/gtest.h"

namespace shapeid {
namespace {

using ::testing::HasSubstr;

TEST(PointCloudTest, StoresContiguousXyzAndViewsItThroughEigen) {
  PointCloud cloud{{1, 2, 3}, {4, 5, 6}};
  cloud.Add(7, 8, 9);
  cloud.Append(std::vector<float>{10, 11, 12});
  ASSERT_EQ(cloud.size(), 4u);
  EXPECT_EQ(cloud.xyz().size(), 12u);
  EXPECT_EQ(cloud.data()[4], 5.0f);
  EXPECT_EQ(cloud.point(2), Eigen::Vector3f(7, 8, 9));
  EXPECT_EQ(cloud.matrix().col(3), Eigen::Vector3f(10, 11, 12));
  EXPECT_FLOAT_EQ(cloud.matrix().rowwise().mean().x(), 5.5f);
}

TEST(PointCloudTest, StatsOfAValidCloud) {
  // Centroid (1, 1, 1); box [0, 3] x [0, 2] x [1, 1]; largest centered coordinate |3 - 1| = 2.
  const PointCloud cloud{{0, 0, 1}, {3, 1, 1}, {0, 2, 1}, {1, 1, 1}};
  const auto stats = ValidateCloud(cloud);
  ASSERT_TRUE(stats.ok()) << stats.status();
  EXPECT_EQ(stats->num_points, 4u);
  EXPECT_EQ(stats->centroid, Eigen::Vector3d(1, 1, 1));
  EXPECT_EQ(stats->min, Eigen::Vector3d(0, 0, 1));
  EXPECT_EQ(stats->max, Eigen::Vector3d(3, 2, 1));
  EXPECT_DOUBLE_EQ(stats->MaxAbsCentered(), 2.0);
}

TEST(PointCloudTest, CentroidKeepsPrecisionOverManyPoints) {
  // A million float additions in float would drift; in double the mean is exact here.
  PointCloud cloud;
  for (int i = 0; i < 1000000; ++i) cloud.Add(1000.1f + (i % 2), -3.0f, 0.5f * (i % 4));
  const auto stats = ValidateCloud(cloud);
  ASSERT_TRUE(stats.ok());
  EXPECT_NEAR(stats->centroid.x(), double(1000.1f) + 0.5, 1e-9);
  EXPECT_NEAR(stats->centroid.z(), 0.75, 1e-12);
}

TEST(PointCloudTest, EveryInvalidInputNamesItsProblem) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float inf = std::numeric_limits<float>::infinity();
  struct Case {
    PointCloud cloud;
    absl::StatusCode code;
    std::string message;
  };
  const std::vector<Case> cases = {
      {PointCloud(), absl::StatusCode::kInvalidArgument, "cloud has 0 points; at least 3"},
      {PointCloud{{1, 1, 1}}, absl::StatusCode::kInvalidArgument, "cloud has 1 point;"},
      {PointCloud{{0, 0, 0}, {1, 1, 1}, {2, -inf, 2}, {nan, 0, 0}},
       absl::StatusCode::kInvalidArgument, "point 2 has a non-finite coordinate (y is -inf)"},
      {PointCloud{{5, 5, 5}, {5, 5, 5}, {5, 5, 5}, {5, 5, 5}}, absl::StatusCode::kInvalidArgument,
       "all 4 points are identical: the cloud has zero extent"},
      {PointCloud(std::vector<float>{1, 2, 3, 4, 5, 6, 7, 8, 9, 10}),
       absl::StatusCode::kInvalidArgument, "not a whole number of xyz points"},
  };
  for (const Case& c : cases) {
    const auto stats = ValidateCloud(c.cloud);
    ASSERT_FALSE(stats.ok()) << c.message;
    EXPECT_EQ(stats.status().code(), c.code) << c.message;
    EXPECT_THAT(stats.status().message(), HasSubstr(c.message));
  }
}

TEST(PointCloudTest, SizeLimitIsResourceExhaustedWithBothNumbers) {
  const PointCloud cloud{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  EXPECT_TRUE(ValidateCloud(cloud, CloudLimits{4}).ok());
  const auto stats = ValidateCloud(cloud, CloudLimits{3});
  EXPECT_EQ(stats.status().code(), absl::StatusCode::kResourceExhausted);
  EXPECT_THAT(stats.status().message(), HasSubstr("cloud has 4 points, more than the limit of 3"));
}

TEST(PointCloudTest, FlatAndCollinearCloudsAreValid) {
  // Zero extent on some axes is a shape (a plane, a line); only all-identical is refused.
  EXPECT_TRUE(ValidateCloud(PointCloud{{0, 0, 0}, {1, 0, 0}, {2, 0, 0}}).ok());
  EXPECT_TRUE(ValidateCloud(PointCloud{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}).ok());
}

}  // namespace
}  // namespace shapeid
