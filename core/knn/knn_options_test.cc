#include "core/knn/knn_options.h"

#include "absl/strings/str_cat.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"

namespace shapeid {
namespace {

using ::testing::HasSubstr;

TEST(KnnOptionsTest, DefaultsAreOneNearestUnscaledUniform) {
  const KnnOptions options;
  EXPECT_EQ(options.k, 1);
  EXPECT_EQ(options.weighting, VoteWeighting::kUniform);
  EXPECT_EQ(options.scaling, FeatureScaling::kNone);
  EXPECT_TRUE(ValidateKnnOptions(options).ok());
}

TEST(KnnOptionsTest, FeatureScalingRoundTrips) {
  for (FeatureScaling s :
       {FeatureScaling::kNone, FeatureScaling::kZScore, FeatureScaling::kMaxAbs}) {
    auto parsed = ParseFeatureScaling(FeatureScalingName(s));
    ASSERT_TRUE(parsed.ok()) << parsed.status();
    EXPECT_EQ(*parsed, s);
  }
  EXPECT_EQ(FeatureScalingName(FeatureScaling::kZScore), "zscore");
  EXPECT_EQ(FeatureScalingName(FeatureScaling::kMaxAbs), "maxabs");
  EXPECT_EQ(FeatureScalingName(FeatureScaling::kNone), "none");
}

TEST(KnnOptionsTest, ParsingIgnoresCaseAndSpaces) {
  EXPECT_EQ(*ParseFeatureScaling("  ZScore "), FeatureScaling::kZScore);
  EXPECT_EQ(*ParseVoteWeighting("DISTANCE"), VoteWeighting::kDistance);
}

TEST(KnnOptionsTest, UnknownNamesListTheChoices) {
  auto scaling = ParseFeatureScaling("minmax");
  EXPECT_EQ(scaling.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(scaling.status().message(), HasSubstr("\"minmax\""));
  EXPECT_THAT(scaling.status().message(), HasSubstr("none, zscore, maxabs"));

  auto weighting = ParseVoteWeighting("");
  EXPECT_EQ(weighting.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(weighting.status().message(), HasSubstr("uniform, distance"));
}

TEST(KnnOptionsTest, VoteWeightingRoundTrips) {
  for (VoteWeighting w : {VoteWeighting::kUniform, VoteWeighting::kDistance}) {
    auto parsed = ParseVoteWeighting(VoteWeightingName(w));
    ASSERT_TRUE(parsed.ok()) << parsed.status();
    EXPECT_EQ(*parsed, w);
  }
}

TEST(KnnOptionsTest, RejectsNonPositiveK) {
  for (int k : {0, -1, -100}) {
    KnnOptions options;
    options.k = k;
    const absl::Status status = ValidateKnnOptions(options);
    EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument);
    EXPECT_THAT(status.message(), HasSubstr(absl::StrCat("got ", k)));
  }
}

TEST(KnnOptionsTest, RejectsOutOfRangeEnums) {
  KnnOptions options;
  options.scaling = static_cast<FeatureScaling>(7);
  EXPECT_EQ(ValidateKnnOptions(options).code(), absl::StatusCode::kInvalidArgument);
  options = KnnOptions();
  options.weighting = static_cast<VoteWeighting>(-1);
  EXPECT_EQ(ValidateKnnOptions(options).code(), absl::StatusCode::kInvalidArgument);
}

}  // namespace
}  // namespace shapeid
