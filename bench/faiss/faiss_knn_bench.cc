// Issue 7: exact kNN of KnnIndex against Faiss's IndexFlatL2 and a plain nanoflann kd-tree,
// single queries and batches, plus Faiss's approximate indexes (IVF-Flat, HNSW-Flat) at 10^6
// samples: the latency-vs-recall points a future approximate gallery index has to beat.
//
//   build/helper-faiss/bench/faiss/faiss_knn_bench --json faiss_bench.json
//
// A plain program rather than Google Benchmark: recall, build times and memory are one-shot
// figures, and within each repetition the engines of one gallery are timed in turn, so a
// noisy neighbor on a shared VM hits them alike. Every figure is the median of --reps.
// Threads: single queries run on one thread everywhere (omp_set_num_threads(1) for Faiss);
// batches are timed with one and with two threads. See README.md for the setup.

#include <malloc.h>
#include <omp.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <functional>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "CLI/CLI.hpp"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/strings/str_join.h"
#include "absl/types/span.h"
#include "core/knn/knn_index.h"
#include "core/knn/knn_kd_tree.h"
#include "core/simd.h"
#include "faiss/IndexFlat.h"
#include "faiss/IndexHNSW.h"
#include "faiss/IndexIVFFlat.h"
#include "faiss/utils/distances.h"
#include "nanoflann.hpp"

namespace shapeid {
namespace {

using Clock = std::chrono::steady_clock;
using FaissId = faiss::Index::idx_t;

// The largest batch; single queries and smaller batches cycle through this many, so no
// query is answered from a warm cache by accident.
constexpr int kQueryPool = 256;

struct Options {
  std::vector<int> dims = {6, 81, 240, 640};
  std::vector<int64_t> sizes = {1000, 10000, 100000, 1000000};
  int k = 5;
  std::vector<int> k1_dims = {81};  // also k = 1, single queries, n >= 10^5
  std::vector<int> batches = {16, 256};
  // A batch runs only where n * d * batch stays under this: the per-query loop of a batch
  // of 256 over 10^6 x 640 would take ~15 s per repetition.
  double batch_max_work = 7e10;
  int nanoflann_max_dim = 81;
  double nanoflann_max_floats = 1e7;
  int reps = 3;
  double min_seconds = 0.2;  // per engine and repetition
  std::vector<int> ann_dims = {81, 240};
  int64_t ann_size = 1000000;
  int ann_queries = 300;
  int nlist = 1024;
  std::vector<int> nprobes = {1, 8, 32, 128};
  int hnsw_m = 32;
  // HNSW builds take ~1 ms per sample and thread on uniform 81-d data on the reference VM
  // (shrinking neighbor lists dominates), 20-30 minutes at 10^6: by default only on the
  // mixture.
  std::vector<std::string> hnsw_distributions = {"mixture"};
  std::vector<int> ef_searches = {16, 32, 64, 128, 256};
  std::string json_path;
};

double SecondsSince(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

double Median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0.0 : v[v.size() / 2];
}

// Resident set size after handing free heap pages back, so that deltas count live data.
int64_t ResidentBytes() {
  malloc_trim(0);
  std::ifstream statm("/proc/self/statm");
  int64_t total_pages = 0, resident_pages = 0;
  statm >> total_pages >> resident_pages;
  return resident_pages * sysconf(_SC_PAGESIZE);
}

// Records as one JSON array, written as they come so a crash keeps what was measured.
class JsonWriter {
 public:
  explicit JsonWriter(const std::string& path) {
    if (!path.empty()) out_.open(path);
    if (out_) out_ << "[\n";
  }
  ~JsonWriter() {
    if (out_) out_ << "\n]\n";
  }
  void Write(const std::string& object) {
    if (!out_) return;
    out_ << (first_ ? "" : ",\n") << object;
    out_.flush();
    first_ = false;
  }

