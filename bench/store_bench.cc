// Issue 5 "start-up time for a 100,000-sample gallery", and what durability costs a Train:
//  - start-up: SqliteGalleryStore::Open + GalleryRegistry::LoadFromStore on a data directory
//    holding one gallery (quick_check, reading and CRC-checking every row, rebuilding the kNN
//    index), against the same rebuild from memory (Gallery::Restore of a StoredGallery) as
//    the baseline measured in the same run;
//  - writes: AppendSamples of 1, 16 and 256 samples (one fsync'd transaction each), and
//    SaveGallery of the whole gallery (an import);
//  - the file size per sample, and the resident memory the loaded gallery takes (issue 7:
//    aim within 1.2x of the raw descriptor floats plus label).
// Medians of --reps runs. A plain program: each figure is a one-shot wall time.
//
//   build/release/bench/store_bench --samples 100000 --dim 81 --reps 5 --dir /var/tmp/x

#include <malloc.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <random>
#include <string>
#include <vector>

#include "CLI/CLI.hpp"
#include "absl/strings/str_cat.h"
#include "absl/time/clock.h"
#include "core/descriptor_registry.h"
#include "core/gallery/gallery.h"
#include "core/gallery/gallery_registry.h"
#include "core/version.h"
#include "server/storage/sqlite_gallery_store.h"

