// The search engines against a plain double-precision reference, against a naive float
// double loop over views and query vectors, and against each other: every SIMD level, with
// and without early abandonment, and the kd-tree must return the same neighbors with
// bit-identical distances.

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <string>
#include <utility>
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

// Normal features around different centers per dimension, with about one sample in ten an
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

// ---- Several views per sample, several query vectors. ----

uint64_t IdOf(std::size_t sample) { return 1000003 * (sample + 1) % 999983; }

// Samples of 1..max_views views each (views * dim floats). Dimension j has spread
// 1 / (1 + j / 8), like DFSD's low-frequency-first coefficients, so that blocks are
// abandoned after the first dimensions; the views of one sample scatter around a center.
// About one sample in eight repeats an earlier sample's view, and one view in eight
// repeats the sample's previous view, so that exact ties occur across and within samples.
std::vector<std::vector<float>> MultiViewGallery(int n, int dim, int max_views, uint32_t seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<float> normal(0.0f, 1.0f);
  std::vector<std::vector<float>> samples;
  for (int i = 0; i < n; ++i) {
    const int views = 1 + static_cast<int>(rng() % static_cast<unsigned>(max_views));
    std::vector<float> center(dim);
    for (int j = 0; j < dim; ++j) center[j] = normal(rng) / (1.0f + static_cast<float>(j) / 8);
    std::vector<float> x;
    for (int v = 0; v < views; ++v) {
      if (v > 0 && rng() % 8 == 0) {
        x.insert(x.end(), x.end() - dim, x.end());
      } else if (i > 0 && rng() % 8 == 0) {
        const std::vector<float>& other = samples[rng() % samples.size()];
        x.insert(x.end(), other.begin(), other.begin() + dim);
      } else {
        for (int j = 0; j < dim; ++j) x.push_back(center[j] + 0.3f * normal(rng) * center[j]);
      }
    }
    samples.push_back(std::move(x));
  }
  return samples;
}

KnnIndex BuildMultiViewIndex(int dim, const std::vector<std::vector<float>>& samples) {
  KnnIndex index = *KnnIndex::Create(dim);
  for (std::size_t i = 0; i < samples.size(); ++i) {
    EXPECT_TRUE(index.Add(IdOf(i), absl::StrCat("c", i % 4), samples[i]).ok());
  }
  return index;
}

// The definition, as a naive double loop: each sample's best (squared distance, view,
// query) over all pairs, in the kernels' float arithmetic and tie order; samples sorted by
// (distance, insertion order).
struct Expected {
  std::size_t sample;
  float distance_sq;
  int view;
  int query;
};

std::vector<Expected> NaiveNearest(const std::vector<std::vector<float>>& samples, int dim,
                                   const std::vector<float>& scale,
                                   const std::vector<float>& queries) {
  const std::size_t d = static_cast<std::size_t>(dim);
  std::vector<Expected> best;
  for (std::size_t i = 0; i < samples.size(); ++i) {
    Expected e{i, std::numeric_limits<float>::infinity(), 0, 0};
    for (std::size_t v = 0; v * d < samples[i].size(); ++v) {
      for (std::size_t q = 0; q * d < queries.size(); ++q) {
        float acc = 0.0f;
        for (std::size_t j = 0; j < d; ++j) {
          const float diff = (queries[q * d + j] - samples[i][v * d + j]) * scale[j];
          acc = acc + diff * diff;
        }
        if (acc < e.distance_sq) e = Expected{i, acc, static_cast<int>(v), static_cast<int>(q)};
      }
    }
    best.push_back(e);
  }
  std::stable_sort(best.begin(), best.end(), [](const Expected& a, const Expected& b) {
    return a.distance_sq < b.distance_sq;
  });
  return best;
}

