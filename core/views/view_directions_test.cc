#include "core/views/view_directions.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "Eigen/Geometry"
#include "gmock/gmock.h"
#include "gtest/gtest.h"

namespace shapeid {
namespace {

using ::testing::HasSubstr;

constexpr double kPi = 3.14159265358979323846;

double ElevationDeg(const Eigen::Vector3d& direction, const Eigen::Vector3d& up) {
  return std::asin(std::clamp(direction.dot(up.normalized()), -1.0, 1.0)) * 180 / kPi;
}

TEST(ViewDirectionsTest, UnitDirectionsInsideTheBand) {
  const Eigen::Vector3d up(1, 2, 3);  // any up, not unit
  const auto directions = ViewDirections(50, up, 10, 60);
  ASSERT_TRUE(directions.ok()) << directions.status();
  ASSERT_EQ(directions->size(), 50u);
  for (const Eigen::Vector3d& d : *directions) {
    EXPECT_NEAR(d.norm(), 1, 1e-12);
    EXPECT_GE(ElevationDeg(d, up), 10 - 1e-9);
    EXPECT_LE(ElevationDeg(d, up), 60 + 1e-9);
  }
  EXPECT_TRUE(ViewDirections(0, up, 10, 60)->empty());
}

TEST(ViewDirectionsTest, SpreadEvenlyOverTheSphere) {
  const size_t n = 200;
  const auto directions = ViewDirections(n, {0, 1, 0}, -90, 90);
  ASSERT_TRUE(directions.ok());
  // Equal areas: as many above the equator as below, and in each octant about n / 8.
  size_t above = 0, octant = 0;
  double closest = kPi;
  for (size_t i = 0; i < n; ++i) {
    const Eigen::Vector3d& d = (*directions)[i];
    above += d.y() > 0;
    octant += d.x() > 0 && d.y() > 0 && d.z() > 0;
    for (size_t j = 0; j < i; ++j) {
      closest = std::min(closest, std::acos(std::clamp(d.dot((*directions)[j]), -1.0, 1.0)));
    }
  }
  EXPECT_EQ(above, n / 2);
  EXPECT_NEAR(static_cast<double>(octant), n / 8.0, 4);
  // No two crowd together: each has about 4 pi / n steradians to itself.
  EXPECT_GT(closest, 0.5 * std::sqrt(4 * kPi / n));
}

TEST(ViewDirectionsTest, AzimuthZeroIsPlusZAboutYAndTurnsRightHanded) {
  const auto zero = ViewDirections(1, {0, 1, 0}, 0, 0, 0);
  const auto quarter = ViewDirections(1, {0, 1, 0}, 0, 0, 90);
  const auto about_z = ViewDirections(1, {0, 0, 1}, 0, 0, 0);
  ASSERT_TRUE(zero.ok() && quarter.ok() && about_z.ok());
  EXPECT_TRUE((*zero)[0].isApprox(Eigen::Vector3d(0, 0, 1), 1e-12));
  EXPECT_TRUE((*quarter)[0].isApprox(Eigen::Vector3d(1, 0, 0), 1e-12));
  EXPECT_TRUE((*about_z)[0].isApprox(Eigen::Vector3d(1, 0, 0), 1e-12));
}

TEST(ViewDirectionsTest, OffsetViewsInterleaveWithoutRepeating) {
  const size_t n = 24;
  const Eigen::Vector3d up(0, 0, 1);
  const auto train = ViewDirections(n, up, 0, 45);
  const auto test = ViewDirections(n, up, 0, 45, 180.0 / n);
  const auto again = ViewDirections(n, up, 0, 45, 360);
  ASSERT_TRUE(train.ok() && test.ok() && again.ok());
  double closest = kPi, nearest_sum = 0;
  for (const Eigen::Vector3d& t : *test) {
    double nearest = kPi;
    for (const Eigen::Vector3d& d : *train) {
      nearest = std::min(nearest, std::acos(std::clamp(t.dot(d), -1.0, 1.0)));
    }
    closest = std::min(closest, nearest);
    nearest_sum += nearest;
  }
  EXPECT_GT(closest, 0.01);
  // Interleaved: a test view's nearest training view is closer than training views are to
  // each other, on average.
  double train_nearest_sum = 0;
  for (size_t i = 0; i < n; ++i) {
    double nearest = kPi;
    for (size_t j = 0; j < n; ++j) {
      if (j != i) {
        nearest = std::min(nearest, std::acos(std::clamp((*train)[i].dot((*train)[j]), -1.0, 1.0)));
      }
    }
    train_nearest_sum += nearest;
  }
  EXPECT_LT(nearest_sum, train_nearest_sum);
  // A whole turn is no offset.
  for (size_t i = 0; i < n; ++i) EXPECT_TRUE((*again)[i].isApprox((*train)[i], 1e-12));
}

TEST(ViewDirectionsTest, InvalidArgumentsAreRejected) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const Eigen::Vector3d up(0, 1, 0);
  struct Case {
    absl::StatusOr<std::vector<Eigen::Vector3d>> result;
    const char* message;
  };
  const Case cases[] = {
      {ViewDirections(4, {0, 0, 0}, 0, 30), "up vector"},
      {ViewDirections(4, {nan, 1, 0}, 0, 30), "up vector"},
      {ViewDirections(4, up, 40, 30), "elevations"},
      {ViewDirections(4, up, -91, 30), "elevations"},
      {ViewDirections(4, up, 0, 90.5), "elevations"},
      {ViewDirections(4, up, nan, 30), "elevations"},
      {ViewDirections(4, up, 0, 30, nan), "offset"},
  };
  for (const Case& c : cases) {
    EXPECT_EQ(c.result.status().code(), absl::StatusCode::kInvalidArgument) << c.message;
    EXPECT_THAT(c.result.status().message(), HasSubstr(c.message));
  }
}

}  // namespace
}  // namespace shapeid
