// KnnIndex's copies share their blocks: what a copy shares, that a change to a copy leaves
// the original alone, removal across block boundaries, and answers equal to a naive loop.

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <string>
#include <tuple>
#include <vector>

#include "absl/strings/str_cat.h"
#include "core/knn/knn_index.h"
#include "gtest/gtest.h"

namespace shapeid {
namespace {

constexpr int kDim = 2048;  // 256 rows per block (knn_feature_storage.h)

std::vector<float> RandomRow(std::mt19937& rng, int views = 1) {
  std::uniform_int_distribution<int> level(0, 7);  // coarse: many ties
  std::vector<float> row(static_cast<std::size_t>(kDim * views));
  for (float& x : row) x = static_cast<float>(level(rng)) * 0.25f;
  return row;
}

// The naive answer: every sample at its least distance over views, computed in float in the
// kernels' order, ties to the earlier sample (then view).
std::vector<std::tuple<float, uint64_t, int>> Naive(const KnnIndex& index,
                                                    const std::vector<float>& query, int k,
                                                    FeatureScaling scaling) {
  const std::vector<float> scale = index.ScaleFactors(scaling);
  std::vector<std::tuple<float, int64_t, int>> best;
  for (int64_t s = 0; s < index.size(); ++s) {
    const std::vector<float> features = index.Features(s);
    float least = 0;
    int view = -1;
    for (int v = 0; v < index.ViewsAt(s); ++v) {
      float acc = 0.0f;
      for (int j = 0; j < kDim; ++j) {
        float e =
            query[static_cast<std::size_t>(j)] - features[static_cast<std::size_t>(v * kDim + j)];
        e = e * scale[static_cast<std::size_t>(j)];
        acc = acc + e * e;
      }
      if (view < 0 || acc < least) least = acc, view = v;
    }
    best.emplace_back(least, s, view);
  }
  std::sort(best.begin(), best.end());
  best.resize(std::min<std::size_t>(best.size(), static_cast<std::size_t>(k)));
  std::vector<std::tuple<float, uint64_t, int>> out;
  for (const auto& [d, s, v] : best) out.emplace_back(d, index.IdAt(s), v);
  return out;
}

void ExpectMatchesNaive(const KnnIndex& index, std::mt19937& rng) {
  for (FeatureScaling scaling : {FeatureScaling::kNone, FeatureScaling::kZScore}) {
    for (int k : {1, 7, 50}) {
      const std::vector<float> query = RandomRow(rng);
      auto found = index.Search(query, k, scaling);
      ASSERT_TRUE(found.ok()) << found.status();
      const auto expected = Naive(index, query, k, scaling);
      ASSERT_EQ(found->size(), expected.size());
      for (std::size_t i = 0; i < expected.size(); ++i) {
        const auto& [d, id, view] = expected[i];
        EXPECT_EQ((*found)[i].id, id) << "k " << k << " rank " << i;
        EXPECT_EQ((*found)[i].distance, std::sqrt(static_cast<double>(d)));
        EXPECT_EQ((*found)[i].view, view);
      }
    }
  }
}

TEST(KnnIndexCopyTest, CopySharesEveryBlockAndAddCopiesOnlyTheLast) {
  std::mt19937 rng(1);
  KnnIndex original = *KnnIndex::Create(kDim);
  for (uint64_t id = 1; id <= 1000; ++id) ASSERT_TRUE(original.Add(id, "a", RandomRow(rng)).ok());
  const auto& storage = original.StorageForTesting();
  ASSERT_EQ(storage.num_blocks(), 4);  // 256 rows per block, the last one part full

  KnnIndex copy = original;
  for (int64_t b = 0; b < storage.num_blocks(); ++b) {
    EXPECT_EQ(copy.StorageForTesting().block_address(b), storage.block_address(b));
  }
  ASSERT_TRUE(copy.Add(5000, "b", RandomRow(rng)).ok());
  for (int64_t b = 0; b < 3; ++b) {
    EXPECT_EQ(copy.StorageForTesting().block_address(b), storage.block_address(b));
  }
  EXPECT_NE(copy.StorageForTesting().block_address(3), storage.block_address(3));

  // The original is as it was.
  EXPECT_EQ(original.size(), 1000);
  EXPECT_FALSE(original.Contains(5000));
  EXPECT_EQ(original.num_labels(), 1);
  EXPECT_EQ(copy.size(), 1001);
  EXPECT_TRUE(copy.Contains(5000));
  EXPECT_EQ(copy.LabelAt(1000), "b");
  ExpectMatchesNaive(original, rng);
  ExpectMatchesNaive(copy, rng);
}

TEST(KnnIndexCopyTest, StatisticsOfACopyAreItsOwn) {
  std::mt19937 rng(2);
  KnnIndex original = *KnnIndex::Create(kDim);
  for (uint64_t id = 1; id <= 300; ++id) ASSERT_TRUE(original.Add(id, "a", RandomRow(rng)).ok());
  const std::vector<float> before = original.ScaleFactors(FeatureScaling::kZScore);
  KnnIndex copy = original;
  std::vector<float> far(kDim, 100.0f);
  ASSERT_TRUE(copy.Add(999, "far", far).ok());
  EXPECT_EQ(original.ScaleFactors(FeatureScaling::kZScore), before);
  EXPECT_NE(copy.ScaleFactors(FeatureScaling::kZScore), before);
}

// Removal across block boundaries, with several views per sample: the result equals an index
// built from the samples left, bit for bit, and the original copy is untouched.
TEST(KnnIndexCopyTest, RemovalAcrossBlocksEqualsARebuild) {
  std::mt19937 rng(3);
  KnnIndex original = *KnnIndex::Create(kDim);
  std::vector<std::vector<float>> features;
  for (uint64_t id = 1; id <= 400; ++id) {
    features.push_back(RandomRow(rng, id % 7 == 0 ? 3 : 1));
    ASSERT_TRUE(original.Add(id, absl::StrCat("c", id % 5), features.back()).ok());
  }
  ASSERT_GT(original.num_rows(), 2 * 256);
  KnnIndex removed = original;
  std::vector<uint64_t> doomed;
  for (uint64_t id = 260; id <= 330; ++id) doomed.push_back(id);  // rows ~ 334 to ~ 424
  doomed.push_back(400);
  ASSERT_TRUE(removed.Remove(doomed).ok());
  // Blocks before the one of the first removed row stay shared.
  EXPECT_EQ(removed.StorageForTesting().block_address(0),
            original.StorageForTesting().block_address(0));

  KnnIndex rebuilt = *KnnIndex::Create(kDim);
  for (uint64_t id = 1; id <= 400; ++id) {
    if (std::find(doomed.begin(), doomed.end(), id) != doomed.end()) continue;
    ASSERT_TRUE(rebuilt.Add(id, absl::StrCat("c", id % 5), features[id - 1]).ok());
  }
  ASSERT_EQ(removed.size(), rebuilt.size());
  ASSERT_EQ(removed.num_rows(), rebuilt.num_rows());
  for (int64_t s = 0; s < rebuilt.size(); ++s) {
    ASSERT_EQ(removed.IdAt(s), rebuilt.IdAt(s));
    ASSERT_EQ(removed.LabelAt(s), rebuilt.LabelAt(s));
    ASSERT_EQ(removed.Features(s), rebuilt.Features(s));
  }
  EXPECT_EQ(removed.LabelCounts(), rebuilt.LabelCounts());
  for (FeatureScaling s : {FeatureScaling::kZScore, FeatureScaling::kMaxAbs}) {
    EXPECT_EQ(removed.ScaleFactors(s), rebuilt.ScaleFactors(s));
  }
  EXPECT_EQ(original.size(), 400);
  EXPECT_TRUE(original.Contains(300));
  ExpectMatchesNaive(removed, rng);
  ExpectMatchesNaive(original, rng);
}

}  // namespace
}  // namespace shapeid
