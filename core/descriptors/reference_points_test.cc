#include "core/descriptors/reference_points.h"

#include <cmath>

#include "gmock/gmock.h"
#include "gtest/gtest.h"

namespace shapeid {
namespace {

using ::testing::HasSubstr;

TEST(ReferencePointsTest, Cross7IsTheAxesAndTheOrigin) {
  const auto refs = Cross7References();
  ASSERT_EQ(refs.size(), 7u);
  EXPECT_EQ(refs[0], Eigen::Vector3f(1, 0, 0));
  EXPECT_EQ(refs[5], Eigen::Vector3f(0, 0, -1));
  EXPECT_EQ(refs[6], Eigen::Vector3f(0, 0, 0));
}

TEST(ReferencePointsTest, Cubic27OrdersXOutermostZInnermost) {
  const auto refs = Cubic27References();
  ASSERT_EQ(refs.size(), 27u);
  EXPECT_EQ(refs[0], Eigen::Vector3f(-1, -1, -1));
  EXPECT_EQ(refs[1], Eigen::Vector3f(-1, -1, 0));
  EXPECT_EQ(refs[3], Eigen::Vector3f(-1, 0, -1));
  EXPECT_EQ(refs[9], Eigen::Vector3f(0, -1, -1));
  EXPECT_EQ(refs[13], Eigen::Vector3f(0, 0, 0));
  EXPECT_EQ(refs[26], Eigen::Vector3f(1, 1, 1));
}

TEST(ReferencePointsTest, Spherical27RingsAtFortyFiveDegreesThenOriginAndPoles) {
  const auto refs = Spherical27References();
  ASSERT_EQ(refs.size(), 27u);
  const float s = static_cast<float>(std::sqrt(0.5));
  // psi = -45, theta = 90: (sin 90 sin -45, cos 90, sin 90 cos -45) = (-s, 0, s).
  EXPECT_NEAR(refs[2].x(), -s, 1e-7);
  EXPECT_EQ(refs[2].y(), 0.0f);
  EXPECT_NEAR(refs[2].z(), s, 1e-7);
  // psi = 0, theta = 0 is the pole (0, 1, 0), as the published arrangement repeats.
  EXPECT_EQ(refs[8], Eigen::Vector3f(0, 1, 0));
  EXPECT_EQ(refs[24], Eigen::Vector3f(0, 0, 0));
  EXPECT_EQ(refs[25], Eigen::Vector3f(0, -1, 0));
  EXPECT_EQ(refs[26], Eigen::Vector3f(0, 1, 0));
  for (int i = 0; i < 24; ++i) EXPECT_NEAR(refs[i].norm(), 1.0f, 1e-6) << i;
}

TEST(ReferencePointsTest, FibonacciSphereIsUnitAndEvenlySpreadInZ) {
  const auto refs = FibonacciReferences(10);
  ASSERT_EQ(refs.size(), 11u);
  EXPECT_EQ(refs[0], Eigen::Vector3f(0, 0, 0));
  for (int i = 1; i <= 10; ++i) {
    EXPECT_NEAR(refs[i].norm(), 1.0f, 1e-6);
    EXPECT_NEAR(refs[i].z(), 1.0 - (2.0 * (i - 1) + 1.0) / 10.0, 1e-6);
  }
  // i = 0: z = 0.9, phi = 0 -> (sqrt(1 - 0.81), 0, 0.9).
  EXPECT_NEAR(refs[1].x(), std::sqrt(0.19), 1e-6);
  EXPECT_EQ(refs[1].y(), 0.0f);
}

TEST(ReferencePointsTest, ParsesNamesAndCustomLists) {
  EXPECT_EQ(ParseReferenceArrangement("CUBIC27")->name, "cubic27");
  EXPECT_EQ(ParseReferenceArrangement("fibonacci:032")->name, "fibonacci:32");
  EXPECT_EQ(ParseReferenceArrangement("fibonacci:32")->points.size(), 33u);
  const auto custom = ParseReferenceArrangement("[0,0,0; 1, -0.5, 2.25]");
  ASSERT_TRUE(custom.ok()) << custom.status();
  EXPECT_EQ(custom->name, "[0,0,0;1,-0.5,2.25]");
  ASSERT_EQ(custom->points.size(), 2u);
  EXPECT_EQ(custom->points[1], Eigen::Vector3f(1, -0.5f, 2.25f));
}

TEST(ReferencePointsTest, RejectsMalformedArrangements) {
  for (const auto& [text, message] : std::vector<std::pair<std::string, std::string>>{
           {"cross8", "is not an arrangement"},
           {"fibonacci:", "fibonacci:N needs N in [1, 4095]"},
           {"fibonacci:5000", "fibonacci:N needs N in [1, 4095]"},
           {"[]", "needs 3 coordinates"},
           {"[1,2,3;4,5]", "\"4,5\""},
           {"[1,2,x]", "coordinate \"x\""},
           {"[1,2,101]", "[-100, 100]"},
       }) {
    const auto refs = ParseReferenceArrangement(text);
    ASSERT_FALSE(refs.ok()) << text;
    EXPECT_EQ(refs.status().code(), absl::StatusCode::kInvalidArgument);
    EXPECT_THAT(refs.status().message(), HasSubstr(message)) << text;
  }
}

}  // namespace
}  // namespace shapeid
