// kNN engine benchmarks: single-query latency of KnnIndex against the cost of reading the
// gallery once, and brute force against a nanoflann kd-tree.
//
//   build/knn-release/bench/knn_bench --benchmark_repetitions=5
//       --benchmark_report_aggregates_only=true
//
// Galleries are uniform random in [0, 1)^d (fixed seed); queries are drawn from the same
// distribution, 64 of them cycled so no query is answered from a warm cache by accident.
// The multi-view cases (BM_MultiView*) model issue 13's robot galleries instead: 3,991
// samples of 1 or 9 views of 240 features with a decaying spectrum. Figures go to
// docs/performance.md.

#include <algorithm>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "absl/strings/str_cat.h"
#include "benchmark/benchmark.h"
#include "core/knn/knn_index.h"
#include "core/knn/knn_kd_tree.h"
#include "core/knn/knn_kernels.h"
#include "core/simd.h"
#include "nanoflann.hpp"

#if defined(__x86_64__) || defined(__i386__)
#include <immintrin.h>
#endif

namespace shapeid {
namespace {

constexpr int kNumQueries = 64;

std::vector<float> RandomFloats(std::size_t count, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> uniform(0.0f, 1.0f);
  std::vector<float> v(count);
  for (float& x : v) x = uniform(rng);
  return v;
}

struct Gallery {
  int dim;
  int64_t n;
  std::vector<float> rows;     // row-major, for nanoflann
  std::vector<float> queries;  // kNumQueries rows
  std::unique_ptr<KnnIndex> index;
};

// Built once per (d, n) and kept: building 100k x 640 takes a while.
const Gallery& GetGallery(int dim, int64_t n) {
  static auto* cache = new std::vector<std::unique_ptr<Gallery>>();
  for (const auto& g : *cache) {
    if (g->dim == dim && g->n == n) return *g;
  }
  // Keep at most one large gallery alive so several 100k x 640 ones do not pile up.
  if (!cache->empty() && static_cast<double>(n) * dim > 1e6) {
    for (auto& g : *cache) {
      if (static_cast<double>(g->n) * g->dim > 1e6) g.reset();
    }
    cache->erase(std::remove(cache->begin(), cache->end(), nullptr), cache->end());
  }
  auto g = std::make_unique<Gallery>();
  g->dim = dim;
  g->n = n;
  g->rows = RandomFloats(static_cast<std::size_t>(n) * dim, 1234);
  g->queries = RandomFloats(static_cast<std::size_t>(kNumQueries) * dim, 99);
  g->index = std::make_unique<KnnIndex>(*KnnIndex::Create(dim));
  for (int64_t i = 0; i < n; ++i) {
    const absl::Span<const float> x(g->rows.data() + i * dim, static_cast<std::size_t>(dim));
    if (!g->index->Add(static_cast<uint64_t>(i), i % 2 == 0 ? "even" : "odd", x).ok()) {
      std::abort();
    }
  }
  cache->push_back(std::move(g));
  return *cache->back();
}

absl::Span<const float> Query(const Gallery& g, int64_t i) {
  return absl::Span<const float>(g.queries.data() + (i % kNumQueries) * g.dim,
                                 static_cast<std::size_t>(g.dim));
}

void SetCounters(benchmark::State& state, const Gallery& g) {
  state.SetItemsProcessed(state.iterations() * g.n);  // gallery samples compared
  state.SetBytesProcessed(state.iterations() * g.n * g.dim * static_cast<int64_t>(sizeof(float)));
}

// ---- The floor: read every float of a gallery-sized array once. ----

#if defined(__x86_64__) || defined(__i386__)
__attribute__((target("avx512f"))) float SumAvx512(const float* p, std::size_t count) {
  __m512 a0 = _mm512_setzero_ps(), a1 = _mm512_setzero_ps();
  __m512 a2 = _mm512_setzero_ps(), a3 = _mm512_setzero_ps();
  std::size_t i = 0;
  for (; i + 64 <= count; i += 64) {
    a0 = _mm512_add_ps(a0, _mm512_load_ps(p + i));
    a1 = _mm512_add_ps(a1, _mm512_load_ps(p + i + 16));
    a2 = _mm512_add_ps(a2, _mm512_load_ps(p + i + 32));
    a3 = _mm512_add_ps(a3, _mm512_load_ps(p + i + 48));
  }
  // Not _mm512_reduce_add_ps: GCC 12 warns (-Wuninitialized) inside it.
  alignas(64) float lanes[16];
  _mm512_store_ps(lanes, _mm512_add_ps(_mm512_add_ps(a0, a1), _mm512_add_ps(a2, a3)));
  float s = 0.0f;
  for (float x : lanes) s += x;
  for (; i < count; ++i) s += p[i];
  return s;
}

__attribute__((target("avx2"))) float SumAvx2(const float* p, std::size_t count) {
  __m256 a0 = _mm256_setzero_ps(), a1 = _mm256_setzero_ps();
  __m256 a2 = _mm256_setzero_ps(), a3 = _mm256_setzero_ps();
  std::size_t i = 0;
  for (; i + 32 <= count; i += 32) {
    a0 = _mm256_add_ps(a0, _mm256_load_ps(p + i));
    a1 = _mm256_add_ps(a1, _mm256_load_ps(p + i + 8));
    a2 = _mm256_add_ps(a2, _mm256_load_ps(p + i + 16));
    a3 = _mm256_add_ps(a3, _mm256_load_ps(p + i + 24));
  }
  alignas(32) float lanes[8];
  _mm256_store_ps(lanes, _mm256_add_ps(_mm256_add_ps(a0, a1), _mm256_add_ps(a2, a3)));
  float s = 0.0f;
  for (float x : lanes) s += x;
  for (; i < count; ++i) s += p[i];
  return s;
}
#endif

float SumFloats(const float* p, std::size_t count) {
#if defined(__x86_64__) || defined(__i386__)
  switch (ActiveSimdLevel()) {
    case SimdLevel::kAvx512:
      return SumAvx512(p, count);
    case SimdLevel::kAvx2:
      return SumAvx2(p, count);
    case SimdLevel::kScalar:
      break;
  }
#endif
  float s = 0.0f;
  for (std::size_t i = 0; i < count; ++i) s += p[i];
  return s;
}

// Args: d, n. Reads an array the size of the index's blocked storage (padding included).
void BM_ReadGalleryOnce(benchmark::State& state) {
  const int dim = static_cast<int>(state.range(0));
  const int64_t n = state.range(1);
  const int64_t blocks = (n + knn_internal::kBlockLanes - 1) / knn_internal::kBlockLanes;
  knn_internal::AlignedFloats storage(static_cast<std::size_t>(blocks) *
                                      knn_internal::BlockFloats(dim));
  const std::vector<float> fill = RandomFloats(storage.size(), 7);
  std::copy(fill.begin(), fill.end(), storage.begin());
  for (auto _ : state) {
    benchmark::DoNotOptimize(storage.data());
    float s = SumFloats(storage.data(), storage.size());
    benchmark::DoNotOptimize(s);
    benchmark::ClobberMemory();
  }
  state.SetItemsProcessed(state.iterations() * n);
  state.SetBytesProcessed(state.iterations() *
                          static_cast<int64_t>(storage.size() * sizeof(float)));
  state.SetLabel(std::string(SimdLevelName(ActiveSimdLevel())));
}

// ---- KnnIndex: public Search (engine chosen automatically). Args: d, n, k. ----

void BM_KnnSearch(benchmark::State& state) {
  const Gallery& g = GetGallery(static_cast<int>(state.range(0)), state.range(1));
  const int k = static_cast<int>(state.range(2));
  // Enough queries for the index to build its kd-tree when it uses one.
  for (int64_t w = 0; w <= knn_internal::kKdTreeBuildAfterQueries; ++w) {
    auto warm = g.index->Search(Query(g, w), k);
    benchmark::DoNotOptimize(warm);
  }
  int64_t i = 0;
  for (auto _ : state) {
    auto result = g.index->Search(Query(g, i++), k);
    benchmark::DoNotOptimize(result);
  }
  SetCounters(state, g);
  state.SetLabel(std::string(SimdLevelName(ActiveSimdLevel())));
}

// Brute force forced, at one SIMD level. Args: d, n, k, level.
void BM_BruteForce(benchmark::State& state) {
  const Gallery& g = GetGallery(static_cast<int>(state.range(0)), state.range(1));
  const int k = static_cast<int>(state.range(2));
  const auto level = static_cast<SimdLevel>(state.range(3));
  if (level > DetectedSimdLevel()) {
    state.SkipWithError("SIMD level not supported on this CPU");
    return;
  }
  int64_t i = 0;
  for (auto _ : state) {
    auto result = g.index->SearchForTesting(Query(g, i++), k, FeatureScaling::kNone, level,
                                            KnnIndex::Engine::kBruteForce);
    benchmark::DoNotOptimize(result);
  }
  SetCounters(state, g);
  state.SetLabel(std::string(SimdLevelName(level)));
}

// KnnIndex's exact kd-tree engine (nanoflann with the engine's metric and tie rules); the
// tree is built before timing. Args: d, n, k.
void BM_KnnKdTree(benchmark::State& state) {
  const Gallery& g = GetGallery(static_cast<int>(state.range(0)), state.range(1));
  const int k = static_cast<int>(state.range(2));
  auto warm = g.index->SearchForTesting(Query(g, 0), k, FeatureScaling::kNone, ActiveSimdLevel(),
                                        KnnIndex::Engine::kKdTree);
  benchmark::DoNotOptimize(warm);
  int64_t i = 0;
  for (auto _ : state) {
    auto result = g.index->SearchForTesting(Query(g, i++), k, FeatureScaling::kNone,
                                            ActiveSimdLevel(), KnnIndex::Engine::kKdTree);
    benchmark::DoNotOptimize(result);
  }
  SetCounters(state, g);
}

// ---- A plain nanoflann kd-tree (L2, float), as the nanoflann examples use it. ----

struct RowsAdaptor {
  const Gallery* g;
  std::size_t kdtree_get_point_count() const { return static_cast<std::size_t>(g->n); }
  float kdtree_get_pt(std::size_t i, std::size_t j) const { return g->rows[i * g->dim + j]; }
  template <class BBox>
  bool kdtree_get_bbox(BBox&) const {
    return false;
  }
};
using PlainTree =
    nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<float, RowsAdaptor>,
                                        RowsAdaptor, -1, uint32_t>;

// Args: d, n, k.
void BM_NanoflannKdTree(benchmark::State& state) {
  const Gallery& g = GetGallery(static_cast<int>(state.range(0)), state.range(1));
  const auto k = static_cast<std::size_t>(state.range(2));
  RowsAdaptor adaptor{&g};
  PlainTree tree(g.dim, adaptor, nanoflann::KDTreeSingleIndexAdaptorParams(16));
  std::vector<uint32_t> ids(k);
  std::vector<float> dists(k);
  int64_t i = 0;
  for (auto _ : state) {
    nanoflann::KNNResultSet<float, uint32_t> result(k);
    result.init(ids.data(), dists.data());
    tree.findNeighbors(result, Query(g, i++).data(), nanoflann::SearchParams());
    benchmark::DoNotOptimize(ids.data());
    benchmark::DoNotOptimize(dists.data());
  }
  SetCounters(state, g);
}

// Args: d, n. Time to build the plain tree: about what KnnIndex pays when it decides to
// build its own.
void BM_NanoflannBuild(benchmark::State& state) {
  const Gallery& g = GetGallery(static_cast<int>(state.range(0)), state.range(1));
  RowsAdaptor adaptor{&g};
  for (auto _ : state) {
    PlainTree tree(g.dim, adaptor, nanoflann::KDTreeSingleIndexAdaptorParams(16));
    benchmark::DoNotOptimize(&tree);
  }
  state.SetItemsProcessed(state.iterations() * g.n);
}

// ---- Issue 13: samples of several views, queries of several vectors. ----

constexpr int kRobotSamples = 3991;
constexpr int kRobotDim = 240;

// Feature j of every view is uniform in [0, 1 / (1 + j / 8)): like DFSD, whose DCT
// coefficients come low frequency first, most of a distance is in the first dimensions.
float Spread(int j) { return 1.0f / (1.0f + static_cast<float>(j) / 8); }

struct RobotGallery {
  int views;
  std::vector<float> rows;  // kRobotSamples * views rows of kRobotDim
  std::unique_ptr<KnnIndex> index;
};

const RobotGallery& GetRobotGallery(int views) {
  static auto* cache = new std::vector<std::unique_ptr<RobotGallery>>();
  for (const auto& g : *cache) {
    if (g->views == views) return *g;
  }
  auto g = std::make_unique<RobotGallery>();
  g->views = views;
  const std::size_t sample_floats = static_cast<std::size_t>(views) * kRobotDim;
  g->rows = RandomFloats(kRobotSamples * sample_floats, 4321);
  for (std::size_t i = 0; i < g->rows.size(); ++i) g->rows[i] *= Spread(i % kRobotDim);
  g->index = std::make_unique<KnnIndex>(*KnnIndex::Create(kRobotDim));
  for (int i = 0; i < kRobotSamples; ++i) {
    const absl::Span<const float> x(g->rows.data() + i * sample_floats, sample_floats);
    if (!g->index->Add(static_cast<uint64_t>(i), absl::StrCat("c", i % 40), x).ok()) {
      std::abort();
    }
  }
  cache->push_back(std::move(g));
  return *cache->back();
}

// kNumQueries query sets of `count` vectors each. Random: fresh points from the gallery's
// distribution, where the nearest sample is hardly nearer than the rest (the hard case for
// abandonment). Near: vector 0 is a stored view plus 5 % noise, the others fresh points,
// as when one of a robot's pose variants matches the object it sees.
std::vector<std::vector<float>> RobotQueries(const RobotGallery& g, int count, bool near) {
  std::mt19937 rng(77);
  std::uniform_real_distribution<float> uniform(0.0f, 1.0f);
  std::normal_distribution<float> noise(0.0f, 0.05f);
  std::vector<std::vector<float>> sets;
  for (int s = 0; s < kNumQueries; ++s) {
    std::vector<float> set(static_cast<std::size_t>(count) * kRobotDim);
    for (std::size_t i = 0; i < set.size(); ++i) set[i] = uniform(rng) * Spread(i % kRobotDim);
    if (near) {
      const std::size_t row = rng() % (g.rows.size() / kRobotDim);
      for (int j = 0; j < kRobotDim; ++j) {
        set[j] = g.rows[row * kRobotDim + j] + noise(rng) * Spread(j);
      }
    }
    sets.push_back(std::move(set));
  }
  return sets;
}

void SetRobotCounters(benchmark::State& state, const RobotGallery& g, int queries) {
  // (stored view, query vector) pairs compared.
  state.SetItemsProcessed(state.iterations() * g.index->num_rows() * queries);
}

// Brute force at one SIMD level, with or without early abandonment: the abandonment
// speed-up is the ratio of the two. Args: views, query vectors, k, near, abandon, level.
void BM_MultiView(benchmark::State& state) {
  const RobotGallery& g = GetRobotGallery(static_cast<int>(state.range(0)));
  const int num_queries = static_cast<int>(state.range(1));
  const int k = static_cast<int>(state.range(2));
  const auto sets = RobotQueries(g, num_queries, state.range(3) != 0);
  const bool abandon = state.range(4) != 0;
  const auto level = static_cast<SimdLevel>(state.range(5));
  if (level > DetectedSimdLevel()) {
    state.SkipWithError("SIMD level not supported on this CPU");
    return;
  }
  int64_t i = 0;
  for (auto _ : state) {
    auto result = g.index->SearchForTesting(sets[i++ % kNumQueries], k, FeatureScaling::kNone,
                                            level, KnnIndex::Engine::kBruteForce, abandon);
    benchmark::DoNotOptimize(result);
  }
  SetRobotCounters(state, g, num_queries);
  state.SetLabel(absl::StrCat(SimdLevelName(level), abandon ? " abandon" : " full"));
}

// The public Classify (ActiveSimdLevel(); SHAPEID_SIMD=avx2 lowers it), with the median
// and 99th percentile of single calls as counters (p50_us, p99_us): what a robot waits.
// Args: views, query vectors, k, near.
void BM_MultiViewClassify(benchmark::State& state) {
  const RobotGallery& g = GetRobotGallery(static_cast<int>(state.range(0)));
  const int num_queries = static_cast<int>(state.range(1));
  KnnOptions options;
  options.k = static_cast<int>(state.range(2));
  const auto sets = RobotQueries(g, num_queries, state.range(3) != 0);
  std::vector<double> micros;
  int64_t i = 0;
  for (auto _ : state) {
    const auto start = std::chrono::steady_clock::now();
    auto result = g.index->Classify(sets[i++ % kNumQueries], options);
    benchmark::DoNotOptimize(result);
    micros.push_back(
        std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - start)
            .count());
  }
  std::sort(micros.begin(), micros.end());
  state.counters["p50_us"] = micros[micros.size() / 2];
  state.counters["p99_us"] = micros[micros.size() * 99 / 100];
  SetRobotCounters(state, g, num_queries);
  state.SetLabel(std::string(SimdLevelName(ActiveSimdLevel())));
}

// The headline: 100k x 81 (32 MB), k = 1 and 5, against reading the gallery once; also
// 400k x 81 (130 MB, past a 32 MB last-level cache), d = 6 and d = 640.
BENCHMARK(BM_ReadGalleryOnce)
    ->Args({81, 100000})
    ->Args({81, 400000})
    ->Args({6, 100000})
    ->Args({640, 100000})
    ->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_KnnSearch)
    ->Args({81, 100000, 1})
    ->Args({81, 100000, 5})
    ->Args({81, 400000, 5})
    ->Args({6, 100000, 1})
    ->Args({6, 100000, 5})
    ->Args({640, 100000, 1})
    ->Args({640, 100000, 5})
    ->Unit(benchmark::kMicrosecond);

