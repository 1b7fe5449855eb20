// Issue 26: the cost of committing one sample into a large gallery, and what a Classify
// costs beside it. For each gallery size:
//  - commit: TrainBatch::Commit of one sample (described before the clock starts) into an
//    in-memory gallery (no store): the in-memory part of a Train. Median of --reps commits;
//  - peak heap during that commit above what was live before it (the program's malloc is
//    counted: shapeid_heap_meter), median;
//  - with the SQLite store (up to --store_max_samples): the same commit, which adds the
//    store's fsync'd append;
//  - exact kNN: ClassifyFeatures of one 240-float query (k = 1, exact), median of --queries,
//    and Classify of a 2,000-point cloud (describe + pose variants + search), median.
// Galleries are filled through Gallery::Restore (a StoredGallery of uniform random features
// in the default descriptor's dimension) so that 10^6 samples load in seconds; only the
// Gallery API is used, so this file builds against older trees too (docs/performance.md).
//
//   build/release/bench/commit_bench --samples 10000,100000,1000000 --reps 21

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "CLI/CLI.hpp"
#include "absl/strings/str_cat.h"
#include "absl/time/clock.h"
#include "bench/bench_clouds.h"
#include "core/descriptor_registry.h"
#include "core/descriptors/heap_meter.h"
#include "core/gallery/gallery.h"
#include "core/version.h"
#include "server/storage/sqlite_gallery_store.h"