void ExpectNaive(const std::vector<Neighbor>& got, const std::vector<Expected>& want, std::size_t k,
                 const std::string& where) {
  ASSERT_EQ(got.size(), std::min(k, want.size())) << where;
  for (std::size_t i = 0; i < got.size(); ++i) {
    EXPECT_EQ(got[i].id, IdOf(want[i].sample)) << where << " rank " << i;
    EXPECT_EQ(got[i].label, absl::StrCat("c", want[i].sample % 4)) << where << " rank " << i;
    EXPECT_EQ(got[i].distance, std::sqrt(static_cast<double>(want[i].distance_sq)))
        << where << " rank " << i;
    EXPECT_EQ(got[i].view, want[i].view) << where << " rank " << i;
    EXPECT_EQ(got[i].query, want[i].query) << where << " rank " << i;
  }
}

TEST(KnnEngineTest, DistinctSamplesMatchANaiveDoubleLoop) {
  const FeatureScaling kScalings[] = {FeatureScaling::kNone, FeatureScaling::kZScore,
                                      FeatureScaling::kMaxAbs};
  for (int dim : {1, 5, 40, 240}) {
    for (int max_views : {1, 4, 9}) {
      // 1..max_views views each: 60 to about 300 rows, never a whole number of blocks.
      const int n = 60 + 7 * max_views;
      const auto samples = MultiViewGallery(n, dim, max_views, static_cast<uint32_t>(dim + n));
      const KnnIndex index = BuildMultiViewIndex(dim, samples);
      for (int num_queries : {1, 4, 9}) {
        // Query vectors: fresh points, a copy of a stored view (distance 0) and one close
        // to a stored view.
        std::vector<float> queries;
        const auto fresh = MultiViewGallery(num_queries, dim, 1, static_cast<uint32_t>(dim * 7));
        for (int q = 0; q < num_queries; ++q) {
          if (q == 1) {
            queries.insert(queries.end(), samples[n / 2].begin(), samples[n / 2].begin() + dim);
          } else if (q == 2) {
            for (int j = 0; j < dim; ++j) queries.push_back(samples[n / 3][j] + 0.01f);
          } else {
            queries.insert(queries.end(), fresh[q].begin(), fresh[q].begin() + dim);
          }
        }
        for (FeatureScaling scaling : kScalings) {
          const std::vector<Expected> want =
              NaiveNearest(samples, dim, index.ScaleFactors(scaling), queries);
          for (int k : {1, 3, 7}) {
            for (SimdLevel level : AvailableLevels()) {
              for (bool abandon : {true, false}) {
                const std::string where =
                    absl::StrCat("d=", dim, " views<=", max_views, " queries=", num_queries, " ",
                                 FeatureScalingName(scaling), " k=", k, " ", SimdLevelName(level),
                                 abandon ? " abandon" : " no-abandon");
                auto got = index.SearchForTesting(queries, k, scaling, level, Engine::kBruteForce,
                                                  abandon);
                ASSERT_TRUE(got.ok()) << got.status();
                ExpectNaive(*got, want, static_cast<std::size_t>(k), where);
              }
            }
          }
        }
      }
    }
  }
}

// A large gallery of near-identical objects, one query close to a late one: blocks are
// abandoned at every check, after the first dimensions and deep in the vector, and the
// last block is a partial one. Abandonment must not change a single bit.
TEST(KnnEngineTest, EarlyAbandonmentChangesNothing) {
  for (int dim : {33, 81, 240}) {
    const auto samples = MultiViewGallery(700, dim, 3, static_cast<uint32_t>(dim));
    const KnnIndex index = BuildMultiViewIndex(dim, samples);
    std::vector<float> queries(samples[650].begin(), samples[650].begin() + dim);
    for (int j = 0; j < dim; ++j) queries[static_cast<std::size_t>(j)] += 1e-3f;
    const auto more = MultiViewGallery(3, dim, 1, 5);
    for (const auto& q : more) queries.insert(queries.end(), q.begin(), q.end());
    for (FeatureScaling scaling :
         {FeatureScaling::kNone, FeatureScaling::kZScore, FeatureScaling::kMaxAbs}) {
      for (int k : {1, 2, 50}) {
        for (SimdLevel level : AvailableLevels()) {
          const std::string where = absl::StrCat("d=", dim, " ", FeatureScalingName(scaling),
                                                 " k=", k, " ", SimdLevelName(level));
          auto with = index.SearchForTesting(queries, k, scaling, level, Engine::kBruteForce);
          auto without = index.SearchForTesting(queries, k, scaling, level, Engine::kBruteForce,
                                                /*early_abandon=*/false);
          ASSERT_TRUE(with.ok() && without.ok()) << where;
          ExpectIdentical(*with, *without, where);
          ExpectNaive(*with, NaiveNearest(samples, dim, index.ScaleFactors(scaling), queries),
                      static_cast<std::size_t>(k), where);
        }
      }
    }
  }
}

