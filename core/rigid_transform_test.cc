#include "core/rigid_transform.h"

#include <cmath>
#include <limits>
#include <vector>

#include "gmock/gmock.h"
#include "gtest/gtest.h"

namespace shapeid {
namespace {

using ::testing::HasSubstr;

std::array<float, 3> Apply(const RigidTransform& t, std::array<float, 3> p) {
  ApplyRigidTransform(t, p.data(), 1);
  return p;
}

void ExpectNear(const std::array<float, 3>& got, const std::array<float, 3>& want) {
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(got[i], want[i], 1e-6) << "coordinate " << i;
}

TEST(RigidTransformTest, RowsAreRotationThenTranslation) {
  // A quarter turn about z, then (1, 2, 3).
  const std::vector<double> rows = {0, -1, 0, 1, 1, 0, 0, 2, 0, 0, 1, 3};
  const RigidTransform t = *RigidTransformFromRows(rows);
  EXPECT_FALSE(t.is_identity());
  ExpectNear(Apply(t, {1, 0, 0}), {1, 3, 3});
  ExpectNear(Apply(t, {0, 0, 1}), {1, 2, 4});
}

TEST(RigidTransformTest, IdentityRowsGiveIdentity) {
  const std::vector<double> rows = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0};
  EXPECT_TRUE(RigidTransformFromRows(rows)->is_identity());
}

TEST(RigidTransformTest, RefusesWhatIsNotRigid) {
  const struct {
    std::vector<double> rows;
    const char* message;
  } cases[] = {
      {{1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1}, "11 numbers; expected 12"},
      {{2, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0}, "not a rotation"},
      {{1, 0.1, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0}, "not a rotation"},
      {{-1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0}, "reflection"},
      {{1, 0, 0, NAN, 0, 1, 0, 0, 0, 0, 1, 0}, "row 0 column 3 is not finite"},
      // Finite as a double, infinite as the float32 the points are moved in.
      {{1, 0, 0, 1e39, 0, 1, 0, 0, 0, 0, 1, 0},
       "row 0 column 3 (transform[3]) is 1e+39, beyond float32's range (|value| <= "
       "3.40282e+38)"},
      {{1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, -4e38}, "row 2 column 3 (transform[11]) is -4e+38"},
  };
  for (const auto& c : cases) {
    const auto t = RigidTransformFromRows(c.rows);
    ASSERT_FALSE(t.ok()) << c.message;
    EXPECT_EQ(t.status().code(), absl::StatusCode::kInvalidArgument);
    EXPECT_THAT(t.status().message(), HasSubstr(c.message));
  }
}

TEST(RigidTransformTest, TheLargestFloat32TranslationIsAccepted) {
  const double max = std::numeric_limits<float>::max();
  const auto t =
      RigidTransformFromRows(std::vector<double>{1, 0, 0, max, 0, 1, 0, -max, 0, 0, 1, 0});
  ASSERT_TRUE(t.ok()) << t.status();
  EXPECT_EQ(t->translation[0], std::numeric_limits<float>::max());
}

TEST(RigidTransformTest, UpOfAnyFiniteLengthIsADirection) {
  const std::array<float, 3> z = {0, 0, 1};
  // Their squared norms overflow and underflow a double.
  for (const double length : {1e200, 1e-200}) {
    const auto t = RotationTakingUpTo(std::vector<double>{0, -length, 0}, z);
    ASSERT_TRUE(t.ok()) << length << ": " << t.status();
    ExpectNear(Apply(*t, {0, -1, 0}), {0, 0, 1});
  }
}

TEST(RigidTransformTest, UpTurnsOntoTheTarget) {
  const std::array<float, 3> z = {0, 0, 1};
  // A camera's optical frame: y points down, so up is -y.
  const std::vector<double> camera_up = {0, -2.5, 0};
  const RigidTransform t = *RotationTakingUpTo(camera_up, z);
  ExpectNear(Apply(t, {0, -1, 0}), {0, 0, 1});
  // The smallest rotation: the axis it turns about (x here) stays where it was.
  ExpectNear(Apply(t, {1, 0, 0}), {1, 0, 0});
  // A target other than z (a gallery whose descriptor says up=y).
  ExpectNear(Apply(*RotationTakingUpTo(std::vector<double>{0, 0, 1}, {0, 1, 0}), {0, 0, 1}),
             {0, 1, 0});
  // Already up, and exactly opposite.
  EXPECT_TRUE(RotationTakingUpTo(std::vector<double>{0, 0, 3}, z)->is_identity());
  ExpectNear(Apply(*RotationTakingUpTo(std::vector<double>{0, 0, -1}, z), {0, 0, -1}), {0, 0, 1});
}

TEST(RigidTransformTest, UpRefusesWhatIsNotADirection) {
  const std::array<float, 3> z = {0, 0, 1};
  EXPECT_THAT(RotationTakingUpTo(std::vector<double>{0, 0, 0}, z).status().message(),
              HasSubstr("not a direction"));
  EXPECT_THAT(RotationTakingUpTo(std::vector<double>{0, INFINITY, 0}, z).status().message(),
              HasSubstr("not a direction"));
  EXPECT_THAT(RotationTakingUpTo(std::vector<double>{0, 1}, z).status().message(),
              HasSubstr("2 numbers; expected 3"));
}

}  // namespace
}  // namespace shapeid