namespace shapeid {
namespace {

// Resident set size of this process, from /proc/self/statm.
double ResidentBytes() {
  long pages_total = 0, pages_resident = 0;
  if (FILE* f = std::fopen("/proc/self/statm", "r")) {
    if (std::fscanf(f, "%ld %ld", &pages_total, &pages_resident) != 2) pages_resident = 0;
    std::fclose(f);
  }
  return static_cast<double>(pages_resident) * static_cast<double>(sysconf(_SC_PAGESIZE));
}

double Median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0.0 : v[v.size() / 2];
}

StoredGallery MakeGallery(int64_t samples, int dim, uint32_t seed) {
  StoredGallery g;
  g.name = "bench";
  g.options.descriptor_spec = "rphsd";
  auto descriptor = CreateDescriptor(g.options.descriptor_spec);
  if (descriptor.ok() && static_cast<int>((*descriptor)->dimension()) == dim) {
    g.options.descriptor_spec = (*descriptor)->spec().ToString();  // loads as compatible
  } else {
    g.options.descriptor_spec = "opaque";  // loads, marked incompatible; costs the same
  }
  g.created = g.updated = absl::Now();
  g.descriptor_version = FindDescriptorKind("rphsd")->version;
  g.software_version = kShapeidVersion;
  g.dimension = dim;
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(0.f, 1.f);
  g.samples.resize(static_cast<size_t>(samples));
  for (int64_t i = 0; i < samples; ++i) {
    StoredSample& s = g.samples[static_cast<size_t>(i)];
    s.id = static_cast<uint64_t>(i + 1);
    s.label = absl::StrCat("class-", i % 40);
    s.features.resize(static_cast<size_t>(dim));
    for (float& f : s.features) f = u(rng);
  }
  return g;
}

int Run(int argc, char** argv) {
  CLI::App app("store_bench: start-up and write cost of the SQLite gallery store");
  int64_t samples = 100'000;
  int dim = 81;
  int reps = 5;
  std::string dir = "/var/tmp/shapeid_store_bench";
  GalleryLimits limits;
  app.add_option("--samples", samples, "samples in the gallery")->capture_default_str();
  app.add_option("--dim", dim, "features per sample (81: RPHSD's default)")->capture_default_str();
  app.add_option("--reps", reps, "repetitions; medians are reported")->capture_default_str();
  app.add_option("--dir", dir, "scratch data directory (wiped), on the disk to measure")
      ->capture_default_str();
  app.add_option("--approximate_min_vectors", limits.approximate.min_vectors,
                 "build the approximate index at load from this many vectors, as shapeid-server "
                 "does (its default: 1000000); 0: exact only")
      ->capture_default_str();
  CLI11_PARSE(app, argc, argv);
  std::system(absl::StrCat("rm -rf '", dir, "'").c_str());

  const StoredGallery gallery = MakeGallery(samples, dim, 1);
  std::vector<double> save_s, load_s, ready_s, restore_s;
  std::vector<double> append_ms[3];
  const int batch_sizes[3] = {1, 16, 256};
  double bytes_per_sample = 0;
  std::vector<double> resident_per_sample;
  for (int r = 0; r < reps; ++r) {
    std::system(absl::StrCat("rm -rf '", dir, "'").c_str());
    {
      auto store = SqliteGalleryStore::Open({dir, false});
      if (!store.ok()) {
        std::fprintf(stderr, "store_bench: %s\n", std::string(store.status().message()).c_str());
        return 1;
      }
      if (!(*store)->LoadAll().ok()) return 1;
      const absl::Time t0 = absl::Now();
      if (absl::Status s = (*store)->SaveGallery(gallery); !s.ok()) {
        std::fprintf(stderr, "store_bench: %s\n", std::string(s.message()).c_str());
        return 1;
      }
      save_s.push_back(absl::ToDoubleSeconds(absl::Now() - t0));
      struct stat st;
      if (stat((*store)->GalleryPath("bench").c_str(), &st) == 0) {
        bytes_per_sample = static_cast<double>(st.st_size) / static_cast<double>(samples);
      }
      uint64_t next_id = static_cast<uint64_t>(samples) + 1;
      for (int b = 0; b < 3; ++b) {
        for (int i = 0; i < 10; ++i) {
          std::vector<StoredSample> batch(static_cast<size_t>(batch_sizes[b]), gallery.samples[0]);
          for (StoredSample& s : batch) s.id = next_id++;
          const absl::Time a0 = absl::Now();
          if (!(*store)->AppendSamples("bench", batch, absl::Now(), 0).ok()) return 1;
          append_ms[b].push_back(absl::ToDoubleMilliseconds(absl::Now() - a0));
        }
      }
    }
    // Start-up as the server does it: open, load every gallery, rebuild the indexes.
    malloc_trim(0);
    const double resident_before = ResidentBytes();
    const absl::Time t1 = absl::Now();
    {
      auto store = SqliteGalleryStore::Open({dir, false});
      if (!store.ok()) return 1;
      GalleryRegistry registry(limits, std::shared_ptr<SqliteGalleryStore>(*std::move(store)));
      if (absl::Status s = registry.LoadFromStore(); !s.ok()) {
        std::fprintf(stderr, "store_bench: %s\n", std::string(s.message()).c_str());
        return 1;
      }
      load_s.push_back(absl::ToDoubleSeconds(absl::Now() - t1));
      // Serving from here; the approximate index (if any) follows in the background.
      registry.WaitForApproximateIndexes();
      ready_s.push_back(absl::ToDoubleSeconds(absl::Now() - t1));
      malloc_trim(0);  // what the loaded gallery holds, not the loader's freed temporaries
      // Per loaded sample: the gallery also holds the samples appended above.
      const auto loaded = registry.Get("bench");
      if (!loaded.ok()) return 1;
      resident_per_sample.push_back((ResidentBytes() - resident_before) /
                                    static_cast<double>((*loaded)->Snapshot()->num_samples()));
    }
    // Baseline: the same rebuild from memory, no disk.
    const absl::Time t2 = absl::Now();
    auto restored = Gallery::Restore(gallery, limits, nullptr);
    if (!restored.ok()) return 1;
    restore_s.push_back(absl::ToDoubleSeconds(absl::Now() - t2));
  }
  std::system(absl::StrCat("rm -rf '", dir, "'").c_str());

  std::printf("gallery: %lld samples x %d floats; %d repetitions, medians; data dir %s\n",
              static_cast<long long>(samples), dim, reps, dir.c_str());
  std::printf("%-52s %10.3f s\n", "start-up: open + load + verify + index (server)",
              Median(load_s));
  std::printf("%-52s %10.3f s\n", "approximate index ready (background, after start-up)",
              Median(ready_s));
  std::printf("%-52s %10.3f s\n", "baseline: index rebuilt from memory (no disk)",
              Median(restore_s));
  std::printf("%-52s %10.2fx\n", "start-up / baseline", Median(load_s) / Median(restore_s));
  std::printf("%-52s %10.3f s\n", "SaveGallery of the whole gallery (an import)", Median(save_s));
  for (int b = 0; b < 3; ++b) {
    std::printf("%-52s %10.2f ms\n",
                absl::StrCat("AppendSamples of ", batch_sizes[b], " (one fsync'd commit)").c_str(),
                Median(append_ms[b]));
  }
  std::printf("%-52s %10.0f B\n", "file size per sample", bytes_per_sample);
  // The raw content: the floats, the label's bytes and the 8-byte id.
  double raw = 0;
  for (const StoredSample& s : gallery.samples) raw += 4.0 * s.features.size() + s.label.size() + 8;
  raw /= static_cast<double>(samples);
  const double resident = Median(resident_per_sample);
  std::printf("%-52s %10.0f B\n", "raw floats + label + id per sample", raw);
  std::printf("%-52s %10.0f B (%.2fx raw)\n", "resident memory per loaded sample (RSS growth)",
              resident, resident / raw);
  std::printf(
      "JSON {\"bench\":\"store\",\"samples\":%lld,\"dim\":%d,\"startup_s\":%.3f,"
      "\"baseline_s\":%.3f,\"save_s\":%.3f,\"file_bytes_per_sample\":%.1f,"
      "\"raw_bytes_per_sample\":%.1f,\"resident_bytes_per_sample\":%.1f,"
      "\"approximate_min_vectors\":%lld,\"approximate_ready_s\":%.3f}\n",
      static_cast<long long>(samples), dim, Median(load_s), Median(restore_s), Median(save_s),
      bytes_per_sample, raw, resident, static_cast<long long>(limits.approximate.min_vectors),
      Median(ready_s));
  return 0;
}

}  // namespace
}  // namespace shapeid

int main(int argc, char** argv) { return shapeid::Run(argc, argv); }
