// The search engines against a plain double-precision reference, and against each other:
// every SIMD level and the kd-tree must return the same neighbours with bit-identical
// distances.

#include <algorithm>
#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "absl/strings/str_cat.h"
#include "core/knn/knn_index.h"
#include "core/simd.h"
#include "gtest/gtest.h"

namespace shapeid {
namespace {

using Engine = KnnIndex::Engine;

struct Gallery {
  int dim = 0;
  std::vector<std::vector<float>> rows;
};

// Normal features around different centres per dimension, with about one sample in ten an
// exact copy of an earlier one so that exact ties occur.
Gallery RandomGallery(int n, int dim, uint32_t seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<float> normal(0.0f, 1.0f);
  Gallery g;
  g.dim = dim;
  for (int i = 0; i < n; ++i) {
    if (i > 0 && rng() % 10 == 0) {
      g.rows.push_back(g.rows[rng() % g.rows.size()]);
      continue;
    }
    std::vector<float> x(dim);
    for (int j = 0; j < dim; ++j)
      x[j] = static_cast<float>(j % 5) * 3.0f + normal(rng) * (1 + j % 3);
    g.rows.push_back(x);
  }
  return g;
}

// Scale factors straight from the definitions, in double.
std::vector<double> ReferenceScale(const Gallery& g, FeatureScaling scaling) {
  std::vector<double> w(g.dim, 1.0);
  if (scaling == FeatureScaling::kNone) return w;
  const double n = static_cast<double>(g.rows.size());
  for (int j = 0; j < g.dim; ++j) {
    if (scaling == FeatureScaling::kMaxAbs) {
      double m = 0;
      for (const auto& r : g.rows) m = std::max(m, std::fabs(static_cast<double>(r[j])));
      w[j] = m > 0 ? 1 / m : 1;
    } else {
      double mean = 0;
      for (const auto& r : g.rows) mean += r[j];
      mean /= n;
      double var = 0;
      for (const auto& r : g.rows) var += (r[j] - mean) * (r[j] - mean);
      const double sd = std::sqrt(var / n);
      w[j] = sd > 0 ? 1 / sd : 1;
    }
  }
  return w;
}

std::vector<double> ReferenceDistances(const Gallery& g, const std::vector<double>& w,
                                       const std::vector<float>& q) {
  std::vector<double> dist;
  for (const auto& r : g.rows) {
    double s = 0;
    for (int j = 0; j < g.dim; ++j) {
      const double e = (static_cast<double>(q[j]) - r[j]) * w[j];
      s += e * e;
    }
    dist.push_back(std::sqrt(s));
  }
  return dist;
}

std::vector<SimdLevel> AvailableLevels() {
  std::vector<SimdLevel> levels = {SimdLevel::kScalar};
  if (DetectedSimdLevel() >= SimdLevel::kAvx2) levels.push_back(SimdLevel::kAvx2);
  if (DetectedSimdLevel() >= SimdLevel::kAvx512) levels.push_back(SimdLevel::kAvx512);
  return levels;
}

KnnIndex BuildIndex(const Gallery& g) {
  KnnIndex index = *KnnIndex::Create(g.dim);
  for (std::size_t i = 0; i < g.rows.size(); ++i) {
    // Ids unrelated to insertion order, so tie order is checked on slots, not ids.
    EXPECT_TRUE(index.Add(1000003 * (i + 1) % 999983, absl::StrCat("c", i % 4), g.rows[i]).ok());
  }
  return index;
}

// Checks one engine answer against the reference: the i-th distance matches the i-th
// smallest reference distance, and each returned sample really is at that distance (so a
// different id is allowed only between near-equal distances, where float and double
// rounding may order them differently).
void ExpectMatchesReference(const std::vector<Neighbor>& got, const std::vector<double>& ref,
                            const std::vector<uint64_t>& slot_ids, std::size_t k,
                            const std::string& where) {
  std::vector<std::size_t> order(ref.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::stable_sort(order.begin(), order.end(),
                   [&](std::size_t a, std::size_t b) { return ref[a] < ref[b]; });
  const std::size_t want = std::min(k, ref.size());
  ASSERT_EQ(got.size(), want) << where;
  for (std::size_t i = 0; i < want; ++i) {
    const double tol = 1e-5 * ref[order[i]] + 1e-6;
    EXPECT_NEAR(got[i].distance, ref[order[i]], tol) << where << " rank " << i;
    const auto slot = static_cast<std::size_t>(
        std::find(slot_ids.begin(), slot_ids.end(), got[i].id) - slot_ids.begin());
    ASSERT_LT(slot, slot_ids.size()) << where;
    EXPECT_NEAR(ref[slot], ref[order[i]], tol) << where << " rank " << i;
    if (i > 0) {
      EXPECT_LE(got[i - 1].distance, got[i].distance) << where;
    }
  }
}

void ExpectIdentical(const std::vector<Neighbor>& a, const std::vector<Neighbor>& b,
                     const std::string& where) {
  ASSERT_EQ(a.size(), b.size()) << where;
  for (std::size_t i = 0; i < a.size(); ++i) {
    EXPECT_EQ(a[i].id, b[i].id) << where << " rank " << i;
    EXPECT_EQ(a[i].distance, b[i].distance) << where << " rank " << i;  // bit-identical
    EXPECT_EQ(a[i].label, b[i].label) << where << " rank " << i;
  }
}

TEST(KnnEngineTest, EveryLevelAndEngineMatchesTheReference) {
  const FeatureScaling kScalings[] = {FeatureScaling::kNone, FeatureScaling::kZScore,
                                      FeatureScaling::kMaxAbs};
  for (int n : {1, 7, 8, 9, 31, 32, 33, 100, 1000}) {
    for (int dim : {1, 6, 81, 100}) {
      const Gallery g = RandomGallery(n, dim, static_cast<uint32_t>(n * 131 + dim));
      const KnnIndex index = BuildIndex(g);
      std::vector<uint64_t> slot_ids;
      for (std::size_t i = 0; i < g.rows.size(); ++i) {
        slot_ids.push_back(1000003 * (i + 1) % 999983);
      }
      // Queries: fresh points, and gallery samples themselves (distance 0, ties).
      std::vector<std::vector<float>> queries = RandomGallery(4, dim, 7 + dim).rows;
      queries.push_back(g.rows[g.rows.size() / 2]);
      for (FeatureScaling scaling : kScalings) {
        const std::vector<double> w = ReferenceScale(g, scaling);
        for (std::size_t qi = 0; qi < queries.size(); ++qi) {
          const std::vector<double> ref = ReferenceDistances(g, w, queries[qi]);
          for (int k : {1, 5, n + 3}) {
            const std::string where = absl::StrCat(
                "n=", n, " d=", dim, " ", FeatureScalingName(scaling), " q=", qi, " k=", k);
            auto baseline = index.SearchForTesting(queries[qi], k, scaling, SimdLevel::kScalar,
                                                   Engine::kBruteForce);
            ASSERT_TRUE(baseline.ok()) << baseline.status();
            ExpectMatchesReference(*baseline, ref, slot_ids, static_cast<std::size_t>(k), where);
            for (SimdLevel level : AvailableLevels()) {
              auto got =
                  index.SearchForTesting(queries[qi], k, scaling, level, Engine::kBruteForce);
              ASSERT_TRUE(got.ok()) << got.status();
              ExpectIdentical(*got, *baseline, absl::StrCat(where, " ", SimdLevelName(level)));
            }
            auto tree =
                index.SearchForTesting(queries[qi], k, scaling, ActiveSimdLevel(), Engine::kKdTree);
            ASSERT_TRUE(tree.ok()) << tree.status();
            ExpectIdentical(*tree, *baseline, absl::StrCat(where, " kd-tree"));
          }
        }
      }
    }
  }
}

// Integer features on a small grid: many exact ties at every rank, including across the
// k-th place, where a kd-tree visiting leaves out of order is most likely to differ.
TEST(KnnEngineTest, KdTreeReproducesBruteForceTiesExactly) {
  for (int dim : {1, 2, 3, 6}) {
    std::mt19937 rng(dim);
    Gallery g;
    g.dim = dim;
    for (int i = 0; i < 4000; ++i) {
      std::vector<float> x(dim);
      for (float& v : x) v = static_cast<float>(rng() % 5);
      g.rows.push_back(x);
    }
    const KnnIndex index = BuildIndex(g);
    for (FeatureScaling scaling :
         {FeatureScaling::kNone, FeatureScaling::kZScore, FeatureScaling::kMaxAbs}) {
      for (int qi = 0; qi < 20; ++qi) {
        std::vector<float> q(dim);
        for (float& v : q) v = static_cast<float>(rng() % 9) * 0.5f;
        for (int k : {1, 4, 10, 57}) {
          const std::string where =
              absl::StrCat("d=", dim, " ", FeatureScalingName(scaling), " q=", qi, " k=", k);
          auto brute =
              index.SearchForTesting(q, k, scaling, ActiveSimdLevel(), Engine::kBruteForce);
          auto tree = index.SearchForTesting(q, k, scaling, ActiveSimdLevel(), Engine::kKdTree);
          auto automatic = index.Search(q, k, scaling);
          ASSERT_TRUE(brute.ok() && tree.ok() && automatic.ok()) << where;
          ExpectIdentical(*tree, *brute, where);
          ExpectIdentical(*automatic, *brute, where);
        }
      }
    }
  }
}

// Every sample identical: the kd-tree cannot split, and every distance ties.
TEST(KnnEngineTest, IdenticalSamplesComeBackInInsertionOrder) {
  Gallery g;
  g.dim = 3;
  g.rows.assign(3000, std::vector<float>{1.5f, -2.0f, 0.25f});
  const KnnIndex index = BuildIndex(g);
  for (Engine engine : {Engine::kBruteForce, Engine::kKdTree}) {
    auto got = index.SearchForTesting(std::vector<float>{0, 0, 0}, 5, FeatureScaling::kZScore,
                                      ActiveSimdLevel(), engine);
    ASSERT_TRUE(got.ok()) << got.status();
    ASSERT_EQ(got->size(), 5u);
    for (std::size_t i = 0; i < 5; ++i) {
      EXPECT_EQ((*got)[i].id, 1000003 * (i + 1) % 999983) << i;
    }
  }
}

// Features far apart in magnitude: large offsets (cancellation in q - x), tiny spreads
// (large zscore factors) and values near zero.
TEST(KnnEngineTest, KdTreeMatchesOnBadlyScaledFeatures) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> uniform(-1.0f, 1.0f);
  Gallery g;
  g.dim = 4;
  for (int i = 0; i < 3000; ++i) {
    g.rows.push_back({1e6f + uniform(rng), 1e-20f * uniform(rng), uniform(rng) * 1e4f,
                      static_cast<float>(i % 3)});
  }
  const KnnIndex index = BuildIndex(g);
  for (FeatureScaling scaling :
       {FeatureScaling::kNone, FeatureScaling::kZScore, FeatureScaling::kMaxAbs}) {
    for (int qi = 0; qi < 30; ++qi) {
      const std::vector<float> q =
          qi % 2 ? g.rows[static_cast<std::size_t>(qi) * 7]
                 : std::vector<float>{1e6f + uniform(rng), 0.0f, uniform(rng) * 1e4f, 1.0f};
      const std::string where = absl::StrCat(FeatureScalingName(scaling), " q=", qi);
      auto brute = index.SearchForTesting(q, 8, scaling, ActiveSimdLevel(), Engine::kBruteForce);
      auto tree = index.SearchForTesting(q, 8, scaling, ActiveSimdLevel(), Engine::kKdTree);
      ASSERT_TRUE(brute.ok() && tree.ok()) << where;
      ExpectIdentical(*tree, *brute, where);
    }
  }
}

}  // namespace
}  // namespace shapeid
