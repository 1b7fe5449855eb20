// The approximate index (inverted lists, knn_ivf.h) through KnnIndex: probing every cell
// is exact, bit for bit; the default probes find nearly every true neighbor on clustered
// data; the lists follow Add, Remove and growth; and a search never returns fewer than
// min(k, size()) neighbors.

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include "absl/strings/str_cat.h"
#include "core/knn/knn_index.h"
#include "core/random.h"
#include "gtest/gtest.h"

namespace shapeid {
namespace {

constexpr int kDim = 24;

// `n` samples around `clusters` centers (clustered, like descriptors of object classes),
// `views` vectors each, labeled by cluster.
struct Data {
  std::vector<std::vector<float>> samples;  // views * kDim floats each
  std::vector<int> cluster;
};

Data Clustered(int n, int clusters, int views, uint64_t seed) {
  SplitMix64 rng(seed);
  auto normal = [&rng] {
    // Box-Muller from the project's defined generator.
    const double u = std::max(rng.Uniform(), 1e-12), v = rng.Uniform();
    return static_cast<float>(std::sqrt(-2.0 * std::log(u)) * std::cos(6.283185307179586 * v));
  };
  std::vector<std::vector<float>> centers(static_cast<size_t>(clusters), std::vector<float>(kDim));
  for (auto& c : centers) {
    for (float& x : c) x = 10.0f * normal();
  }
  Data data;
  for (int i = 0; i < n; ++i) {
    const int c = static_cast<int>(rng.Next() % static_cast<uint64_t>(clusters));
    std::vector<float> features;
    for (int v = 0; v < views; ++v) {
      for (int j = 0; j < kDim; ++j)
        features.push_back(centers[static_cast<size_t>(c)][j] + normal());
    }
    data.samples.push_back(std::move(features));
    data.cluster.push_back(c);
  }
  return data;
}

KnnIndex Build(const Data& data) {
  KnnIndex index = KnnIndex::Create(kDim).value();
  for (size_t i = 0; i < data.samples.size(); ++i) {
    EXPECT_TRUE(index.Add(i + 1, absl::StrCat("c", data.cluster[i]), data.samples[i]).ok());
  }
  return index;
}

ApproximateOptions Approximate(int64_t min_vectors, int lists = 0, int probes = 0) {
  ApproximateOptions options;
  options.min_vectors = min_vectors;
  options.lists = lists;
  options.probes = probes;
  return options;
}

// Queries: perturbed copies of gallery vectors (a query near the gallery, as in use).
std::vector<std::vector<float>> Queries(const Data& data, int count, int vectors, uint64_t seed) {
  SplitMix64 rng(seed);
  std::vector<std::vector<float>> queries;
  for (int q = 0; q < count; ++q) {
    std::vector<float> query;
    for (int v = 0; v < vectors; ++v) {
      const auto& s = data.samples[rng.Next() % data.samples.size()];
      for (int j = 0; j < kDim; ++j) {
        query.push_back(s[static_cast<size_t>(j)] + static_cast<float>(rng.Uniform() - 0.5));
      }
    }
    queries.push_back(std::move(query));
  }
  return queries;
}

void ExpectSame(const std::vector<Neighbor>& got, const std::vector<Neighbor>& want) {
  ASSERT_EQ(got.size(), want.size());
  for (size_t i = 0; i < got.size(); ++i) {
    EXPECT_EQ(got[i].id, want[i].id) << "neighbor " << i;
    EXPECT_EQ(got[i].distance, want[i].distance) << "neighbor " << i;  // bit for bit
    EXPECT_EQ(got[i].view, want[i].view) << "neighbor " << i;
    EXPECT_EQ(got[i].query, want[i].query) << "neighbor " << i;
  }
}

TEST(KnnIvfTest, ProbingEveryCellIsExactBitForBit) {
  for (int views : {1, 3}) {
    for (int vectors : {1, 4}) {
      for (FeatureScaling scaling : {FeatureScaling::kNone, FeatureScaling::kZScore}) {
        SCOPED_TRACE(absl::StrCat("views ", views, " query vectors ", vectors, " scaling ",
                                  FeatureScalingName(scaling)));
        const Data data = Clustered(3000, 20, views, 7);
        KnnIndex index = Build(data);
        // 40 cells, every one probed: the lists hold every row but the last partial block,
        // which is the exact tail.
        ASSERT_TRUE(index.UpdateApproximate(Approximate(1, 40, 40), scaling).ok());
        ASSERT_TRUE(index.approximate());
        EXPECT_EQ(index.approximate_lists(), 40);
        EXPECT_EQ(index.approximate_filed_vectors(), index.num_rows() / 32 * 32);
        for (const auto& query : Queries(data, 20, vectors, 11)) {
          for (int k : {1, 5, 12}) {
            const auto got = index.Search(query, k, scaling).value();
            const auto want = index.Search(query, k, scaling, SearchMode::kExact).value();
            ExpectSame(got, want);
          }
        }
      }
    }
  }
}

TEST(KnnIvfTest, DefaultProbesFindNearlyEveryTrueNeighborOnClusteredData) {
  const Data data = Clustered(20000, 200, 1, 3);
  KnnIndex index = Build(data);
  ASSERT_TRUE(index.UpdateApproximate(Approximate(10000)).ok());
  ASSERT_TRUE(index.approximate());
  // sqrt(20000) ~ 141 cells.
  EXPECT_EQ(index.approximate_lists(), 141);
  int found = 0, wanted = 0, same_label = 0;
  const auto queries = Queries(data, 200, 1, 5);
  KnnOptions options;
  options.k = 5;
  for (const auto& query : queries) {
    const auto got = index.Search(query, 5).value();
    const auto want = index.Search(query, 5, FeatureScaling::kNone, SearchMode::kExact).value();
    for (const Neighbor& w : want) {
      ++wanted;
      found += std::any_of(got.begin(), got.end(), [&](const Neighbor& g) { return g.id == w.id; });
    }
    const KnnResult approximate = index.Classify(query, options).value();
    const KnnResult exact = index.Classify(query, options, SearchMode::kExact).value();
    EXPECT_TRUE(approximate.approximate);
    EXPECT_FALSE(exact.approximate);
    same_label += approximate.label == exact.label;
  }
  const double recall = static_cast<double>(found) / wanted;
  EXPECT_GE(recall, 0.95) << "recall@5 " << recall;
  EXPECT_GE(same_label, 198) << "of 200 answers, as the exact search's";
}

TEST(KnnIvfTest, BelowTheThresholdOrWithoutOneSearchesStayExact) {
  const Data data = Clustered(2000, 10, 1, 1);
  KnnIndex index = Build(data);
  ASSERT_TRUE(index.UpdateApproximate(Approximate(0)).ok());
  EXPECT_FALSE(index.approximate());
  ASSERT_TRUE(index.UpdateApproximate(Approximate(2001)).ok());
  EXPECT_FALSE(index.approximate());
  ASSERT_TRUE(index.UpdateApproximate(Approximate(2000)).ok());
  EXPECT_TRUE(index.approximate());
  // A gallery that shrinks below the threshold drops its lists at the next update.
  ASSERT_TRUE(index.Remove(1).ok());
  ASSERT_TRUE(index.UpdateApproximate(Approximate(2000)).ok());
  EXPECT_FALSE(index.approximate());
  KnnOptions options;
  EXPECT_FALSE(index.Classify(Queries(data, 1, 1, 2)[0], options).value().approximate);
}

TEST(KnnIvfTest, LowDimensionsKeepTheExactKdTree) {
  KnnIndex index = KnnIndex::Create(3).value();
  SplitMix64 rng(9);
  for (uint64_t id = 1; id <= 5000; ++id) {
    const float x[3] = {static_cast<float>(rng.Uniform()), static_cast<float>(rng.Uniform()),
                        static_cast<float>(rng.Uniform())};
    ASSERT_TRUE(index.Add(id, "a", x).ok());
  }
  ASSERT_TRUE(index.UpdateApproximate(Approximate(1)).ok());
  EXPECT_FALSE(index.approximate());
}

TEST(KnnIvfTest, InvalidOptionsChangeNothing) {
  KnnIndex index = Build(Clustered(1000, 5, 1, 4));
  ASSERT_TRUE(index.UpdateApproximate(Approximate(1, 8)).ok());
  for (const ApproximateOptions& bad : {Approximate(-1), Approximate(1, -2), Approximate(1, 0, -3),
                                        Approximate(1, ApproximateOptions::kMaxLists + 1)}) {
    const absl::Status status = index.UpdateApproximate(bad);
    EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument) << status;
    EXPECT_EQ(index.approximate_lists(), 8);
  }
}

TEST(KnnIvfTest, SamplesAddedSinceTheUpdateAreScannedExactly) {
  const Data data = Clustered(4000, 20, 1, 21);
  KnnIndex index = Build(data);
  ASSERT_TRUE(index.UpdateApproximate(Approximate(1000, 50, 1)).ok());
  const int64_t filed = index.approximate_filed_vectors();
  // A new sample far from every cell center: only the exact tail can find it.
  std::vector<float> far(kDim, 500.0f);
  ASSERT_TRUE(index.Add(99999, "far", far).ok());
  EXPECT_EQ(index.approximate_filed_vectors(), filed);
  const auto got = index.Search(far, 1).value();
  ASSERT_EQ(got.size(), 1u);
  EXPECT_EQ(got[0].id, 99999u);
  EXPECT_EQ(got[0].distance, 0.0);

  // A few more are not worth filing yet; more than 1/16 of the filed rows are.
  ASSERT_TRUE(index.UpdateApproximate(Approximate(1000, 50, 1)).ok());
  EXPECT_EQ(index.approximate_filed_vectors(), filed);
  const Data more = Clustered(400, 20, 1, 22);
  for (size_t i = 0; i < more.samples.size(); ++i) {
    ASSERT_TRUE(index.Add(200000 + i, "more", more.samples[i]).ok());
  }
  ASSERT_TRUE(index.UpdateApproximate(Approximate(1000, 50, 1)).ok());
  EXPECT_EQ(index.approximate_filed_vectors(), index.num_rows() / 32 * 32);
  EXPECT_EQ(index.approximate_lists(), 50);  // filed into the old cells, not retrained
  // Every probe: exact again, now with the new rows in the lists.
  ASSERT_TRUE(index.UpdateApproximate(Approximate(1000, 50, 50)).ok());
  for (const auto& query : Queries(more, 10, 1, 23)) {
    ExpectSame(index.Search(query, 3).value(),
               index.Search(query, 3, FeatureScaling::kNone, SearchMode::kExact).value());
  }
}

TEST(KnnIvfTest, GrowingFourfoldRetrainsTheCells) {
  const Data data = Clustered(8000, 20, 1, 31);
  KnnIndex index = KnnIndex::Create(kDim).value();
  for (size_t i = 0; i < 2000; ++i) ASSERT_TRUE(index.Add(i + 1, "a", data.samples[i]).ok());
  ASSERT_TRUE(index.UpdateApproximate(Approximate(1000)).ok());
  // round(sqrt(2000)) = 45 cells would average under 64 rows: 1984 / 64 = 31.
  EXPECT_EQ(index.approximate_lists(), 31);
  for (size_t i = 2000; i < 8000; ++i) ASSERT_TRUE(index.Add(i + 1, "a", data.samples[i]).ok());
  ASSERT_TRUE(index.UpdateApproximate(Approximate(1000)).ok());
  EXPECT_EQ(index.approximate_lists(), 89);  // round(sqrt(8000)): trained again
  EXPECT_EQ(index.approximate_filed_vectors(), 8000);
}

TEST(KnnIvfTest, RemovedSamplesLeaveTheListsAndTheRestIsRenumbered) {
  const Data data = Clustered(3000, 20, 2, 41);
  KnnIndex index = Build(data);
  ASSERT_TRUE(index.UpdateApproximate(Approximate(1000, 30, 30)).ok());
  std::vector<uint64_t> doomed;
  for (uint64_t id = 1; id <= 3000; id += 3) doomed.push_back(id);
  ASSERT_TRUE(index.Remove(doomed).ok());
  ASSERT_TRUE(index.approximate());
  // The kept filed rows, down to a whole block; the rows after them are the exact tail.
  EXPECT_LE(index.approximate_filed_vectors(), index.num_rows());
  EXPECT_GT(index.approximate_filed_vectors(), index.num_rows() - 64);
  EXPECT_EQ(index.approximate_filed_vectors() % 32, 0);
  for (const auto& query : Queries(data, 20, 2, 42)) {
    const auto got = index.Search(query, 7).value();
    ExpectSame(got, index.Search(query, 7, FeatureScaling::kNone, SearchMode::kExact).value());
    for (const Neighbor& n : got) EXPECT_NE(n.id % 3, 1u) << "removed sample " << n.id;
  }
}

TEST(KnnIvfTest, ProbedCellsWithFewerThanKSamplesFallBackToExact) {
  const Data data = Clustered(2048, 64, 1, 51);
  KnnIndex index = Build(data);
  ASSERT_TRUE(index.UpdateApproximate(Approximate(1, 32, 1)).ok());
  KnnOptions options;
  options.k = 2048;  // more than any one cell holds
  const KnnResult result = index.Classify(Queries(data, 1, 1, 52)[0], options).value();
  EXPECT_EQ(result.neighbors.size(), 2048u);
  EXPECT_FALSE(result.approximate);
}

TEST(KnnIvfTest, CopiesShareTheListsAndAnswerAlike) {
  const Data data = Clustered(3000, 20, 1, 61);
  KnnIndex index = Build(data);
  ASSERT_TRUE(index.UpdateApproximate(Approximate(1000, 50, 2)).ok());
  const KnnIndex copy = index;
  EXPECT_TRUE(copy.approximate());
  for (const auto& query : Queries(data, 10, 1, 62)) {
    ExpectSame(copy.Search(query, 4).value(), index.Search(query, 4).value());
  }
}

TEST(KnnIvfTest, BuildingTwiceGivesTheSameLists) {
  const Data data = Clustered(5000, 30, 1, 71);
  KnnIndex a = Build(data);
  KnnIndex b = Build(data);
  ASSERT_TRUE(a.UpdateApproximate(Approximate(1000, 40, 3)).ok());
  ASSERT_TRUE(b.UpdateApproximate(Approximate(1000, 40, 3)).ok());
  for (const auto& query : Queries(data, 20, 1, 72)) {
    ExpectSame(a.Search(query, 5).value(), b.Search(query, 5).value());
  }
}

}  // namespace
}  // namespace shapeid