namespace shapeid {
namespace {

double Median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0.0 : v[v.size() / 2];
}

StoredGallery MakeGallery(int64_t samples, uint32_t seed) {
  StoredGallery g;
  g.name = "bench";
  auto descriptor = CreateDescriptor(g.options.descriptor_spec);
  if (!descriptor.ok()) std::abort();
  g.options.descriptor_spec = (*descriptor)->spec().ToString();
  g.created = g.updated = absl::Now();
  g.descriptor_version = FindDescriptorKind((*descriptor)->spec().kind)->version;
  g.software_version = kShapeidVersion;
  g.dimension = static_cast<int>((*descriptor)->dimension());
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(0.f, 1.f);
  g.samples.resize(static_cast<size_t>(samples));
  for (int64_t i = 0; i < samples; ++i) {
    StoredSample& s = g.samples[static_cast<size_t>(i)];
    s.id = static_cast<uint64_t>(i + 1);
    s.label = absl::StrCat("class-", i % 40);
    s.features.resize(static_cast<size_t>(g.dimension));
    for (float& f : s.features) f = u(rng);
  }
  return g;
}

struct CommitFigures {
  double median_ms = 0;
  double peak_heap_mib = 0;
};

// `reps` commits of one described sample each.
CommitFigures Commits(Gallery& gallery, int reps) {
  std::vector<double> ms, peak;
  for (int r = 0; r < reps; ++r) {
    TrainBatch batch = gallery.NewBatch();
    if (!batch.AddSample(0, "new", bench::SurfaceCloud(500, static_cast<uint32_t>(r))).ok()) {
      std::abort();
    }
    heap_meter::Start();
    const absl::Time t0 = absl::Now();
    absl::StatusOr<CommitResult> result = batch.Commit();
    const absl::Duration elapsed = absl::Now() - t0;
    peak.push_back(static_cast<double>(heap_meter::Stop()) / (1 << 20));
    if (!result.ok()) {
      std::fprintf(stderr, "commit_bench: %s\n", std::string(result.status().message()).c_str());
      std::exit(1);
    }
    ms.push_back(absl::ToDoubleMilliseconds(elapsed));
  }
  return CommitFigures{Median(ms), Median(peak)};
}

int Run(int argc, char** argv) {
  CLI::App app("commit_bench: cost of committing one sample into a large gallery");
  std::vector<int64_t> sizes = {10'000, 100'000, 1'000'000};
  int reps = 21;
  int queries = 21;
  int64_t store_max = 100'000;
  std::string dir = "/var/tmp/shapeid_commit_bench";
  app.add_option("--samples", sizes, "gallery sizes")->delimiter(',')->capture_default_str();
  app.add_option("--reps", reps, "commits per size; medians are reported")->capture_default_str();
  app.add_option("--queries", queries, "queries per size; medians")->capture_default_str();
  app.add_option("--store_max_samples", store_max,
                 "largest gallery also measured with the SQLite store (it writes the gallery "
                 "first: ~1 GB at 10^6 x 240); 0: none")
      ->capture_default_str();
  app.add_option("--dir", dir, "scratch data directory for the store (wiped)")
      ->capture_default_str();
  CLI11_PARSE(app, argc, argv);

  std::printf(
      "| samples x dim | commit, memory (ms) | peak heap in commit (MiB) | "
      "commit, SQLite (ms) | exact kNN, 1 vector (ms) | Classify 2,000 points (ms) |\n");
  std::printf("|---|---|---|---|---|---|\n");
  const PointCloud query_cloud = bench::SurfaceCloud(2000, 7);
  for (int64_t n : sizes) {
    std::shared_ptr<Gallery> gallery;
    int dim = 0;
    double store_ms = -1;
    GalleryLimits limits;  // exact search, as shapeid-server below 10^6 vectors
    limits.max_samples_per_gallery = n + 2 * reps;
    {
      StoredGallery stored = MakeGallery(n, 1);
      dim = stored.dimension;
      if (n <= store_max) {
        std::system(absl::StrCat("rm -rf '", dir, "'").c_str());
        auto store = SqliteGalleryStore::Open({dir, false});
        if (!store.ok() || !(*store)->LoadAll().ok() || !(*store)->SaveGallery(stored).ok()) {
          std::fprintf(stderr, "commit_bench: store set-up failed\n");
          return 1;
        }
        std::shared_ptr<GalleryStore> shared = std::move(*store);
        auto stored_gallery = Gallery::Restore(stored, limits, shared);
        if (!stored_gallery.ok()) return 1;
        store_ms = Commits(**stored_gallery, reps).median_ms;
      }
      auto restored = Gallery::Restore(stored, limits, nullptr);
      if (!restored.ok()) {
        std::fprintf(stderr, "commit_bench: %s\n",
                     std::string(restored.status().message()).c_str());
        return 1;
      }
      gallery = *std::move(restored);
    }
    const CommitFigures memory = Commits(*gallery, reps);

    std::mt19937 rng(5);
    std::uniform_real_distribution<float> u(0.f, 1.f);
    std::vector<double> knn_ms, classify_ms;
    std::vector<float> query(static_cast<size_t>(dim));
    for (int q = 0; q < queries; ++q) {
      for (float& f : query) f = u(rng);
      const std::shared_ptr<const GallerySnapshot> snapshot = gallery->Snapshot();
      const absl::Time t0 = absl::Now();
      auto answer = snapshot->ClassifyFeatures(query, 1, SearchMode::kExact);
      knn_ms.push_back(absl::ToDoubleMilliseconds(absl::Now() - t0));
      if (!answer.ok()) return 1;
      const absl::Time t1 = absl::Now();
      auto classified = snapshot->Classify(query_cloud);
      classify_ms.push_back(absl::ToDoubleMilliseconds(absl::Now() - t1));
      if (!classified.ok()) return 1;
    }
    char store_text[32] = "-";
    if (store_ms >= 0) std::snprintf(store_text, sizeof(store_text), "%.3f", store_ms);
    std::printf("| %lld x %d | %.3f | %.2f | %s | %.3f | %.3f |\n", static_cast<long long>(n), dim,
                memory.median_ms, memory.peak_heap_mib, store_text, Median(knn_ms),
                Median(classify_ms));
    std::fflush(stdout);
  }
  return 0;
}

}  // namespace
}  // namespace shapeid

int main(int argc, char** argv) { return shapeid::Run(argc, argv); }
