// Issue 40's probe of a gallery's trained head: how a head's options move its accuracy on test
// views made by other code, fitted as a gallery fits it (FitGalleryHead) beside the gallery's
// kNN answer, without describing the clouds again for each option.
//
// The first run on a views folder (bench/independent_views.py's layout: LABEL/train/*,
// LABEL/test/*) describes every training cloud as a gallery with the given spec and
// augmentation stores it, and every test view with its pose variants, into --cache; later
// runs read the cache. Then, for each --config, it fits a head and prints one line of
// accuracy on the test views: the head alone, the kNN vote alone, and the two combined.
//
//   learn_probe --views build/independent-views/modelnet10-hpr-limit0
//     --spec dfsd:size=0.15 --augment-views 16 --cache build/learn-probe/mn10-hpr.bin
//     --config "hidden=256,256 epochs=30 dropout=0.25" --config "noise=0.2"
//
// A --config is space-separated key=value: hidden (comma list), epochs, batch, lr, wd,
// dropout, smoothing, noise, seed; keys left out keep MlpOptions' defaults.

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <mutex>
#include <string>
#include <vector>

#include "CLI/CLI.hpp"
#include "absl/strings/numbers.h"
#include "absl/strings/str_split.h"
#include "core/gallery/gallery.h"
#include "core/gallery/gallery_head.h"
#include "core/gallery/gallery_snapshot.h"
#include "core/io/point_cloud_reader.h"
#include "core/parallel_ranges.h"