 private:
  std::ofstream out_;
  bool first_ = true;
};

enum class Distribution { kUniform, kMixture };
const char* DistributionName(Distribution d) {
  return d == Distribution::kUniform ? "uniform" : "mixture";
}

// Rows of a synthetic gallery or query set, drawn in order from a fixed seed. Uniform: every
// feature in [0, 1), the worst case for an approximate index (no structure to exploit,
// distances concentrate). Mixture: 1,000 Gaussians of standard deviation 0.1 per feature
// around centers uniform in [0, 1)^d (the same centers for gallery and queries), a stand-in
// for descriptors that cluster by object and class.
class RowSource {
 public:
  static constexpr int kComponents = 1000;

  RowSource(Distribution distribution, int dim, uint32_t seed)
      : distribution_(distribution), dim_(dim), rng_(seed) {
    if (distribution_ != Distribution::kMixture) return;
    std::mt19937 center_rng(2024);
    centers_.resize(static_cast<std::size_t>(kComponents) * dim_);
    for (float& c : centers_) c = uniform_(center_rng);
  }

  void Fill(float* row) {
    if (distribution_ == Distribution::kUniform) {
      for (int j = 0; j < dim_; ++j) row[j] = uniform_(rng_);
      return;
    }
    const float* center = centers_.data() + static_cast<std::size_t>(rng_() % kComponents) * dim_;
    for (int j = 0; j < dim_; ++j) row[j] = center[j] + normal_(rng_);
  }

  std::vector<float> Rows(int count) {
    std::vector<float> rows(static_cast<std::size_t>(count) * dim_);
    for (int i = 0; i < count; ++i) Fill(rows.data() + static_cast<std::size_t>(i) * dim_);
    return rows;
  }

 private:
  Distribution distribution_;
  int dim_;
  std::mt19937 rng_;
  std::uniform_real_distribution<float> uniform_{0.0f, 1.0f};
  std::normal_distribution<float> normal_{0.0f, 0.1f};
  std::vector<float> centers_;
};

// One gallery held twice: by KnnIndex (blocked layout) and by Faiss (row-major, which the
// nanoflann adaptor and the approximate indexes read too). Sample i has id i.
struct Gallery {
  Distribution distribution;
  int dim;
  int64_t n;
  std::unique_ptr<KnnIndex> index;
  std::unique_ptr<faiss::IndexFlatL2> flat;
  std::vector<float> queries;  // kQueryPool rows
  double index_seconds = 0, flat_seconds = 0;
  int64_t index_bytes = 0, flat_bytes = 0;  // resident set deltas