// Brute force at each SIMD level (0 scalar, 1 avx2, 2 avx512), 100k x 81, k = 5.
BENCHMARK(BM_BruteForce)
    ->ArgsProduct({{81}, {100000}, {5}, {0, 1, 2}})
    ->Unit(benchmark::kMicrosecond);

// Brute force vs kd-tree: d in {6, 81, 300}, n in {1k, 10k, 100k}, k = 5.
BENCHMARK(BM_BruteForce)
    ->ArgsProduct({{6, 81, 300}, {1000, 10000, 100000}, {5}, {2}})
    ->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_NanoflannKdTree)
    ->ArgsProduct({{6, 81, 300}, {1000, 10000, 100000}, {5}})
    ->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_KnnKdTree)
    ->ArgsProduct({{6, 81, 300}, {1000, 10000, 100000}, {5}})
    ->Unit(benchmark::kMicrosecond);
// Where the kd-tree starts to win: d in {3, 8, 12, 16}, n in {5k, 20k, 100k}.
BENCHMARK(BM_BruteForce)
    ->ArgsProduct({{3, 8, 12, 16}, {5000, 20000, 100000}, {5}, {2}})
    ->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_KnnKdTree)
    ->ArgsProduct({{3, 8, 12, 16}, {5000, 20000, 100000}, {5}})
    ->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_NanoflannBuild)
    ->ArgsProduct({{6}, {1000, 10000, 100000}})
    ->Unit(benchmark::kMillisecond);

// Issue 13: 3,991 samples x {1, 9} views x 240, {1, 9} query vectors, k = 1 and 5, random
// and near queries; abandonment on and off, AVX2 and AVX-512.
BENCHMARK(BM_MultiView)
    ->ArgsProduct({{1, 9}, {1, 9}, {1, 5}, {0, 1}, {1, 0}, {1, 2}})
    ->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_MultiViewClassify)
    ->ArgsProduct({{1, 9}, {1, 9}, {1, 5}, {0, 1}})
    ->Unit(benchmark::kMicrosecond);

}  // namespace
}  // namespace shapeid

BENCHMARK_MAIN();
