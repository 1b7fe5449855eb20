#include "core/knn/knn_index.h"

#include <cmath>
#include <limits>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include "absl/strings/str_cat.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"

namespace shapeid {
namespace {

using ::testing::ElementsAre;
using ::testing::HasSubstr;

KnnIndex MakeIndex(int dim) {
  auto index = KnnIndex::Create(dim);
  EXPECT_TRUE(index.ok()) << index.status();
  return *std::move(index);
}

void AddOrDie(KnnIndex& index, uint64_t id, const std::string& label, std::vector<float> x) {
  const absl::Status status = index.Add(id, label, x);
  ASSERT_TRUE(status.ok()) << status;
}

std::vector<uint64_t> Ids(const std::vector<Neighbor>& neighbors) {
  std::vector<uint64_t> ids;
  for (const Neighbor& n : neighbors) ids.push_back(n.id);
  return ids;
}

// The hand-worked example. Four 2-D samples, query q = (0, 0), k = 3:
//
//   id  label  x   y
//   1   b     -1   0
//   2   a      3   0
//   3   a     -1   2
//   4   b      3   2
//
// Gallery statistics: x has mean 1, population std 2, max |x| 3; y has mean 1, std 1,
// max |y| 2. So the factors w multiplying the differences q - x are
//   none (1, 1),  zscore (1/2, 1),  maxabs (1/3, 1/2).
// Differences q - x: id1 (1, 0), id2 (-3, 0), id3 (1, -2), id4 (-3, -2).
//
// none:   distances 1, 3, sqrt 5 = 2.2361, sqrt 13 = 3.6056
//         neighbors 1 (1, b), 3 (2.2361, a), 2 (3, a)
//         uniform:  a 2, b 1 -> a, confidence 2/3
//         distance: b 1/1 = 1, a 1/2.2361 + 1/3 = 0.4472 + 0.3333 = 0.7805
//                   -> b, confidence 1 / 1.7805 = 0.5616
// zscore: scaled differences (0.5, 0), (-1.5, 0), (0.5, -2), (-1.5, -2)
//         distances 0.5, 1.5, sqrt 4.25 = 2.0616, 2.5
//         neighbors 1 (0.5, b), 2 (1.5, a), 3 (2.0616, a)
//         uniform:  a 2, b 1 -> a, confidence 2/3
//         distance: b 1/0.5 = 2, a 1/1.5 + 1/2.0616 = 0.6667 + 0.4851 = 1.1517
//                   -> b, confidence 2 / 3.1517 = 0.6346
// maxabs: scaled differences (1/3, 0), (-1, 0), (1/3, -1), (-1, -1)
//         distances 0.3333, 1, sqrt(10)/3 = 1.0541, sqrt 2 = 1.4142
//         neighbors 1 (0.3333, b), 2 (1, a), 3 (1.0541, a)
//         uniform:  a 2, b 1 -> a, confidence 2/3
//         distance: b 3, a 1 + 0.9487 = 1.9487 -> b, confidence 3 / 4.9487 = 0.6062
struct HandCase {
  FeatureScaling scaling;
  VoteWeighting weighting;
  std::vector<uint64_t> ids;
  std::vector<double> distances;
  std::string label;
  double confidence;
  std::vector<std::pair<std::string, double>> votes;
};

class HandWorkedTest : public ::testing::TestWithParam<HandCase> {};

TEST_P(HandWorkedTest, MatchesTheComment) {
  const HandCase& c = GetParam();
  KnnIndex index = MakeIndex(2);
  AddOrDie(index, 1, "b", {-1, 0});
  AddOrDie(index, 2, "a", {3, 0});
  AddOrDie(index, 3, "a", {-1, 2});
  AddOrDie(index, 4, "b", {3, 2});

  KnnOptions options;
  options.k = 3;
  options.scaling = c.scaling;
  options.weighting = c.weighting;
  const std::vector<float> query = {0, 0};
  auto result = index.Classify(query, options);
  ASSERT_TRUE(result.ok()) << result.status();

  EXPECT_EQ(Ids(result->neighbors), c.ids);
  ASSERT_EQ(result->neighbors.size(), c.distances.size());
  for (std::size_t i = 0; i < c.distances.size(); ++i) {
    EXPECT_NEAR(result->neighbors[i].distance, c.distances[i], 1e-6) << i;
  }
  EXPECT_EQ(result->neighbors[0].label, "b");
  EXPECT_EQ(result->label, c.label);
  EXPECT_NEAR(result->confidence, c.confidence, 1e-4);
  ASSERT_EQ(result->votes.size(), c.votes.size());
  for (std::size_t i = 0; i < c.votes.size(); ++i) {
    EXPECT_EQ(result->votes[i].label, c.votes[i].first);
    EXPECT_NEAR(result->votes[i].weight, c.votes[i].second, 1e-4);
  }
}

const double kSqrt5 = std::sqrt(5.0);
const double kSqrt425 = std::sqrt(4.25);
const double kSqrt10By3 = std::sqrt(10.0) / 3;

// clang-format off: one case per line reads like the table above.
INSTANTIATE_TEST_SUITE_P(AllScalingsAndWeightings, HandWorkedTest,
                         ::testing::Values(HandCase{FeatureScaling::kNone,
                                                    VoteWeighting::kUniform,
                                                    {1, 3, 2},
                                                    {1, kSqrt5, 3},
                                                    "a",
                                                    2.0 / 3,
                                                    {{"a", 2}, {"b", 1}}},
                                           HandCase{FeatureScaling::kNone,
                                                    VoteWeighting::kDistance,
                                                    {1, 3, 2},
                                                    {1, kSqrt5, 3},
                                                    "b",
                                                    0.5616,
                                                    {{"b", 1}, {"a", 0.7805}}},
                                           HandCase{FeatureScaling::kZScore,
                                                    VoteWeighting::kUniform,
                                                    {1, 2, 3},
                                                    {0.5, 1.5, kSqrt425},
                                                    "a",
                                                    2.0 / 3,
                                                    {{"a", 2}, {"b", 1}}},
                                           HandCase{FeatureScaling::kZScore,
                                                    VoteWeighting::kDistance,
                                                    {1, 2, 3},
                                                    {0.5, 1.5, kSqrt425},
                                                    "b",
                                                    0.6346,
                                                    {{"b", 2}, {"a", 1.1517}}},
                                           HandCase{FeatureScaling::kMaxAbs,
                                                    VoteWeighting::kUniform,
                                                    {1, 2, 3},
                                                    {1.0 / 3, 1, kSqrt10By3},
                                                    "a",
                                                    2.0 / 3,
                                                    {{"a", 2}, {"b", 1}}},
                                           HandCase{FeatureScaling::kMaxAbs,
                                                    VoteWeighting::kDistance,
                                                    {1, 2, 3},
                                                    {1.0 / 3, 1, kSqrt10By3},
                                                    "b",
                                                    0.6062,
                                                    {{"b", 3}, {"a", 1.9487}}}));
// clang-format on

TEST(KnnIndexTest, ScaleFactorsOfTheHandWorkedGallery) {
  KnnIndex index = MakeIndex(2);
  AddOrDie(index, 1, "b", {-1, 0});
  AddOrDie(index, 2, "a", {3, 0});
  AddOrDie(index, 3, "a", {-1, 2});
  AddOrDie(index, 4, "b", {3, 2});
  EXPECT_THAT(index.ScaleFactors(FeatureScaling::kNone), ElementsAre(1.0f, 1.0f));
  EXPECT_THAT(index.ScaleFactors(FeatureScaling::kZScore), ElementsAre(0.5f, 1.0f));
  EXPECT_THAT(index.ScaleFactors(FeatureScaling::kMaxAbs), ElementsAre(1.0f / 3, 0.5f));
}

TEST(KnnIndexTest, EqualDistancesGoToTheEarlierSample) {
  KnnIndex index = MakeIndex(1);
  // Slots 0..99 alternate between x = 1 and x = -1, all at distance 1 from 0, so the
  // order is insertion order across several storage blocks.
  for (uint64_t i = 0; i < 100; ++i) {
    AddOrDie(index, 1000 - i, i % 2 ? "odd" : "even", {i % 2 ? 1.0f : -1.0f});
  }
  auto neighbors = index.Search(std::vector<float>{0}, 5);
  ASSERT_TRUE(neighbors.ok()) << neighbors.status();
  EXPECT_THAT(Ids(*neighbors), ElementsAre(1000, 999, 998, 997, 996));
  // A strictly nearer sample added last still comes first.
  AddOrDie(index, 7, "late", {0.5f});
  neighbors = index.Search(std::vector<float>{0}, 3);
  ASSERT_TRUE(neighbors.ok());
  EXPECT_THAT(Ids(*neighbors), ElementsAre(7, 1000, 999));
}

TEST(KnnIndexTest, EqualVotesGoToTheClassOfTheNearestNeighbor) {
  KnnIndex index = MakeIndex(1);
  // "far" is added first, so insertion order would favour it; distance must decide.
  AddOrDie(index, 1, "far", {3});
  AddOrDie(index, 2, "near", {1});
  KnnOptions options;
  options.k = 2;
  auto result = index.Classify(std::vector<float>{0}, options);
  ASSERT_TRUE(result.ok()) << result.status();
  EXPECT_EQ(result->label, "near");
  EXPECT_DOUBLE_EQ(result->confidence, 0.5);
  ASSERT_EQ(result->votes.size(), 2u);
  EXPECT_EQ(result->votes[0].label, "near");
  EXPECT_EQ(result->votes[1].label, "far");
}

TEST(KnnIndexTest, KLargerThanTheGalleryReturnsEverySample) {
  KnnIndex index = MakeIndex(2);
  AddOrDie(index, 10, "a", {0, 0});
  AddOrDie(index, 11, "b", {5, 5});
  auto neighbors = index.Search(std::vector<float>{4, 4}, 50);
  ASSERT_TRUE(neighbors.ok()) << neighbors.status();
  EXPECT_THAT(Ids(*neighbors), ElementsAre(11, 10));
  KnnOptions options;
  options.k = 50;
  auto result = index.Classify(std::vector<float>{4, 4}, options);
  ASSERT_TRUE(result.ok());
  EXPECT_EQ(result->neighbors.size(), 2u);
}

TEST(KnnIndexTest, ZeroDistanceNeighborsOutvoteAllOthersUnderDistanceWeighting) {
  KnnIndex index = MakeIndex(1);
  AddOrDie(index, 1, "exact", {2});
  AddOrDie(index, 2, "other", {2.5f});
  AddOrDie(index, 3, "other", {1.5f});
  AddOrDie(index, 4, "other", {2.25f});
  KnnOptions options;
  options.k = 4;
  options.weighting = VoteWeighting::kDistance;
  auto result = index.Classify(std::vector<float>{2}, options);
  ASSERT_TRUE(result.ok()) << result.status();
  EXPECT_EQ(result->label, "exact");
  EXPECT_DOUBLE_EQ(result->confidence, 1.0);
  ASSERT_EQ(result->votes.size(), 2u);
  EXPECT_EQ(result->votes[1].label, "other");
  EXPECT_EQ(result->votes[1].weight, 0.0);

  // Two zero-distance samples of different classes: one vote each; the tie goes to the
  // class of the nearest neighbor, which among equal distances is the earlier sample.
  AddOrDie(index, 5, "twin", {2});
  options.k = 5;
  result = index.Classify(std::vector<float>{2}, options);
  ASSERT_TRUE(result.ok());
  EXPECT_EQ(result->label, "exact");
  EXPECT_DOUBLE_EQ(result->confidence, 0.5);
  EXPECT_EQ(result->votes[1].label, "twin");
  EXPECT_EQ(result->votes[1].weight, 1.0);

  // Uniform weighting is unaffected: three "other" against one each.
  options.weighting = VoteWeighting::kUniform;
  result = index.Classify(std::vector<float>{2}, options);
  ASSERT_TRUE(result.ok());
  EXPECT_EQ(result->label, "other");
  EXPECT_DOUBLE_EQ(result->confidence, 0.6);
}

TEST(KnnIndexTest, RemoveThenQuery) {
  KnnIndex index = MakeIndex(1);
  for (uint64_t i = 0; i < 70; ++i) {
    AddOrDie(index, i, i < 35 ? "low" : "high", {static_cast<float>(i)});
  }
  ASSERT_TRUE(index.Remove(std::vector<uint64_t>{40, 41, 39, 40}).ok());
  EXPECT_EQ(index.size(), 67);
  EXPECT_FALSE(index.Contains(40));
  EXPECT_TRUE(index.Contains(42));
  auto neighbors = index.Search(std::vector<float>{40}, 3);
  ASSERT_TRUE(neighbors.ok()) << neighbors.status();
  EXPECT_THAT(Ids(*neighbors), ElementsAre(38, 42, 37));

  // Unknown id: NotFound, nothing removed.
  const absl::Status status = index.Remove(std::vector<uint64_t>{1, 999});
  EXPECT_EQ(status.code(), absl::StatusCode::kNotFound);
  EXPECT_THAT(status.message(), HasSubstr("999"));
  EXPECT_EQ(index.size(), 67);
  EXPECT_TRUE(index.Contains(1));

  // Removing a whole class drops its label; re-adding an id works.
  std::vector<uint64_t> high;
  for (uint64_t i = 35; i < 70; ++i) {
    if (index.Contains(i)) high.push_back(i);
  }
  ASSERT_TRUE(index.Remove(high).ok());
  EXPECT_EQ(index.num_labels(), 1);
  AddOrDie(index, 40, "high", {40});
  neighbors = index.Search(std::vector<float>{100}, 2);
  ASSERT_TRUE(neighbors.ok());
  EXPECT_EQ((*neighbors)[0].id, 40u);
  EXPECT_EQ((*neighbors)[0].label, "high");
  EXPECT_EQ((*neighbors)[1].id, 34u);

  // Remove everything: the index is empty again.
  std::vector<uint64_t> all;
  for (uint64_t i = 0; i < 70; ++i) {
    if (index.Contains(i)) all.push_back(i);
  }
  ASSERT_TRUE(index.Remove(all).ok());
  EXPECT_TRUE(index.empty());
  EXPECT_EQ(index.Search(std::vector<float>{1}, 1).status().code(),
            absl::StatusCode::kFailedPrecondition);
}

// Reference statistics, straight from the definition, in double.
std::vector<double> ReferenceZScoreFactors(const std::vector<std::vector<float>>& rows) {
  const std::size_t d = rows[0].size();
  std::vector<double> w(d);
  for (std::size_t j = 0; j < d; ++j) {
    double mean = 0;
    for (const auto& r : rows) mean += r[j];
    mean /= rows.size();
    double var = 0;
    for (const auto& r : rows) var += (r[j] - mean) * (r[j] - mean);
    const double sd = std::sqrt(var / rows.size());
    w[j] = sd > 0 ? 1 / sd : 1;
  }
  return w;
}

TEST(KnnIndexTest, ScalingStatisticsFollowAddAndRemove) {
  std::mt19937 rng(5);
  std::normal_distribution<float> normal(100.0f, 3.0f);
  const int d = 5;
  std::vector<std::vector<float>> rows(300, std::vector<float>(d));
  for (auto& r : rows) {
    for (float& x : r) x = normal(rng);
  }
  for (auto& r : rows) r[4] = 7.0f;  // constant dimension: std 0 -> factor 1
  // Sample 0 is removed below and holds the largest |x| of dimension 0, so maxabs must
  // shrink on removal.
  rows[0][0] = 1000.0f;

  KnnIndex index = MakeIndex(d);
  for (std::size_t i = 0; i < rows.size(); ++i) AddOrDie(index, i, "x", rows[i]);
  std::vector<uint64_t> doomed;
  std::vector<std::vector<float>> kept;
  for (std::size_t i = 0; i < rows.size(); ++i) {
    if (i % 3 == 0 || i > 250) {
      doomed.push_back(i);
    } else {
      kept.push_back(rows[i]);
    }
  }
  ASSERT_TRUE(index.Remove(doomed).ok());

  const std::vector<double> want = ReferenceZScoreFactors(kept);
  const std::vector<float> zscore = index.ScaleFactors(FeatureScaling::kZScore);
  const std::vector<float> maxabs = index.ScaleFactors(FeatureScaling::kMaxAbs);
  for (int j = 0; j < d; ++j) {
    EXPECT_NEAR(zscore[j], want[j], 1e-6 * want[j]) << j;
    float max_abs = 0;
    for (const auto& r : kept) max_abs = std::max(max_abs, std::fabs(r[j]));
    EXPECT_FLOAT_EQ(maxabs[j], static_cast<float>(1.0 / max_abs)) << j;
  }
  EXPECT_EQ(zscore[4], 1.0f);

  // Bit for bit what an index built from the remaining samples, in order, holds.
  KnnIndex fresh = MakeIndex(d);
  for (std::size_t i = 0; i < kept.size(); ++i) AddOrDie(fresh, i, "x", kept[i]);
  EXPECT_EQ(index.ScaleFactors(FeatureScaling::kZScore),
            fresh.ScaleFactors(FeatureScaling::kZScore));
  EXPECT_EQ(index.ScaleFactors(FeatureScaling::kMaxAbs),
            fresh.ScaleFactors(FeatureScaling::kMaxAbs));
}

TEST(KnnIndexTest, AllZeroDimensionIsLeftUnscaled) {
  KnnIndex index = MakeIndex(2);
  AddOrDie(index, 1, "a", {0, 2});
  AddOrDie(index, 2, "a", {0, -4});
  EXPECT_THAT(index.ScaleFactors(FeatureScaling::kMaxAbs), ElementsAre(1.0f, 0.25f));
  EXPECT_THAT(index.ScaleFactors(FeatureScaling::kZScore), ElementsAre(1.0f, 1.0f / 3));
}

TEST(KnnIndexTest, InvalidInputsGiveClearErrors) {
  EXPECT_EQ(KnnIndex::Create(0).status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(KnnIndex::Create(-3).status().code(), absl::StatusCode::kInvalidArgument);

  KnnIndex index = MakeIndex(3);
  auto empty = index.Search(std::vector<float>{1, 2, 3}, 1);
  EXPECT_EQ(empty.status().code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_THAT(empty.status().message(), HasSubstr("empty"));

  absl::Status status = index.Add(1, "a", std::vector<float>{1, 2});
  EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(status.message(),
              HasSubstr("features.size() 2 is not a positive multiple of the dimension 3"));

  status = index.Add(1, "a", std::vector<float>{});
  EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(status.message(), HasSubstr("features.size() 0 is not a positive multiple"));

  status = index.Add(1, "a", std::vector<float>{1, 2, 3, 4, 5, 6, 7});
  EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(status.message(), HasSubstr("features.size() 7 is not a positive multiple"));

  status = index.Add(1, "a", std::vector<float>{1, 2, 3, 4, 5, NAN});
  EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(status.message(), HasSubstr("sample 1: view 1 feature 2 is nan"));

  status = index.Add(1, "a", std::vector<float>{1, std::nanf(""), 3});
  EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(status.message(), HasSubstr("feature 1 is nan"));

  status = index.Add(1, "a", std::vector<float>{1, 2, -INFINITY});
  EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(status.message(), HasSubstr("feature 2 is -inf"));

  status = index.Add(1, "", std::vector<float>{1, 2, 3});
  EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_TRUE(index.empty());

  AddOrDie(index, 1, "a", {1, 2, 3});
  status = index.Add(1, "b", std::vector<float>{4, 5, 6});
  EXPECT_EQ(status.code(), absl::StatusCode::kAlreadyExists);
  EXPECT_EQ(index.size(), 1);

  auto bad_k = index.Search(std::vector<float>{1, 2, 3}, 0);
  EXPECT_EQ(bad_k.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(bad_k.status().message(), HasSubstr("got 0"));

  auto bad_dim = index.Search(std::vector<float>{1, 2, 3, 4}, 1);
  EXPECT_EQ(bad_dim.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(bad_dim.status().message(),
              HasSubstr("query has 4 features, not a positive multiple of the dimension 3"));
  EXPECT_EQ(index.Search(std::vector<float>{}, 1).status().code(),
            absl::StatusCode::kInvalidArgument);

  auto nan_query = index.Search(std::vector<float>{1, NAN, 3}, 1);
  EXPECT_EQ(nan_query.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(nan_query.status().message(), HasSubstr("query feature 1 is nan"));

  auto inf_second = index.Search(std::vector<float>{1, 2, 3, 4, 5, INFINITY}, 1);
  EXPECT_EQ(inf_second.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(inf_second.status().message(), HasSubstr("query vector 1 feature 2 is inf"));

  KnnOptions options;
  options.k = -2;
  EXPECT_EQ(index.Classify(std::vector<float>{1, 2, 3}, options).status().code(),
            absl::StatusCode::kInvalidArgument);
}

// Finite but huge features (an import of +-3e38) would make distances infinite: refused,
// by sample and feature, with the bound; the bound itself is a valid feature.
TEST(KnnIndexTest, FeaturesBeyondTheBoundAreRefused) {
  constexpr float kMax = KnnIndex::kMaxFeatureMagnitude;
  KnnIndex index = MakeIndex(2);
  AddOrDie(index, 1, "a", {kMax, -kMax});
  absl::Status status = index.Add(7, "b", std::vector<float>{0, 3e38f});
  EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(status.message(), HasSubstr("sample 7: feature 1 is 3e+38"));
  EXPECT_THAT(status.message(), HasSubstr("must be finite and within +-1e+08"));
  status = index.Add(8, "b", std::vector<float>{0, 0, std::nextafter(-kMax, -INFINITY), 0});
  EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(status.message(), HasSubstr("sample 8: view 1 feature 0 is"));
  EXPECT_EQ(index.size(), 1);

  auto query = index.Search(std::vector<float>{-3e38f, 0}, 1);
  EXPECT_EQ(query.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(query.status().message(), HasSubstr("query feature 0 is -3e+38"));
  query = index.Search(std::vector<float>{-kMax, kMax}, 1);
  ASSERT_TRUE(query.ok()) << query.status();
  EXPECT_FLOAT_EQ(static_cast<float>((*query)[0].distance), 2 * std::sqrt(2.0f) * kMax);
}

// A spread far below any real descriptor's would make a factor of up to FLT_MAX, and a
// query far off in that dimension an infinite distance: the factor stops at
// 1 / kMinScaleSpread. Spreads above it are scaled as before.
TEST(KnnIndexTest, TinySpreadsAreScaledAtMostByTheCap) {
  KnnIndex index = MakeIndex(3);
  AddOrDie(index, 1, "a", {0, 0, 1});
  AddOrDie(index, 2, "b", {1e-30f, 4e-8f, 3});
  const float cap = static_cast<float>(1 / KnnIndex::kMinScaleSpread);
  const std::vector<float> zscore = index.ScaleFactors(FeatureScaling::kZScore);
  EXPECT_EQ(zscore[0], cap);
  EXPECT_FLOAT_EQ(zscore[1], 1 / 2e-8f);
  EXPECT_EQ(zscore[2], 1.0f);
  const std::vector<float> maxabs = index.ScaleFactors(FeatureScaling::kMaxAbs);
  EXPECT_EQ(maxabs[0], cap);
  EXPECT_FLOAT_EQ(maxabs[1], 1 / 4e-8f);
  EXPECT_FLOAT_EQ(maxabs[2], 1.0f / 3);
}

// The worst a gallery within the bound can do, in the most dimensions an index takes: a
// spread of one subnormal in every dimension (factors at the cap) and a query at the bound.
// Every distance stays finite and every confidence in (0, 1], whatever the scaling and vote.
TEST(KnnIndexTest, DistancesAndConfidenceStayFiniteAtTheExtremes) {
  constexpr int kDim = KnnIndex::kMaxDimension;
  KnnIndex index = MakeIndex(kDim);
  AddOrDie(index, 1, "zero", std::vector<float>(kDim, 0.0f));
  AddOrDie(index, 2, "tiny", std::vector<float>(kDim, std::numeric_limits<float>::denorm_min()));
  AddOrDie(index, 3, "zero", std::vector<float>(kDim, 0.0f));
  for (const float q : {KnnIndex::kMaxFeatureMagnitude, -KnnIndex::kMaxFeatureMagnitude}) {
    const std::vector<float> query(kDim, q);
    for (FeatureScaling scaling :
         {FeatureScaling::kNone, FeatureScaling::kZScore, FeatureScaling::kMaxAbs}) {
      for (VoteWeighting weighting : {VoteWeighting::kUniform, VoteWeighting::kDistance}) {
        const std::string where =
            absl::StrCat(FeatureScalingName(scaling), " ", VoteWeightingName(weighting), " q=", q);
        KnnOptions options;
        options.k = 3;
        options.scaling = scaling;
        options.weighting = weighting;
        auto result = index.Classify(query, options);
        ASSERT_TRUE(result.ok()) << where << ": " << result.status();
        ASSERT_EQ(result->neighbors.size(), 3u) << where;
        for (const Neighbor& n : result->neighbors) {
          EXPECT_TRUE(std::isfinite(n.distance) && n.distance > 0) << where << " " << n.distance;
        }
        for (const ClassVote& v : result->votes) {
          EXPECT_TRUE(std::isfinite(v.weight) && v.weight > 0) << where << " " << v.weight;
        }
        EXPECT_GT(result->confidence, 0.0) << where;
        EXPECT_LE(result->confidence, 1.0) << where;
        EXPECT_EQ(result->label, "zero") << where;
      }
    }
  }
}

// Views of sample i: 1 + i % 4 of them, view v = (i, v, i * v) scaled per dimension.
std::vector<float> Views(uint64_t i) {
  std::vector<float> x;
  for (uint64_t v = 0; v <= i % 4; ++v) {
    x.insert(x.end(), {static_cast<float>(i), static_cast<float>(v) * 0.5f,
                       static_cast<float>(i * v) - 3.0f});
  }
  return x;
}

TEST(KnnIndexTest, SamplesWithSeveralViewsSurviveAddRemoveAndRebuild) {
  KnnIndex index = MakeIndex(3);
  for (uint64_t i = 0; i < 50; ++i) AddOrDie(index, 100 + i, absl::StrCat("c", i % 3), Views(i));
  EXPECT_EQ(index.size(), 50);
  EXPECT_EQ(index.num_rows(), 123);  // 12 * (1 + 2 + 3 + 4) + 1 + 2
  ASSERT_TRUE(index.Remove(std::vector<uint64_t>{100, 103, 131, 148}).ok());
  EXPECT_EQ(index.size(), 46);
  EXPECT_EQ(index.num_rows(), 123 - 1 - 4 - 4 - 1);

  std::vector<uint64_t> kept;
  for (uint64_t i = 0; i < 50; ++i) {
    if (index.Contains(100 + i)) kept.push_back(i);
  }
  ASSERT_EQ(kept.size(), 46u);
  KnnIndex rebuilt = MakeIndex(3);
  for (int64_t s = 0; s < index.size(); ++s) {
    const uint64_t i = kept[static_cast<std::size_t>(s)];
    EXPECT_EQ(index.IdAt(s), 100 + i);
    EXPECT_EQ(index.LabelAt(s), absl::StrCat("c", i % 3));
    EXPECT_EQ(index.ViewsAt(s), static_cast<int>(1 + i % 4));
    EXPECT_EQ(index.Features(s), Views(i)) << s;
    std::vector<float> copied(Views(i).size() + 1, -7.0f);
    index.CopyFeatures(s, copied.data());
    EXPECT_EQ(copied.back(), -7.0f) << "wrote past ViewsAt * dimension floats";
    copied.pop_back();
    EXPECT_EQ(copied, Views(i));
    AddOrDie(rebuilt, index.IdAt(s), index.LabelAt(s), index.Features(s));
  }

  // Bit for bit the same index: statistics and answers.
  for (FeatureScaling scaling :
       {FeatureScaling::kNone, FeatureScaling::kZScore, FeatureScaling::kMaxAbs}) {
    EXPECT_EQ(index.ScaleFactors(scaling), rebuilt.ScaleFactors(scaling));
    const std::vector<float> queries = {20, 1, 15, 3, 0.5f, -3, 40, 0, 0};
    auto a = index.Search(queries, 10, scaling);
    auto b = rebuilt.Search(queries, 10, scaling);
    ASSERT_TRUE(a.ok() && b.ok());
    ASSERT_EQ(a->size(), b->size());
    for (std::size_t r = 0; r < a->size(); ++r) {
      EXPECT_EQ((*a)[r].id, (*b)[r].id);
      EXPECT_EQ((*a)[r].distance, (*b)[r].distance);
      EXPECT_EQ((*a)[r].view, (*b)[r].view);
      EXPECT_EQ((*a)[r].query, (*b)[r].query);
    }
  }
}

// One-view galleries keep no row maps (rows are samples); the first sample with several
// views brings them in, and removing the last such sample takes them out again. Answers,
// views and features must not notice either switch.
TEST(KnnIndexTest, RowMapsComeAndGoWithMultiViewSamples) {
  KnnIndex index = MakeIndex(3);
  for (uint64_t i = 0; i < 40; ++i) {
    AddOrDie(index, i + 1, i % 2 == 0 ? "even" : "odd",
             {static_cast<float>(i), 0.5f * static_cast<float>(i % 7), 1.0f});
  }
  const std::vector<float> query = {20.2f, 3.0f, 1.0f, 7.1f, 0.0f, 1.0f};  // two query vectors
  auto before = index.Search(query, 6);
  ASSERT_TRUE(before.ok());
  // Two query vectors may meet one sample twice: it still takes one place.
  for (std::size_t a = 0; a < before->size(); ++a) {
    for (std::size_t b = a + 1; b < before->size(); ++b)
      EXPECT_NE((*before)[a].id, (*before)[b].id);
  }

  AddOrDie(index, 100, "many", {50, 0, 0, 20.2f, 3.0f, 1.0f, 60, 0, 0});
  EXPECT_EQ(index.size(), 41);
  EXPECT_EQ(index.num_rows(), 43);
  EXPECT_EQ(index.ViewsAt(40), 3);
  EXPECT_EQ(index.ViewsAt(39), 1);
  auto with = index.Search(query, 1);
  ASSERT_TRUE(with.ok());
  EXPECT_EQ((*with)[0].id, 100u);
  EXPECT_EQ((*with)[0].view, 1);
  EXPECT_EQ((*with)[0].distance, 0.0);

  ASSERT_TRUE(index.Remove(100).ok());
  EXPECT_EQ(index.num_rows(), 40);
  auto after = index.Search(query, 6);
  ASSERT_TRUE(after.ok());
  ASSERT_EQ(after->size(), before->size());
  for (std::size_t r = 0; r < after->size(); ++r) {
    EXPECT_EQ((*after)[r].id, (*before)[r].id);
    EXPECT_EQ((*after)[r].distance, (*before)[r].distance);
    EXPECT_EQ((*after)[r].query, (*before)[r].query);
  }
  EXPECT_EQ(index.Features(39), (std::vector<float>{39, 2, 1}));
}

TEST(KnnIndexTest, LabelCountsAndIdsWithLabelFollowAddAndRemove) {
  KnnIndex index = MakeIndex(1);
  for (uint64_t id = 1; id <= 6; ++id) {
    AddOrDie(index, id, id <= 2 ? "a" : (id <= 5 ? "b" : "c"), {static_cast<float>(id)});
  }
  using Count = std::pair<std::string, int64_t>;
  EXPECT_THAT(index.LabelCounts(), ElementsAre(Count{"a", 2}, Count{"b", 3}, Count{"c", 1}));
  EXPECT_THAT(index.IdsWithLabel("b"), ElementsAre(3, 4, 5));
  EXPECT_THAT(index.IdsWithLabel("z"), ElementsAre());
  ASSERT_TRUE(index.Remove(std::vector<uint64_t>{1, 2, 4}).ok());
  EXPECT_THAT(index.LabelCounts(), ElementsAre(Count{"b", 2}, Count{"c", 1}));
  EXPECT_THAT(index.IdsWithLabel("a"), ElementsAre());
  EXPECT_THAT(index.IdsWithLabel("b"), ElementsAre(3, 5));
}

// Every view is one observation of the statistics.
TEST(KnnIndexTest, ScalingStatisticsCountEveryView) {
  KnnIndex index = MakeIndex(2);
  AddOrDie(index, 1, "a", {0, 1, 2, 1, 4, 1});  // three views
  AddOrDie(index, 2, "b", {-8, 3});
  // Dimension 0: 0, 2, 4, -8: mean -0.5, population variance 20.75; max |x| 8.
  // Dimension 1: 1, 1, 1, 3: mean 1.5, variance 0.75; max |x| 3.
  const std::vector<float> zscore = index.ScaleFactors(FeatureScaling::kZScore);
  EXPECT_FLOAT_EQ(zscore[0], static_cast<float>(1 / std::sqrt(20.75)));
  EXPECT_FLOAT_EQ(zscore[1], static_cast<float>(1 / std::sqrt(0.75)));
  EXPECT_THAT(index.ScaleFactors(FeatureScaling::kMaxAbs), ElementsAre(0.125f, 1.0f / 3));
  ASSERT_TRUE(index.Remove(2).ok());
  EXPECT_THAT(index.ScaleFactors(FeatureScaling::kMaxAbs), ElementsAre(0.25f, 1.0f));
}

// The nearest (view, query) pair decides, and is reported; equal distances go to the
// earlier view, then the earlier query, then the earlier sample.
TEST(KnnIndexTest, TheClosestViewAndQueryDecide) {
  KnnIndex index = MakeIndex(1);
  AddOrDie(index, 1, "a", {10, 4, 6, -4});
  AddOrDie(index, 2, "b", {3});
  AddOrDie(index, 3, "c", {7, 5.5f});
  // One query at 5: sample 1 at 1 (views 1 and 2 tie: view 1), 3 at 0.5 (view 1), 2 at 2.
  auto got = index.Search(std::vector<float>{5}, 3);
  ASSERT_TRUE(got.ok()) << got.status();
  EXPECT_THAT(Ids(*got), ElementsAre(3, 1, 2));
  EXPECT_EQ((*got)[0].view, 1);
  EXPECT_EQ((*got)[0].distance, 0.5);
  EXPECT_EQ((*got)[1].view, 1);
  EXPECT_EQ((*got)[1].distance, 1.0);
  EXPECT_EQ((*got)[2].view, 0);

  // Queries 0 and -3: sample 1's view 3 (-4) is 1 from query 1; sample 2 (3) is 3 from
  // query 0.
  got = index.Search(std::vector<float>{0, -3}, 2);
  ASSERT_TRUE(got.ok());
  EXPECT_THAT(Ids(*got), ElementsAre(1, 2));
  EXPECT_EQ((*got)[0].distance, 1.0);
  EXPECT_EQ((*got)[0].view, 3);
  EXPECT_EQ((*got)[0].query, 1);
  EXPECT_EQ((*got)[1].distance, 3.0);
  EXPECT_EQ((*got)[1].query, 0);

  // Two queries equally close to the same view: the first query is reported.
  got = index.Search(std::vector<float>{2.75f, 3.25f}, 1);
  ASSERT_TRUE(got.ok());
  EXPECT_EQ((*got)[0].id, 2u);
  EXPECT_EQ((*got)[0].query, 0);

  // Samples at equal distance: the earlier-added one first.
  AddOrDie(index, 4, "d", {100, 2});
  got = index.Search(std::vector<float>{2.5f}, 2);
  ASSERT_TRUE(got.ok());
  EXPECT_THAT(Ids(*got), ElementsAre(2, 4));
}

// Nine views of one object next to the query take one neighbor place and one vote.
TEST(KnnIndexTest, ClassifyVotesOncePerSample) {
  KnnIndex index = MakeIndex(2);
  std::vector<float> many;
  for (int v = 0; v < 9; ++v) many.insert(many.end(), {0.01f * v, 0});
  AddOrDie(index, 1, "mug", many);
  AddOrDie(index, 2, "bowl", {1, 0});
  AddOrDie(index, 3, "bowl", {0, 1.5f});
  AddOrDie(index, 4, "mug", {5, 5});
  KnnOptions options;
  options.k = 3;
  auto result = index.Classify(std::vector<float>{0, 0}, options);
  ASSERT_TRUE(result.ok()) << result.status();
  EXPECT_THAT(Ids(result->neighbors), ElementsAre(1, 2, 3));
  EXPECT_EQ(result->label, "bowl");
  EXPECT_DOUBLE_EQ(result->confidence, 2.0 / 3);
  ASSERT_EQ(result->votes.size(), 2u);
  EXPECT_EQ(result->votes[1].label, "mug");
  EXPECT_EQ(result->votes[1].weight, 1.0);

  // A second query vector that sits on the far mug makes it a zero-distance neighbor.
  options.weighting = VoteWeighting::kDistance;
  result = index.Classify(std::vector<float>{0, 0.2f, 5, 5}, options);
  ASSERT_TRUE(result.ok());
  EXPECT_THAT(Ids(result->neighbors), ElementsAre(4, 1, 2));
  EXPECT_EQ(result->neighbors[0].query, 1);
  EXPECT_EQ(result->label, "mug");
  EXPECT_DOUBLE_EQ(result->confidence, 1.0);
}

TEST(KnnIndexTest, CopiesAreIndependent) {
  KnnIndex index = MakeIndex(1);
  for (uint64_t i = 0; i < 3000; ++i) AddOrDie(index, i, "a", {static_cast<float>(i)});
  ASSERT_TRUE(index.Search(std::vector<float>{1}, 1).ok());  // builds a kd-tree the copy shares
  KnnIndex copy = index;
  ASSERT_TRUE(copy.Remove(std::vector<uint64_t>{10}).ok());
  AddOrDie(copy, 5000, "b", {10.25f});
  auto original = index.Search(std::vector<float>{10.2f}, 1);
  auto changed = copy.Search(std::vector<float>{10.2f}, 1);
  ASSERT_TRUE(original.ok() && changed.ok());
  EXPECT_EQ((*original)[0].id, 10u);
  EXPECT_EQ((*changed)[0].id, 5000u);

  KnnIndex moved = std::move(copy);
  auto after_move = moved.Search(std::vector<float>{10.2f}, 1);
  ASSERT_TRUE(after_move.ok());
  EXPECT_EQ((*after_move)[0].id, 5000u);
}

// Queries are const and may run from many threads at once. For d = 3 (12k samples) the
// index switches from brute force to a kd-tree it builds during the run (after
// kKdTreeBuildAfterQueries queries); answers must not change.
TEST(KnnIndexTest, ConcurrentQueriesGiveIdenticalAnswers) {
  for (int d : {3, 81}) {
    std::mt19937 rng(d);
    std::uniform_real_distribution<float> uniform(0.0f, 1.0f);
    KnnIndex index = MakeIndex(d);
    for (uint64_t i = 0; i < 12000; ++i) {
      std::vector<float> x(d);
      for (float& v : x) v = uniform(rng);
      AddOrDie(index, i, absl::StrCat("c", i % 7), x);
    }
    std::vector<std::vector<float>> queries(40, std::vector<float>(d));
    for (auto& q : queries) {
      for (float& v : q) v = uniform(rng);
    }
    KnnOptions options;
    options.k = 5;
    options.weighting = VoteWeighting::kDistance;
    options.scaling = FeatureScaling::kZScore;

    constexpr int kThreads = 4;
    std::vector<std::vector<KnnResult>> answers(kThreads);
    std::vector<std::thread> threads;
    for (int t = 0; t < kThreads; ++t) {
      threads.emplace_back([&, t] {
        for (int rep = 0; rep < 4; ++rep) {  // 640 queries in all: the tree gets built
          for (std::size_t i = 0; i < queries.size(); ++i) {
            // Each thread walks the queries from a different start.
            const auto& q = queries[(i + static_cast<std::size_t>(t) * 10) % queries.size()];
            auto r = index.Classify(q, options);
            if (r.ok() && rep == 0) answers[t].push_back(*std::move(r));
          }
        }
      });
    }
    for (auto& th : threads) th.join();

    for (int t = 0; t < kThreads; ++t) {
      ASSERT_EQ(answers[t].size(), queries.size()) << t;
      for (std::size_t i = 0; i < queries.size(); ++i) {
        const std::size_t qi = (i + static_cast<std::size_t>(t) * 10) % queries.size();
        auto single = index.Classify(queries[qi], options);
        ASSERT_TRUE(single.ok());
        const KnnResult& got = answers[t][i];
        EXPECT_EQ(got.label, single->label);
        EXPECT_EQ(got.confidence, single->confidence);
        ASSERT_EQ(got.neighbors.size(), single->neighbors.size());
        for (std::size_t n = 0; n < got.neighbors.size(); ++n) {
          EXPECT_EQ(got.neighbors[n].id, single->neighbors[n].id);
          EXPECT_EQ(got.neighbors[n].distance, single->neighbors[n].distance);
        }
      }
    }
  }
}

}  // namespace
}  // namespace shapeid