  absl::Span<const float> Query(int64_t i) const {
    return absl::Span<const float>(queries.data() + (i % kQueryPool) * dim,
                                   static_cast<std::size_t>(dim));
  }
};

std::unique_ptr<Gallery> BuildGallery(Distribution distribution, int dim, int64_t n) {
  auto g = std::make_unique<Gallery>();
  g->distribution = distribution;
  g->dim = dim;
  g->n = n;
  constexpr int64_t kChunkRows = 4096;
  std::vector<float> chunk(static_cast<std::size_t>(kChunkRows) * dim);
  RowSource source(distribution, dim, 1234);

  int64_t before = ResidentBytes();
  g->index = std::make_unique<KnnIndex>(*KnnIndex::Create(dim));
  for (int64_t first = 0; first < n; first += kChunkRows) {
    const int64_t rows = std::min(kChunkRows, n - first);
    for (int64_t r = 0; r < rows; ++r) source.Fill(chunk.data() + r * dim);
    const auto start = Clock::now();  // Add only, not the random numbers
    for (int64_t r = 0; r < rows; ++r) {
      const absl::Span<const float> x(chunk.data() + r * dim, static_cast<std::size_t>(dim));
      const int64_t id = first + r;
      if (!g->index->Add(static_cast<uint64_t>(id), id % 2 == 0 ? "even" : "odd", x).ok()) {
        std::abort();
      }
    }
    g->index_seconds += SecondsSince(start);
  }
  g->index_bytes = ResidentBytes() - before;

  before = ResidentBytes();
  g->flat = std::make_unique<faiss::IndexFlatL2>(dim);
  // Exactly n rows: growing by doubling would leave a transient second copy of 2.6 GB at
  // 10^6 x 640.
  g->flat->codes.reserve(static_cast<std::size_t>(n) * dim * sizeof(float));
  for (int64_t first = 0; first < n; first += kChunkRows) {
    const int64_t rows = std::min(kChunkRows, n - first);
    for (int64_t r = 0; r < rows; ++r) g->index->CopyFeatures(first + r, chunk.data() + r * dim);
    const auto start = Clock::now();
    g->flat->add(rows, chunk.data());
    g->flat_seconds += SecondsSince(start);
  }
  g->flat_bytes = ResidentBytes() - before;

  g->queries = RowSource(distribution, dim, 99).Rows(kQueryPool);
  return g;
}

// A plain nanoflann kd-tree (L2, float, leaves of 16) over Faiss's row-major copy, as
// bench/knn_bench.cc builds it.
struct RowsAdaptor {
  const float* rows;
  int dim;
  int64_t n;
  std::size_t kdtree_get_point_count() const { return static_cast<std::size_t>(n); }
  float kdtree_get_pt(std::size_t i, std::size_t j) const { return rows[i * dim + j]; }
  template <class BBox>
  bool kdtree_get_bbox(BBox&) const {
    return false;
  }
};
using NanoflannTree =
    nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<float, RowsAdaptor>,
                                        RowsAdaptor, -1, uint32_t>;

// One timed engine setting: run(call) answers `batch` queries.
struct Case {
  std::string engine;
  int threads;
  int batch;
  int k;
  std::function<void(int64_t call)> run;
  std::vector<double> micros_per_query;  // one per repetition
};

double MicrosPerQuery(const Case& c, double min_seconds) {
  int64_t calls = 0;
  const auto start = Clock::now();
  double elapsed = 0;
  do {
    c.run(calls++);
    elapsed = SecondsSince(start);
  } while (elapsed < min_seconds);
  return elapsed * 1e6 / static_cast<double>(calls * c.batch);
}

void CheckOk(bool ok) {
  if (!ok) std::abort();
}

// The machine's 1-minute load average: on a shared VM, the context of every figure.
double LoadAverage() {
  std::ifstream loadavg("/proc/loadavg");
  double one_minute = 0;
  loadavg >> one_minute;
  return one_minute;
}

std::string GalleryJson(const Gallery& g) {
  return absl::StrCat("\"dist\":\"", DistributionName(g.distribution), "\",\"d\":", g.dim,
                      ",\"n\":", g.n);
}

// The exact engines on one gallery; with `single_only`, just one-query KnnIndex and Faiss
// flat (the reference rows of the approximate table).
void RunExact(const Gallery& g, const Options& o, bool single_only, JsonWriter& json) {
  const KnnIndex& index = *g.index;
  const faiss::IndexFlatL2& flat = *g.flat;
  std::vector<float> distances(static_cast<std::size_t>(kQueryPool) * o.k);
  std::vector<FaissId> labels(distances.size());
  std::vector<Case> cases;
  auto add = [&cases](std::string engine, int threads, int batch, int neighbors,
                      std::function<void(int64_t)> run) {
    cases.push_back(Case{std::move(engine), threads, batch, neighbors, std::move(run), {}});
  };

  std::vector<int> ks = {o.k};
  if (!single_only && g.n >= 100000 && std::count(o.k1_dims.begin(), o.k1_dims.end(), g.dim) > 0) {
    ks.push_back(1);
  }
  for (const int k : ks) {
    add("shapeid", 1, 1, k,
        [&index, &g, k](int64_t call) { CheckOk(index.Search(g.Query(call), k).ok()); });
    if (g.dim <= knn_internal::kKdTreeMaxDimension) {
      add("shapeid_brute_force", 1, 1, k, [&index, &g, k](int64_t call) {
        CheckOk(index
                    .SearchForTesting(g.Query(call), k, FeatureScaling::kNone, ActiveSimdLevel(),
                                      KnnIndex::Engine::kBruteForce)
                    .ok());
      });
    }
    add("faiss_flat", 1, 1, k, [&](int64_t call) {
      omp_set_num_threads(1);
      flat.search(1, g.Query(call).data(), k, distances.data(), labels.data());
    });
  }

  std::unique_ptr<NanoflannTree> tree;
  RowsAdaptor adaptor{flat.get_xb(), g.dim, g.n};
  double tree_seconds = 0;
  if (!single_only && g.dim <= o.nanoflann_max_dim &&
      static_cast<double>(g.n) * g.dim <= o.nanoflann_max_floats) {
    const auto start = Clock::now();
    try {  // nanoflann reports failure by exception; none leaves this block
      tree = std::make_unique<NanoflannTree>(g.dim, adaptor,
                                             nanoflann::KDTreeSingleIndexAdaptorParams(16));
    } catch (const std::exception& e) {
      std::fprintf(stderr, "nanoflann failed: %s\n", e.what());
    }
    tree_seconds = SecondsSince(start);
  }
  if (tree != nullptr) {
    add("nanoflann", 1, 1, o.k, [&](int64_t call) {
      nanoflann::KNNResultSet<float, uint32_t> result(static_cast<std::size_t>(o.k));
      uint32_t ids[64];
      result.init(ids, distances.data());
      tree->findNeighbors(result, g.Query(call).data(), nanoflann::SearchParams());
    });
  }

  for (const int batch : single_only ? std::vector<int>{} : o.batches) {
    if (static_cast<double>(g.n) * g.dim * batch > o.batch_max_work) continue;
    const int k = o.k;
    for (const int threads : {1, 2}) {
      add("shapeid_loop", threads, batch, k, [&, batch, threads](int64_t call) {
        const int64_t first = call * batch;
        // One query after another, each on one thread, as a server would.
#pragma omp parallel for num_threads(threads) schedule(dynamic) if (threads > 1)
        for (int q = 0; q < batch; ++q) {
          CheckOk(index.Search(g.Query(first + q), k).ok());
        }
      });
      add("faiss_flat", threads, batch, k, [&, batch, threads](int64_t call) {
        omp_set_num_threads(threads);
        const int first = static_cast<int>((call * batch) % kQueryPool);
        flat.search(batch, g.Query(first).data(), k, distances.data(), labels.data());
      });
    }
  }

  // Warm up: touch result buffers, and let KnnIndex build its kd-tree where it would.
  for (const Case& c : cases) {
    if (c.batch == 1) c.run(0);
  }
  if (g.dim <= knn_internal::kKdTreeMaxDimension) {
    for (int64_t q = 0; q <= knn_internal::kKdTreeBuildAfterQueries; ++q) {
      CheckOk(index.Search(g.Query(q), o.k).ok());
    }
  }

  // Does Faiss flat return KnnIndex's neighbors? (Ties aside, it must.) 16 queries: at
  // 10^6 x 640 each costs 0.2 s.
  constexpr int kCheckedQueries = 16;
  int agree = 0;
  for (int q = 0; q < kCheckedQueries; ++q) {
    auto exact = index.Search(g.Query(q), o.k);
    CheckOk(exact.ok());
    omp_set_num_threads(1);
    flat.search(1, g.Query(q).data(), o.k, distances.data(), labels.data());
    for (int i = 0; i < o.k; ++i) {
      agree += static_cast<FaissId>((*exact)[static_cast<std::size_t>(i)].id) == labels[i];
    }
  }

  for (int rep = 0; rep < o.reps; ++rep) {
    for (Case& c : cases) c.micros_per_query.push_back(MicrosPerQuery(c, o.min_seconds));
  }
  omp_set_num_threads(2);

  json.Write(absl::StrCat(
      "{\"kind\":\"gallery\",", GalleryJson(g), ",\"shapeid_add_s\":", g.index_seconds,
      ",\"shapeid_rss_bytes_per_sample\":", static_cast<double>(g.index_bytes) / g.n,
      ",\"faiss_add_s\":", g.flat_seconds,
      ",\"faiss_rss_bytes_per_sample\":", static_cast<double>(g.flat_bytes) / g.n,
      ",\"raw_bytes_per_sample\":", 4 * g.dim, ",\"nanoflann_build_s\":", tree_seconds,
      ",\"faiss_agrees_with_shapeid\":", static_cast<double>(agree) / (kCheckedQueries * o.k),
      ",\"load_average_1min\":", LoadAverage(), "}"));
  std::printf(
      "%s d=%d n=%lld: KnnIndex add %.2f s, %.1f B/sample (raw %d); Faiss add %.2f s, "
      "%.1f B/sample; nanoflann build %.3f s (0: none); Faiss top-%d = KnnIndex's: %.4f; "
      "load %.2f\n",
      DistributionName(g.distribution), g.dim, static_cast<long long>(g.n), g.index_seconds,
      static_cast<double>(g.index_bytes) / g.n, 4 * g.dim, g.flat_seconds,
      static_cast<double>(g.flat_bytes) / g.n, tree_seconds, o.k,
      static_cast<double>(agree) / (kCheckedQueries * o.k), LoadAverage());
  for (const Case& c : cases) {
    const double median = Median(c.micros_per_query);
    json.Write(absl::StrCat("{\"kind\":\"exact\",", GalleryJson(g), ",\"k\":", c.k,
                            ",\"batch\":", c.batch, ",\"engine\":\"", c.engine,
                            "\",\"threads\":", c.threads, ",\"us_per_query\":", median,
                            ",\"reps_us\":[", absl::StrJoin(c.micros_per_query, ","), "]}"));
    std::printf("  k=%d batch=%-3d %-20s threads=%d %12.2f us/query  [%s]\n", c.k, c.batch,
                c.engine.c_str(), c.threads, median,
                absl::StrJoin(c.micros_per_query, " ", [](std::string* out, double v) {
                  absl::StrAppend(out, absl::StrFormat("%.2f", v));
                }).c_str());
  }
  std::fflush(stdout);
}

// Faiss IVF-Flat and HNSW-Flat on one gallery: single-thread latency per query and recall@k
// against KnnIndex's exact neighbors, over o.ann_queries fresh queries.
void RunApproximate(const Gallery& g, const Options& o, JsonWriter& json) {
  const int nq = o.ann_queries;
  const int k = o.k;
  const std::vector<float> queries = RowSource(g.distribution, g.dim, 777).Rows(nq);
  auto query = [&](int q) { return queries.data() + static_cast<std::size_t>(q) * g.dim; };

  std::vector<uint64_t> truth(static_cast<std::size_t>(nq) * k);
  const auto truth_start = Clock::now();
#pragma omp parallel for num_threads(2) schedule(dynamic)
  for (int q = 0; q < nq; ++q) {
    auto exact = g.index->Search(absl::MakeConstSpan(query(q), static_cast<std::size_t>(g.dim)), k);
    CheckOk(exact.ok() && static_cast<int>(exact->size()) == k);
    for (int i = 0; i < k; ++i) truth[q * k + i] = (*exact)[static_cast<std::size_t>(i)].id;
  }
  std::printf("%s d=%d n=%lld: exact ground truth for %d queries in %.1f s (2 threads)\n",
              DistributionName(g.distribution), g.dim, static_cast<long long>(g.n), nq,
              SecondsSince(truth_start));

  // Median per-query latency over o.reps passes of all queries, and the recall of the last.
  auto sweep = [&](faiss::Index& ann, const std::string& engine, const std::string& build,
                   const char* param_name, int param, const std::function<void()>& set_param) {
    set_param();
    omp_set_num_threads(1);
    std::vector<float> distances(static_cast<std::size_t>(k));
    std::vector<FaissId> labels(static_cast<std::size_t>(k));
    std::vector<double> micros;
    int64_t hits = 0;
    for (int rep = 0; rep < o.reps; ++rep) {
      hits = 0;
      const auto start = Clock::now();
      for (int q = 0; q < nq; ++q) {
        ann.search(1, query(q), k, distances.data(), labels.data());
        for (int i = 0; i < k; ++i) {
          const uint64_t* exact = truth.data() + static_cast<std::size_t>(q) * k;
          hits += std::count(exact, exact + k, static_cast<uint64_t>(labels[i]));
        }
      }
      micros.push_back(SecondsSince(start) * 1e6 / nq);
    }
    const double recall = static_cast<double>(hits) / (static_cast<double>(nq) * k);
    json.Write(absl::StrCat("{\"kind\":\"ann\",", GalleryJson(g), ",\"k\":", k, ",\"engine\":\"",
                            engine, "\",", build, ",\"", param_name, "\":", param,
                            ",\"us_per_query\":", Median(micros), ",\"reps_us\":[",
                            absl::StrJoin(micros, ","), "],\"recall\":", recall, "}"));
    std::printf("  %-10s %s=%-4d %10.1f us/query  recall@%d %.4f\n", engine.c_str(), param_name,
                param, Median(micros), k, recall);
    std::fflush(stdout);
  };

  {
    // shapeid's own approximate index (KnnIndex::UpdateApproximate) on a copy of the
    // gallery, with Faiss's list count, so the two IVF-Flats compare setting for setting.
    KnnIndex approximate = *g.index;
    const int64_t before = ResidentBytes();
    ApproximateOptions options;
    options.min_vectors = 1;
    options.lists = o.nlist;
    auto start = Clock::now();
    CheckOk(approximate.UpdateApproximate(options).ok() && approximate.approximate());
    const double build_seconds = SecondsSince(start);
    const double rss = static_cast<double>(ResidentBytes() - before) / g.n;
    // The lists' copy of the vectors, a gallery row id and a cell per row, the centroids.
    const double bytes =
        static_cast<double>(g.dim * sizeof(float) + sizeof(int64_t) + sizeof(int32_t)) +
        static_cast<double>(o.nlist) * g.dim * sizeof(float) / g.n;
    std::printf(
        "  shapeid IVF lists=%d: build %.1f s (2 threads), %.1f B/sample on top of the "
        "gallery (resident set delta of the copy and lists %.1f)\n",
        approximate.approximate_lists(), build_seconds, bytes, rss);
    const std::string build =
        absl::StrCat("\"nlist\":", approximate.approximate_lists(), ",\"build_s\":", build_seconds,
                     ",\"bytes_per_sample\":", bytes, ",\"rss_bytes_per_sample\":", rss);
    for (const int nprobe : o.nprobes) {
      options.probes = nprobe;
      CheckOk(approximate.UpdateApproximate(options).ok());  // same lists, new probes
      std::vector<double> micros;
      int64_t hits = 0;
      for (int rep = 0; rep < o.reps; ++rep) {
        hits = 0;
        const auto sweep_start = Clock::now();
        for (int q = 0; q < nq; ++q) {
          auto found =
              approximate.Search(absl::MakeConstSpan(query(q), static_cast<std::size_t>(g.dim)), k);
          CheckOk(found.ok());
          const uint64_t* exact = truth.data() + static_cast<std::size_t>(q) * k;
          for (const Neighbor& n : *found) hits += std::count(exact, exact + k, n.id);
        }
        micros.push_back(SecondsSince(sweep_start) * 1e6 / nq);
      }
      const double recall = static_cast<double>(hits) / (static_cast<double>(nq) * k);
      json.Write(absl::StrCat("{\"kind\":\"ann\",", GalleryJson(g), ",\"k\":", k,
                              ",\"engine\":\"shapeid_ivf\",", build, ",\"nprobe\":", nprobe,
                              ",\"us_per_query\":", Median(micros), ",\"reps_us\":[",
                              absl::StrJoin(micros, ","), "],\"recall\":", recall, "}"));
      std::printf("  %-10s %s=%-4d %10.1f us/query  recall@%d %.4f\n", "shapeid_ivf", "nprobe",
                  nprobe, Median(micros), k, recall);
      std::fflush(stdout);
    }
  }
  {
    omp_set_num_threads(2);
    const int64_t before = ResidentBytes();
    faiss::IndexFlatL2 quantizer(g.dim);
    faiss::IndexIVFFlat ivf(&quantizer, g.dim, static_cast<std::size_t>(o.nlist));
    // 256 points per list is Faiss's own cap; the rows are i.i.d., so a prefix is a sample.
    const int64_t train_rows = std::min<int64_t>(g.n, int64_t{256} * o.nlist);
    auto start = Clock::now();
    ivf.train(train_rows, g.flat->get_xb());
    const double train_seconds = SecondsSince(start);
    start = Clock::now();
    ivf.add(g.n, g.flat->get_xb());
    const double add_seconds = SecondsSince(start);
    const double rss = static_cast<double>(ResidentBytes() - before) / g.n;
    // From the structures (sizes, not capacities): codes and ids per sample, and centroids.
    const double bytes = static_cast<double>(ivf.code_size + sizeof(FaissId)) +
                         static_cast<double>(o.nlist) * g.dim * sizeof(float) / g.n;
    std::printf(
        "  IVF-Flat nlist=%d: train %.1f s, add %.1f s (2 threads), %.1f B/sample "
        "(resident set delta %.1f)\n",
        o.nlist, train_seconds, add_seconds, bytes, rss);
    const std::string build = absl::StrCat(
        "\"nlist\":", o.nlist, ",\"train_s\":", train_seconds, ",\"add_s\":", add_seconds,
        ",\"bytes_per_sample\":", bytes, ",\"rss_bytes_per_sample\":", rss);
    for (const int nprobe : o.nprobes) {
      sweep(ivf, "ivf_flat", build, "nprobe", nprobe,
            [&] { ivf.nprobe = static_cast<std::size_t>(nprobe); });
    }
  }
  if (std::count(o.hnsw_distributions.begin(), o.hnsw_distributions.end(),
                 DistributionName(g.distribution)) > 0) {
    omp_set_num_threads(2);
    const int64_t before = ResidentBytes();
    faiss::IndexHNSWFlat hnsw(g.dim, o.hnsw_m);
    const auto start = Clock::now();
    hnsw.add(g.n, g.flat->get_xb());
    const double add_seconds = SecondsSince(start);
    const double rss = static_cast<double>(ResidentBytes() - before) / g.n;
    // From the structures: the vectors, every level's neighbor lists, offsets and levels.
    const faiss::HNSW& graph = hnsw.hnsw;
    const double bytes = static_cast<double>(g.dim * sizeof(float)) +
                         static_cast<double>(graph.neighbors.size() * sizeof(graph.neighbors[0]) +
                                             graph.offsets.size() * sizeof(graph.offsets[0]) +
                                             graph.levels.size() * sizeof(graph.levels[0])) /
                             g.n;
    std::printf(
        "  HNSW-Flat M=%d efConstruction=%d: build %.1f s (2 threads), %.1f B/sample "
        "(resident set delta %.1f)\n",
        o.hnsw_m, graph.efConstruction, add_seconds, bytes, rss);
    const std::string build =
        absl::StrCat("\"M\":", o.hnsw_m, ",\"ef_construction\":", graph.efConstruction,
                     ",\"add_s\":", add_seconds, ",\"bytes_per_sample\":", bytes,
                     ",\"rss_bytes_per_sample\":", rss);
    for (const int ef : o.ef_searches) {
      sweep(hnsw, "hnsw_flat", build, "ef_search", ef, [&] { hnsw.hnsw.efSearch = ef; });
    }
  }
  omp_set_num_threads(2);
}

bool Contains(const std::vector<int>& v, int x) {
  return std::find(v.begin(), v.end(), x) != v.end();
}

int Run(int argc, char** argv) {
  CLI::App app("faiss_knn_bench: KnnIndex against Faiss (flat, IVF, HNSW) and nanoflann");
  Options o;
  app.add_option("--dims", o.dims, "feature dimensions")->delimiter(',')->capture_default_str();
  app.add_option("--sizes", o.sizes, "gallery sizes")->delimiter(',')->capture_default_str();
  app.add_option("--k", o.k, "neighbors")->capture_default_str();
  app.add_option("--k1-dims", o.k1_dims, "dimensions also timed with k = 1 (n >= 10^5)")
      ->delimiter(',');
  app.add_option("--batches", o.batches, "batch sizes besides 1")->delimiter(',');
  app.add_option("--batch-max-work", o.batch_max_work, "largest n * d * batch timed")
      ->capture_default_str();
  app.add_option("--nanoflann-max-dim", o.nanoflann_max_dim)->capture_default_str();
  app.add_option("--nanoflann-max-floats", o.nanoflann_max_floats, "largest n * d for nanoflann")
      ->capture_default_str();
  app.add_option("--reps", o.reps, "repetitions; medians are reported")->capture_default_str();
  app.add_option("--min-seconds", o.min_seconds, "least time per engine and repetition")
      ->capture_default_str();
  app.add_option("--ann-dims", o.ann_dims, "dimensions of the approximate runs (none: skip)")
      ->delimiter(',');
  app.add_option("--ann-size", o.ann_size, "gallery size of the approximate runs")
      ->capture_default_str();
  app.add_option("--ann-queries", o.ann_queries)->capture_default_str();
  app.add_option("--nlist", o.nlist, "IVF lists")->capture_default_str();
  app.add_option("--nprobes", o.nprobes)->delimiter(',');
  app.add_option("--hnsw-m", o.hnsw_m)->capture_default_str();
  app.add_option("--ef-searches", o.ef_searches)->delimiter(',');
  app.add_option("--hnsw-on", o.hnsw_distributions, "distributions that get an HNSW index")
      ->delimiter(',');
  app.add_option("--json", o.json_path, "write every record to this JSON file");
  CLI11_PARSE(app, argc, argv);
  // An empty list ("--ann-dims ''") arrives as {0}: no approximate runs, no batches.
  for (std::vector<int>* list : {&o.ann_dims, &o.batches}) {
    list->erase(std::remove_if(list->begin(), list->end(), [](int x) { return x < 1; }),
                list->end());
  }
  if (o.k < 1 || o.k > 64 || o.reps < 1) {
    std::fprintf(stderr, "need 1 <= k <= 64 and reps >= 1\n");
    return 2;
  }

  JsonWriter json(o.json_path);
  const auto run_start = Clock::now();
  std::printf("SIMD: %s; OpenMP max threads %d; Faiss BLAS threshold %d queries\n",
              std::string(SimdLevelName(ActiveSimdLevel())).c_str(), omp_get_max_threads(),
              faiss::distance_compute_blas_threshold);
  json.Write(absl::StrCat("{\"kind\":\"setup\",\"simd\":\"", SimdLevelName(ActiveSimdLevel()),
                          "\",\"omp_max_threads\":", omp_get_max_threads(),
                          ",\"faiss_blas_threshold\":", faiss::distance_compute_blas_threshold,
                          ",\"reps\":", o.reps, "}"));
  for (const int dim : o.dims) {
    for (const int64_t n : o.sizes) {
      const auto gallery = BuildGallery(Distribution::kUniform, dim, n);
      RunExact(*gallery, o, /*single_only=*/false, json);
      if (n == o.ann_size && Contains(o.ann_dims, dim)) RunApproximate(*gallery, o, json);
    }
  }
  for (const int dim : o.ann_dims) {
    const auto gallery = BuildGallery(Distribution::kMixture, dim, o.ann_size);
    RunExact(*gallery, o, /*single_only=*/true, json);
    RunApproximate(*gallery, o, json);
  }
  std::printf("total %.0f s\n", SecondsSince(run_start));
  return 0;
}

}  // namespace
}  // namespace shapeid

int main(int argc, char** argv) { return shapeid::Run(argc, argv); }
