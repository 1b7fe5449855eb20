#include "core/knn/knn_statistics.h"

#include <cmath>
#include <vector>

#include "gtest/gtest.h"

namespace shapeid {
namespace knn_internal {
namespace {

TEST(RunningStatisticsTest, FactorsAreOneOverSpread) {
  RunningStatistics stats(2, 1e-8);
  EXPECT_EQ(stats.Factors(FeatureScaling::kNone), nullptr);
  EXPECT_EQ(stats.Factors(FeatureScaling::kZScore)[0], 1.0f);  // empty: all ones
  const std::vector<float> rows = {1, 5, 3, 5, -2, 5};         // dim 1 constant
  for (int r = 0; r < 3; ++r) stats.Add(&rows[static_cast<std::size_t>(2 * r)]);
  stats.UpdateFactors();
  EXPECT_EQ(stats.count(), 3);
  const double mean = (1.0 + 3.0 - 2.0) / 3.0;
  const double var =
      ((1 - mean) * (1 - mean) + (3 - mean) * (3 - mean) + (-2 - mean) * (-2 - mean)) / 3;
  EXPECT_FLOAT_EQ(stats.Factors(FeatureScaling::kZScore)[0],
                  static_cast<float>(1 / std::sqrt(var)));
  EXPECT_EQ(stats.Factors(FeatureScaling::kZScore)[1], 1.0f);  // std 0: unscaled
  EXPECT_FLOAT_EQ(stats.Factors(FeatureScaling::kMaxAbs)[0], 1.0f / 3.0f);
  EXPECT_FLOAT_EQ(stats.Factors(FeatureScaling::kMaxAbs)[1], 1.0f / 5.0f);
}

TEST(RunningStatisticsTest, TinySpreadIsCapped) {
  RunningStatistics stats(1, 1e-8);
  const float a = 1e-12f, b = -1e-12f;
  stats.Add(&a);
  stats.Add(&b);
  stats.UpdateFactors();
  EXPECT_EQ(stats.Factors(FeatureScaling::kMaxAbs)[0], static_cast<float>(1e8));
  EXPECT_EQ(stats.Factors(FeatureScaling::kZScore)[0], static_cast<float>(1e8));
}

TEST(RunningStatisticsTest, ResetAndReplayGiveTheSameBits) {
  RunningStatistics once(3, 1e-8);
  std::vector<float> rows;
  for (int i = 0; i < 300; ++i) rows.push_back(std::sin(static_cast<float>(i) * 0.37f) * 1000.0f);
  for (int r = 0; r < 100; ++r) once.Add(&rows[static_cast<std::size_t>(3 * r)]);
  once.UpdateFactors();
  RunningStatistics copy = once;
  copy.Reset();
  EXPECT_EQ(copy.count(), 0);
  for (int r = 0; r < 100; ++r) copy.Add(&rows[static_cast<std::size_t>(3 * r)]);
  copy.UpdateFactors();
  for (FeatureScaling s : {FeatureScaling::kZScore, FeatureScaling::kMaxAbs}) {
    for (int j = 0; j < 3; ++j) EXPECT_EQ(copy.Factors(s)[j], once.Factors(s)[j]);
  }
}

}  // namespace
}  // namespace knn_internal
}  // namespace shapeid