namespace shapeid {
namespace {

struct Query {
  int truth = 0;
  std::vector<float> vectors;  // the descriptor, then its pose variants
};

struct Cache {
  std::vector<std::string> labels;  // sorted
  std::vector<int> sample_class;
  std::vector<std::vector<float>> sample_vectors;  // a sample's views, dimension each
  std::vector<Query> queries;
};

std::vector<std::pair<std::string, int>> Files(const std::string& root, const std::string& split,
                                               std::vector<std::string>& labels) {
  namespace fs = std::filesystem;
  labels.clear();
  for (const auto& entry : fs::directory_iterator(root)) {
    if (entry.is_directory()) labels.push_back(entry.path().filename().string());
  }
  std::sort(labels.begin(), labels.end());
  std::vector<std::pair<std::string, int>> files;
  for (size_t c = 0; c < labels.size(); ++c) {
    std::vector<std::string> names;
    for (const auto& entry : fs::directory_iterator(fs::path(root) / labels[c] / split)) {
      names.push_back(entry.path().string());
    }
    std::sort(names.begin(), names.end());
    for (const std::string& name : names) files.emplace_back(name, static_cast<int>(c));
  }
  return files;
}

template <typename T>
void Put(std::ofstream& out, const T& v) {
  out.write(reinterpret_cast<const char*>(&v), sizeof(v));
}
template <typename T>
void Get(std::ifstream& in, T& v) {
  in.read(reinterpret_cast<char*>(&v), sizeof(v));
}
void PutVector(std::ofstream& out, const std::vector<float>& v) {
  Put(out, static_cast<uint64_t>(v.size()));
  out.write(reinterpret_cast<const char*>(v.data()), v.size() * 4);
}
void GetVector(std::ifstream& in, std::vector<float>& v) {
  uint64_t n = 0;
  Get(in, n);
  v.resize(n);
  in.read(reinterpret_cast<char*>(v.data()), n * 4);
}

void Save(const Cache& cache, const std::string& path) {
  std::filesystem::create_directories(std::filesystem::path(path).parent_path());
  std::ofstream out(path, std::ios::binary);
  Put(out, static_cast<uint32_t>(cache.labels.size()));
  for (const std::string& l : cache.labels) {
    Put(out, static_cast<uint32_t>(l.size()));
    out.write(l.data(), l.size());
  }
  Put(out, static_cast<uint64_t>(cache.sample_class.size()));
  for (size_t s = 0; s < cache.sample_class.size(); ++s) {
    Put(out, cache.sample_class[s]);
    PutVector(out, cache.sample_vectors[s]);
  }
  Put(out, static_cast<uint64_t>(cache.queries.size()));
  for (const Query& q : cache.queries) {
    Put(out, q.truth);
    PutVector(out, q.vectors);
  }
}

bool Load(Cache& cache, const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return false;
  uint32_t labels = 0;
  Get(in, labels);
  cache.labels.resize(labels);
  for (std::string& l : cache.labels) {
    uint32_t n = 0;
    Get(in, n);
    l.resize(n);
    in.read(l.data(), n);
  }
  uint64_t samples = 0;
  Get(in, samples);
  cache.sample_class.resize(samples);
  cache.sample_vectors.resize(samples);
  for (size_t s = 0; s < samples; ++s) {
    Get(in, cache.sample_class[s]);
    GetVector(in, cache.sample_vectors[s]);
  }
  uint64_t queries = 0;
  Get(in, queries);
  cache.queries.resize(queries);
  for (Query& q : cache.queries) {
    Get(in, q.truth);
    GetVector(in, q.vectors);
  }
  return static_cast<bool>(in);
}

absl::StatusOr<Cache> Describe(const std::string& views, const GalleryOptions& options) {
  absl::StatusOr<std::shared_ptr<Gallery>> empty =
      Gallery::Create("probe", options, GalleryLimits{}, nullptr);
  if (!empty.ok()) return empty.status();
  const std::shared_ptr<const GallerySnapshot> snapshot = (*empty)->Snapshot();
  Cache cache;
  std::vector<std::string> test_labels;
  const auto train = Files(views, "train", cache.labels);
  const auto test = Files(views, "test", test_labels);
  cache.sample_class.resize(train.size());
  cache.sample_vectors.resize(train.size());
  cache.queries.resize(test.size());
  std::mutex mu;
  int done = 0;
  const size_t total = train.size() + test.size();
  ParallelRanges(static_cast<int64_t>(total), 2, 1, [&](int, int64_t begin, int64_t end) {
    for (int64_t i = begin; i < end; ++i) {
      const bool is_train = static_cast<size_t>(i) < train.size();
      const auto& [path, cls] = is_train ? train[i] : test[i - train.size()];
      absl::StatusOr<ReadResult> read = ReadPointCloud(path);
      if (read.ok()) {
        if (is_train) {
          absl::StatusOr<std::vector<float>> f = snapshot->DescribeForTraining(read->cloud);
          if (f.ok()) cache.sample_vectors[i] = *std::move(f);
          cache.sample_class[i] = cls;
        } else {
          Query& q = cache.queries[i - train.size()];
          std::vector<float> variants;
          if (snapshot->shared_descriptor()
                  ->ComputeWithPoseVariants(read->cloud, &q.vectors, &variants)
                  .ok()) {
            q.vectors.insert(q.vectors.end(), variants.begin(), variants.end());
          }
          q.truth = cls;
        }
      }
      std::lock_guard<std::mutex> lock(mu);
      if (++done % 500 == 0) fprintf(stderr, "described %d / %zu\n", done, total);
    }
  });
  return cache;
}

absl::StatusOr<HeadOptions> ParseConfig(const std::string& config) {
  HeadOptions head;
  MlpOptions& o = head.mlp;
  for (absl::string_view item : absl::StrSplit(config, ' ', absl::SkipEmpty())) {
    const std::vector<std::string> kv = absl::StrSplit(item, '=');
    if (kv.size() != 2) return absl::InvalidArgumentError(absl::StrCat("bad item ", item));
    const std::string& k = kv[0];
    const std::string& v = kv[1];
    double d = 0;
    if (k == "hidden") {
      o.hidden.clear();
      for (absl::string_view u : absl::StrSplit(v, ',')) {
        int units = 0;
        if (!absl::SimpleAtoi(u, &units)) return absl::InvalidArgumentError("bad hidden");
        o.hidden.push_back(units);
      }
      continue;
    }
    if (!absl::SimpleAtod(v, &d)) return absl::InvalidArgumentError(absl::StrCat("bad ", k));
    if (k == "epochs")
      o.epochs = static_cast<int>(d);
    else if (k == "batch")
      o.batch_size = static_cast<int>(d);
    else if (k == "lr")
      o.learning_rate = d;
    else if (k == "wd")
      o.weight_decay = d;
    else if (k == "dropout")
      o.dropout = d;
    else if (k == "smoothing")
      o.label_smoothing = d;
    else if (k == "noise")
      o.input_noise = d;
    else if (k == "seed")
      o.seed = static_cast<uint64_t>(d);
    else
      return absl::InvalidArgumentError(absl::StrCat("unknown key ", k));
  }
  return head;
}

int Main(int argc, char** argv) {
  CLI::App app("issue 40's probe of a gallery's trained head");
  std::string views, cache_path, spec = "dfsd:size=0.15", mix = "camera";
  int augment_views = 16, k = 5;
  std::vector<std::string> configs;
  app.add_option("--views", views)->required();
  app.add_option("--cache", cache_path)->required();
  app.add_option("--spec", spec);
  app.add_option("--augment-views", augment_views);
  app.add_option("--augment-mix", mix);
  app.add_option("--k", k);
  app.add_option("--config", configs);
  CLI11_PARSE(app, argc, argv);

  GalleryOptions options;
  options.descriptor_spec = spec;
  options.knn.k = k;
  options.knn.weighting = VoteWeighting::kDistance;
  options.augment.views = augment_views;
  options.augment.mix = mix == "varied" ? ViewMix::kVaried : ViewMix::kCamera;
  Cache cache;
  if (!Load(cache, cache_path)) {
    absl::StatusOr<Cache> described = Describe(views, options);
    if (!described.ok()) {
      fprintf(stderr, "%s\n", described.status().ToString().c_str());
      return 1;
    }
    cache = *std::move(described);
    Save(cache, cache_path);
  }
  absl::StatusOr<std::shared_ptr<Gallery>> empty =
      Gallery::Create("probe", options, GalleryLimits{}, nullptr);
  StoredGallery stored = (*empty)->Snapshot()->ToStored();
  for (size_t s = 0; s < cache.sample_class.size(); ++s) {
    if (cache.sample_vectors[s].empty()) continue;
    stored.samples.push_back(
        {kFirstAssignedId + s, cache.labels[cache.sample_class[s]], cache.sample_vectors[s]});
  }
  std::shared_ptr<Gallery> gallery = *Gallery::Restore(stored, GalleryLimits{}, nullptr);
  const std::shared_ptr<const GallerySnapshot> snapshot = gallery->Snapshot();
  const int d = snapshot->dimension();
  // kNN answers once: they do not depend on the head.
  std::vector<GalleryClassification> knn(cache.queries.size());
  int knn_right = 0, tests = 0;
  for (size_t q = 0; q < cache.queries.size(); ++q) {
    if (cache.queries[q].vectors.empty()) continue;
    knn[q] = *snapshot->ClassifyFeatures(cache.queries[q].vectors);
    ++tests;
    knn_right += knn[q].knn.label == cache.labels[cache.queries[q].truth];
  }
  printf("%zu samples, %d tests; kNN %.1f %%\n", stored.samples.size(), tests,
         100.0 * knn_right / tests);
  for (const std::string& config : configs) {
    absl::StatusOr<HeadOptions> head_options = ParseConfig(config);
    if (!head_options.ok()) {
      fprintf(stderr, "%s\n", head_options.status().ToString().c_str());
      return 2;
    }
    absl::StatusOr<GalleryHead> head = FitGalleryHead(*snapshot, *head_options);
    if (!head.ok()) {
      fprintf(stderr, "%s\n", head.status().ToString().c_str());
      return 1;
    }
    int right_mean = 0, right_first = 0, right_mix = 0, right_max = 0;
    // What the head adds to a Classify: its probabilities over the query and its variants.
    const absl::Time timed = absl::Now();
    for (const Query& query : cache.queries) {
      if (!query.vectors.empty()) (void)head->classifier.Probabilities(query.vectors);
    }
    const double head_us = absl::ToDoubleMicroseconds(absl::Now() - timed) / tests;
    for (size_t q = 0; q < cache.queries.size(); ++q) {
      const Query& query = cache.queries[q];
      if (query.vectors.empty()) continue;
      const std::vector<float> mean = *head->classifier.Probabilities(query.vectors);
      const std::vector<float> first =
          *head->classifier.Probabilities({query.vectors.data(), static_cast<size_t>(d)});
      const auto best = [](const std::vector<float>& p) {
        return static_cast<int>(std::max_element(p.begin(), p.end()) - p.begin());
      };
      // Head and kNN: the head's probabilities plus the kNN vote shares, half each.
      std::vector<float> combined = mean;
      double total = 0;
      for (const ClassVote& vote : knn[q].knn.votes) total += vote.weight;
      for (const ClassVote& vote : knn[q].knn.votes) {
        const int c = head->ClassOf(vote.label);
        if (c >= 0 && total > 0) combined[c] += static_cast<float>(vote.weight / total);
      }
      // The most confident pose variant alone.
      int most_confident = best(first);
      float top = 0;
      for (size_t v = 0; v * d < query.vectors.size(); ++v) {
        const std::vector<float> p =
            *head->classifier.Probabilities({query.vectors.data() + v * d, static_cast<size_t>(d)});
        if (p[best(p)] > top) {
          top = p[best(p)];
          most_confident = best(p);
        }
      }
      right_max += head->labels[most_confident] == cache.labels[query.truth];
      right_mean += head->labels[best(mean)] == cache.labels[query.truth];
      right_first += head->labels[best(first)] == cache.labels[query.truth];
      right_mix += head->labels[best(combined)] == cache.labels[query.truth];
    }
    printf(
        "[%s] head %.1f %% (first pose %.1f %%, most confident pose %.1f %%), head+kNN %.1f %%; "
        "held out %.1f %%, fit %.0f s, head %.0f us a query\n",
        config.c_str(), 100.0 * right_mean / tests, 100.0 * right_first / tests,
        100.0 * right_max / tests, 100.0 * right_mix / tests, 100 * head->holdout_accuracy(),
        absl::ToDoubleSeconds(head->fit_time), head_us);
    fflush(stdout);
  }
  return 0;
}

}  // namespace
}  // namespace shapeid

int main(int argc, char** argv) { return shapeid::Main(argc, argv); }