// Query 0 sets the k-th at distance 0 on a later sample; query 1 then finds an earlier
// sample, in the same block, at distance 0 too. The earlier sample must win: neither the
// emission test nor abandonment may drop a candidate that only ties the k-th.
TEST(KnnEngineTest, TiesFoundByALaterQueryGoToTheEarlierSample) {
  const int dim = 40;
  const auto samples = MultiViewGallery(40, dim, 1, 9);  // rows 5 and 20 in block 0
  const KnnIndex index = BuildMultiViewIndex(dim, samples);
  std::vector<float> queries = samples[20];
  queries.insert(queries.end(), samples[5].begin(), samples[5].end());
  for (SimdLevel level : AvailableLevels()) {
    for (bool abandon : {true, false}) {
      const std::string where =
          absl::StrCat(SimdLevelName(level), abandon ? " abandon" : " no-abandon");
      auto got = index.SearchForTesting(queries, 1, FeatureScaling::kNone, level,
                                        Engine::kBruteForce, abandon);
      ASSERT_TRUE(got.ok()) << where;
      ASSERT_EQ(got->size(), 1u) << where;
      EXPECT_EQ((*got)[0].id, IdOf(5)) << where;
      EXPECT_EQ((*got)[0].distance, 0.0) << where;
      EXPECT_EQ((*got)[0].view, 0) << where;
      EXPECT_EQ((*got)[0].query, 1) << where;
    }
  }
}

// The kd-tree serves one-view galleries and one-vector queries only; otherwise every
// engine, forced or automatic, answers by brute force with the same result.
TEST(KnnEngineTest, KdTreeStepsAsideForViewsAndSeveralQueries) {
  const int dim = 3;
  const auto one_view_samples = MultiViewGallery(12000, dim, 1, 3);
  auto two_view_samples = one_view_samples;
  two_view_samples[5000].insert(two_view_samples[5000].end(), {0.5f, 0.5f, 0.25f});
  const KnnIndex one_view = BuildMultiViewIndex(dim, one_view_samples);
  const KnnIndex two_views = BuildMultiViewIndex(dim, two_view_samples);
  const std::vector<float> one = {0.5f, 0.5f, 0.25f};
  const std::vector<float> two = {1.0f, -1.0f, 0.0f, 0.5f, 0.5f, 0.25f};
  const std::pair<const KnnIndex*, const std::vector<std::vector<float>>*> galleries[] = {
      {&one_view, &one_view_samples}, {&two_views, &two_view_samples}};
  for (const auto& [index, samples] : galleries) {
    for (const std::vector<float>* queries : {&one, &two}) {
      const std::vector<Expected> want =
          NaiveNearest(*samples, dim, index->ScaleFactors(FeatureScaling::kZScore), *queries);
      for (Engine engine : {Engine::kAuto, Engine::kBruteForce, Engine::kKdTree}) {
        const std::string where = absl::StrCat(index->num_rows(), " rows, ", queries->size() / dim,
                                               " queries, engine ", static_cast<int>(engine));
        auto got = index->SearchForTesting(*queries, 5, FeatureScaling::kZScore, ActiveSimdLevel(),
                                           engine);
        ASSERT_TRUE(got.ok()) << where;
        ExpectNaive(*got, want, 5, where);
      }
    }
  }
}

}  // namespace
}  // namespace shapeid
