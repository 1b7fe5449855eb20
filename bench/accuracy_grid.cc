// The accuracy study of issue 6, in-process: for every descriptor spec, k, vote weighting,
// feature scaling and test-cloud perturbation, the kNN accuracy on ModelNet10 (the official
// hold-out split) and on DALES Objects (stratified 5-fold cross-validation, seeded, with the
// fold assignment of `shapeid eval`). One JSON line per (dataset, spec, k, weighting, scaling,
// perturbation). bench/accuracy runs the paper's grids with it and writes docs/accuracy.md.
//
//   accuracy_grid --specs-file bench/accuracy_specs.txt > grid.jsonl
//   accuracy_grid --spec rphsd --spec cnsd --perturb clean,yaw,rot3d,noise1,partial
//   accuracy_grid --quick    a few dozen clouds per dataset, every perturbation, ~1 s (ctest)
//
// The gallery is always the clean training clouds; perturbations (core/views/perturb.h) touch
// the test clouds only, seeded per cloud by DeriveSeed(--seed, "<perturbation>|<relative path>")
// so results do not depend on thread order. Each (spec, cloud, perturbation) is described once;
// each (spec, scaling, perturbation, fold) runs one search per test cloud with the largest k,
// and every k and weighting is voted from that sorted neighbor list by KnnIndex::Classify's
// rules; a sample of queries (every one with --quick) is checked against Classify itself.
//
// Exit status: 0 done, 2 bad arguments or data, 3 a derived vote differed from Classify,
// 77 no requested dataset is present (a skip, for ctest's SKIP_RETURN_CODE).

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "CLI/CLI.hpp"
#include "absl/strings/ascii.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/strings/str_join.h"
#include "absl/strings/str_split.h"
#include "absl/strings/strip.h"
#include "client/cli/eval_command.h"
#include "client/cli/input_files.h"
#include "core/descriptor_registry.h"
#include "core/gallery/gallery.h"
#include "core/io/point_cloud_reader.h"
#include "core/knn/knn_index.h"
#include "core/views/augment.h"
#include "core/views/perturb.h"

namespace shapeid {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

constexpr int kExitUsage = 2;
constexpr int kExitMismatch = 3;
constexpr int kExitSkip = 77;

void Progress(const std::string& line) {
  std::fprintf(stderr, "accuracy_grid: %s\n", line.c_str());
}

// Runs body(i) for i in [0, n) on `threads` threads; each i writes only its own slot, so the
// results do not depend on scheduling.
void ParallelFor(size_t n, int threads, const std::function<void(size_t)>& body) {
  std::atomic<size_t> next{0};
  auto work = [&] {
    for (size_t i = next++; i < n; i = next++) body(i);
  };
  std::vector<std::thread> pool;
  for (int t = 1; t < threads; ++t) pool.emplace_back(work);
  work();
  for (std::thread& t : pool) t.join();
}

double Median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  const size_t h = v.size() / 2;
  return v.size() % 2 ? v[h] : 0.5 * (v[h - 1] + v[h]);
}

std::string JsonString(const std::string& s) {
  std::string out = "\"";
  for (char c : s) {
    if (c == '"' || c == '\\') {
      out += '\\';
      out += c;
    } else if (static_cast<unsigned char>(c) < 0x20) {
      out += absl::StrFormat("\\u%04x", static_cast<int>(c));
    } else {
      out += c;
    }
  }
  return out + "\"";
}

// ----------------------------------------------------------------------------- inputs

struct SpecEntry {
  std::string group;  // the specs file's [section], else the descriptor kind
  std::unique_ptr<Descriptor> descriptor;
  std::string spec;  // canonical
  // Training-time view augmentation of the gallery (core/views/augment.h); off by default.
  AugmentOptions augment;
  // spec, plus " +views=N" when augmented: what the records and the report call it.
  std::string name;
  // What a gallery created with no spec and no augmentation gets (kDefaultDescriptorSpec).
  bool is_default = false;
};

// "SPEC [+views=N] [+pose=random]": a spec, optionally with the gallery's view augmentation.
absl::Status ParseSpecLine(absl::string_view line, std::string* spec, AugmentOptions* augment) {
  std::vector<std::string> words = absl::StrSplit(line, ' ', absl::SkipEmpty());
  if (words.empty()) return absl::InvalidArgumentError("empty spec");
  *spec = words[0];
  *augment = AugmentOptions();
  for (size_t w = 1; w < words.size(); ++w) {
    absl::string_view word = words[w];
    int views = 0;
    if (absl::ConsumePrefix(&word, "+views=") && absl::SimpleAtoi(word, &views)) {
      augment->views = views;
    } else if (words[w] == "+pose=random") {
      augment->sensor.random_pose = true;
    } else {
      return absl::InvalidArgumentError(
          absl::StrCat("\"", words[w], "\" after the spec: expected +views=N or +pose=random"));
    }
  }
  return ValidateAugmentOptions(*augment);
}

// One spec per line, '#' starts a comment, "[name]" starts a section.
absl::Status ReadSpecsFile(const std::string& path,
                           std::vector<std::pair<std::string, std::string>>* out) {
  std::ifstream in(path);
  if (!in) return absl::NotFoundError(absl::StrCat(path, ": cannot open the specs file"));
  std::string line, group;
  while (std::getline(in, line)) {
    absl::string_view text = line;
    text = text.substr(0, text.find('#'));
    text = absl::StripAsciiWhitespace(text);
    if (text.empty()) continue;
    if (text.front() == '[' && text.back() == ']') {
      group = std::string(absl::StripAsciiWhitespace(text.substr(1, text.size() - 2)));
      continue;
    }
    out->emplace_back(group, std::string(text));
  }
  return absl::OkStatus();
}

struct KChoice {
  std::string name;  // "5" or "ln"
  int value = 0;     // 0 for ln: round(ln N_train), resolved per fold
  int Resolve(size_t train) const {
    return value > 0
               ? value
               : std::max(1, static_cast<int>(std::lround(std::log(static_cast<double>(train)))));
  }
};

struct Sample {
  std::string key;  // path relative to the dataset folder: names the perturbation seed
  std::string label;
  int label_id = 0;
  int fold = 0;        // the fold it is tested in
  bool train = false;  // hold-out: in the training split (never tested)
  PointCloud cloud;
};

struct Dataset {
  std::string name;
  std::string protocol;  // "holdout" | "kfold"
  int folds = 1;         // rounds
  std::vector<std::string> labels;
  std::vector<Sample> samples;
  bool Trains(const Sample& s, int round) const {
    return protocol == "holdout" ? s.train : s.fold != round;
  }
  bool Tests(const Sample& s, int round) const {
    return protocol == "holdout" ? !s.train : s.fold == round;
  }
};

// The first `per_label` files of each label, for --quick.
std::vector<LabeledFile> FirstPerLabel(const std::vector<LabeledFile>& files, size_t per_label) {
  std::map<std::string, size_t> taken;
  std::vector<LabeledFile> out;
  for (const LabeledFile& f : files) {
    if (taken[f.label]++ < per_label) out.push_back(f);
  }
  return out;
}

absl::Status LoadClouds(const std::string& root, Dataset* data, int threads) {
  std::vector<absl::Status> errors(data->samples.size());
  ParallelFor(data->samples.size(), threads, [&](size_t i) {
    Sample& s = data->samples[i];
    absl::StatusOr<ReadResult> read = ReadPointCloud((fs::path(root) / s.key).string());
    if (read.ok()) {
      s.cloud = std::move(read->cloud);
    } else {
      errors[i] = read.status();
    }
  });
  for (const absl::Status& e : errors) {
    if (!e.ok()) return e;
  }
  std::map<std::string, int> ids;
  for (Sample& s : data->samples) {
    auto [it, inserted] = ids.emplace(s.label, static_cast<int>(data->labels.size()));
    if (inserted) data->labels.push_back(s.label);
    s.label_id = it->second;
  }
  return absl::OkStatus();
}

std::string Relative(const std::string& path, const std::string& root) {
  return fs::path(path).lexically_relative(root).generic_string();
}

absl::StatusOr<Dataset> LoadModelNet(const std::string& root, bool quick, int threads) {
  Dataset data;
  data.name = "modelnet10";
  data.protocol = "holdout";
  absl::StatusOr<std::vector<LabeledFile>> train = LabeledFiles(root, Split::kTrain);
  if (!train.ok()) return train.status();
  absl::StatusOr<std::vector<LabeledFile>> test = LabeledFiles(root, Split::kTest);
  if (!test.ok()) return test.status();
  if (quick) {
    *train = FirstPerLabel(*train, 4);
    *test = FirstPerLabel(*test, 2);
  }
  for (const auto& [files, is_train] : {std::pair{&*train, true}, std::pair{&*test, false}}) {
    for (const LabeledFile& f : *files) {
      Sample s;
      s.key = Relative(f.path, root);
      s.label = f.label;
      s.train = is_train;
      data.samples.push_back(std::move(s));
    }
  }
  if (absl::Status s = LoadClouds(root, &data, threads); !s.ok()) return s;
  return data;
}

absl::StatusOr<Dataset> LoadDales(const std::string& root, bool quick, int folds, uint64_t seed,
                                  int threads) {
  Dataset data;
  data.name = "dales";
  data.protocol = "kfold";
  data.folds = folds;
  absl::StatusOr<std::vector<LabeledFile>> files = LabeledFiles(root, Split::kAll);
  if (!files.ok()) return files.status();
  if (quick) *files = FirstPerLabel(*files, 6);
  // The fold assignment of `shapeid eval --folds`, so the two tools agree cloud for cloud.
  const std::vector<int> fold = StratifiedFolds(*files, folds, seed);
  for (size_t i = 0; i < files->size(); ++i) {
    Sample s;
    s.key = Relative((*files)[i].path, root);
    s.label = (*files)[i].label;
    s.fold = fold[i];
    data.samples.push_back(std::move(s));
  }
  if (absl::Status s = LoadClouds(root, &data, threads); !s.ok()) return s;
  return data;
}

// ----------------------------------------------------------------------------- describe

// The descriptors of some clouds under one spec; empty vectors where Compute failed.
struct Described {
  // By sample index: the descriptor followed by its pose variants (a query matches the best
  // of them, as GallerySnapshot::Classify does), or for a gallery cloud its descriptor
  // followed by its augmented views' (a sample matches by its best view).
  std::vector<std::vector<float>> features;
  std::vector<double> micros;  // per described cloud
  size_t failed = 0;
  size_t vectors = 0;  // descriptors over all described clouds (poses or views)
};

Described DescribeAll(const Descriptor& descriptor, const std::vector<const PointCloud*>& clouds,
                      int threads) {
  Described d;
  d.features.resize(clouds.size());
  std::vector<double> micros(clouds.size(), -1);
  ParallelFor(clouds.size(), threads, [&](size_t i) {
    if (clouds[i] == nullptr) return;
    const auto start = Clock::now();
    std::vector<float> v, variants;
    const absl::Status status = descriptor.ComputeWithPoseVariants(*clouds[i], &v, &variants);
    micros[i] = std::chrono::duration<double, std::micro>(Clock::now() - start).count();
    if (!status.ok()) return;
    v.insert(v.end(), variants.begin(), variants.end());
    d.features[i] = std::move(v);
  });
  for (size_t i = 0; i < clouds.size(); ++i) {
    if (clouds[i] == nullptr) continue;
    d.micros.push_back(micros[i]);
    d.failed += d.features[i].empty();
    d.vectors += d.features[i].size() / descriptor.dimension();
  }
  return d;
}

// The gallery's descriptors of the training clouds (train[i] says which), exactly as a
// gallery stores them (DescribeForTraining): each cloud's own, then those of its augmented
// views, which are seeded by the cloud's content.
Described DescribeGallery(const Descriptor& descriptor, const Dataset& data,
                          const std::vector<bool>& train, const AugmentOptions& augment,
                          int threads) {
  Described d;
  d.features.resize(data.samples.size());
  ParallelFor(data.samples.size(), threads, [&](size_t i) {
    if (!train[i]) return;
    absl::StatusOr<std::vector<float>> features =
        DescribeForTraining(descriptor, data.samples[i].cloud, augment);
    if (features.ok()) d.features[i] = std::move(*features);
  });
  for (size_t i = 0; i < data.samples.size(); ++i) {
    if (!train[i]) continue;
    d.failed += d.features[i].empty();
    d.vectors += d.features[i].size() / descriptor.dimension();
  }
  return d;
}

// Median single-thread time of one cloud, after a warm-up.
double TimeOne(const Descriptor& descriptor, const PointCloud& cloud) {
  std::vector<float> out;
  (void)descriptor.Compute(cloud, &out);
  std::vector<double> t;
  for (int r = 0; r < 31; ++r) {
    const auto start = Clock::now();
    (void)descriptor.Compute(cloud, &out);
    t.push_back(std::chrono::duration<double, std::micro>(Clock::now() - start).count());
  }
  return Median(t);
}

// ----------------------------------------------------------------------------- voting

// KnnIndex::Classify's vote over the first k of `neighbors` (sorted nearest first, ties in
// insertion order, as Search returns them): weights summed in neighbor order, classes in
// order of their nearest neighbor, the most weight wins and ties go to the earlier class;
// with distance weighting and a neighbor at distance 0, only those at 0 vote, one each.
struct Vote {
  const std::string* label = nullptr;
  double confidence = 0;
};

Vote VoteOf(const std::vector<Neighbor>& neighbors, size_t k, bool by_distance) {
  k = std::min(k, neighbors.size());
  bool any_zero = false;
  for (size_t i = 0; i < k; ++i) any_zero = any_zero || neighbors[i].distance == 0.0;
  std::vector<std::pair<const std::string*, double>> votes;
  for (size_t i = 0; i < k; ++i) {
    double w = 1.0;
    if (by_distance && any_zero) {
      w = neighbors[i].distance == 0.0 ? 1.0 : 0.0;
    } else if (by_distance) {
      w = 1.0 / neighbors[i].distance;
    }
    size_t v = 0;
    while (v < votes.size() && *votes[v].first != neighbors[i].label) ++v;
    if (v == votes.size()) votes.emplace_back(&neighbors[i].label, 0.0);
    votes[v].second += w;
  }
  size_t best = 0;
  double total = 0;
  for (size_t v = 0; v < votes.size(); ++v) {
    total += votes[v].second;
    if (votes[v].second > votes[best].second) best = v;
  }
  return Vote{votes[best].first, total > 0.0 ? votes[best].second / total : 1.0};
}

// ----------------------------------------------------------------------------- the run

struct Settings {
  std::vector<KChoice> ks;
  std::vector<VoteWeighting> weightings;
  std::vector<FeatureScaling> scalings;
  std::vector<Perturbation> perturbations;
  uint64_t seed = 1;
  int threads = 2;
  size_t verify_every = 16;
  std::FILE* out = stdout;
};

// Counts for one (k, weighting) over the rounds.
struct Tally {
  std::vector<int> right_per_round, tested_per_round;
  std::vector<int> right_per_class, tested_per_class;
  std::vector<int> k_used;
};

std::string FoldList(const std::vector<double>& v) {
  return absl::StrCat(
      "[",
      absl::StrJoin(
          v, ",", [](std::string* s, double x) { absl::StrAppend(s, absl::StrFormat("%.4f", x)); }),
      "]");
}

struct PerturbedSet {
  Perturbation perturbation;
  std::vector<PointCloud> clouds;  // by sample index; empty where not tested
  std::vector<bool> ok;            // the perturbation succeeded
  // Points kept / points over the tested clouds: mean, least, most.
  double kept_fraction = 1, kept_min = 1, kept_max = 1;
};

PerturbedSet Perturb(const Dataset& data, const Perturbation& p, uint64_t seed, int threads) {
  PerturbedSet set;
  set.perturbation = p;
  set.clouds.resize(data.samples.size());
  set.ok.assign(data.samples.size(), false);
  std::vector<double> kept(data.samples.size(), -1);
  ParallelFor(data.samples.size(), threads, [&](size_t i) {
    const Sample& s = data.samples[i];
    if (data.protocol == "holdout" && s.train) return;
    absl::StatusOr<PointCloud> c =
        ApplyPerturbation(s.cloud, p, DeriveSeed(seed, absl::StrCat(p.name, "|", s.key)));
    if (!c.ok()) return;
    kept[i] = static_cast<double>(c->size()) / static_cast<double>(s.cloud.size());
    set.clouds[i] = std::move(*c);
    set.ok[i] = true;
  });
  double sum = 0;
  size_t n = 0;
  set.kept_min = 1;
  set.kept_max = 0;
  for (double k : kept) {
    if (k >= 0) {
      sum += k;
      ++n;
      set.kept_min = std::min(set.kept_min, k);
      set.kept_max = std::max(set.kept_max, k);
    }
  }
  set.kept_fraction = n > 0 ? sum / static_cast<double>(n) : 0;
  return set;
}

// Evaluates one spec on one dataset for every perturbation, writing its JSON lines. Returns
// false when a derived vote differed from Classify.
bool EvaluateSpec(const Dataset& data, const SpecEntry& entry, const Described& gallery,
                  const Described& clean, const std::vector<const PerturbedSet*>& perturbed,
                  const std::vector<const Described*>& perturbed_features, double micros_1024,
                  const Settings& settings) {
  const Descriptor& descriptor = *entry.descriptor;
  // One index per round, on the training clouds that could be described (with their
  // augmented views, if any).
  std::vector<KnnIndex> indices;
  std::vector<size_t> train_sizes;
  int64_t gallery_vectors = 0;
  for (int r = 0; r < data.folds; ++r) {
    KnnIndex index = *KnnIndex::Create(static_cast<int>(descriptor.dimension()));
    for (size_t i = 0; i < data.samples.size(); ++i) {
      const Sample& s = data.samples[i];
      if (!data.Trains(s, r) || gallery.features[i].empty()) continue;
      (void)index.Add(i, s.label, gallery.features[i]);  // ids unique, features finite
    }
    train_sizes.push_back(static_cast<size_t>(index.size()));
    gallery_vectors = std::max(gallery_vectors, index.num_rows());
    indices.push_back(std::move(index));
  }
  const size_t nk = settings.ks.size(), nw = settings.weightings.size();
  const size_t num_labels = data.labels.size();
  std::atomic<bool> mismatch{false};

  for (size_t p = 0; p < perturbed.size(); ++p) {
    const Described& queries = perturbed[p] == nullptr ? clean : *perturbed_features[p];
    const std::string perturbation_name =
        perturbed[p] == nullptr ? "clean" : perturbed[p]->perturbation.name;
    const double kept = perturbed[p] == nullptr ? 1.0 : perturbed[p]->kept_fraction;
    const double kept_min = perturbed[p] == nullptr ? 1.0 : perturbed[p]->kept_min;
    const double kept_max = perturbed[p] == nullptr ? 1.0 : perturbed[p]->kept_max;
    for (FeatureScaling scaling : settings.scalings) {
      std::vector<Tally> tallies(nk * nw);
      for (Tally& t : tallies) {
        t.right_per_round.assign(data.folds, 0);
        t.tested_per_round.assign(data.folds, 0);
        t.right_per_class.assign(num_labels, 0);
        t.tested_per_class.assign(num_labels, 0);
      }
      for (int r = 0; r < data.folds; ++r) {
        const KnnIndex& index = indices[r];
        std::vector<int> k_of(nk);
        int k_max = 1;
        for (size_t a = 0; a < nk; ++a) {
          k_of[a] = settings.ks[a].Resolve(train_sizes[r]);
          k_max = std::max(k_max, k_of[a]);
        }
        std::vector<size_t> tested;
        for (size_t i = 0; i < data.samples.size(); ++i) {
          if (data.Tests(data.samples[i], r)) tested.push_back(i);
        }
        // right[q * nk * nw + a * nw + b]: query q right under k a, weighting b.
        std::vector<char> right(tested.size() * nk * nw, 0);
        ParallelFor(tested.size(), settings.threads, [&](size_t q) {
          const size_t i = tested[q];
          const std::vector<float>& query = queries.features[i];
          if (query.empty() || index.empty()) return;  // not described: counts as wrong
          absl::StatusOr<std::vector<Neighbor>> found = index.Search(query, k_max, scaling);
          if (!found.ok()) return;
          const bool verify = q % settings.verify_every == 0;
          for (size_t a = 0; a < nk; ++a) {
            for (size_t b = 0; b < nw; ++b) {
              const bool by_distance = settings.weightings[b] == VoteWeighting::kDistance;
              const Vote vote = VoteOf(*found, static_cast<size_t>(k_of[a]), by_distance);
              right[(q * nk + a) * nw + b] = *vote.label == data.samples[i].label;
              if (!verify) continue;
              KnnOptions options;
              options.k = k_of[a];
              options.weighting = settings.weightings[b];
              options.scaling = scaling;
              absl::StatusOr<KnnResult> check = index.Classify(query, options);
              if (!check.ok() || check->label != *vote.label ||
                  check->confidence != vote.confidence) {
                mismatch = true;
              }
            }
          }
        });
        for (size_t q = 0; q < tested.size(); ++q) {
          const Sample& s = data.samples[tested[q]];
          for (size_t c = 0; c < nk * nw; ++c) {
            Tally& t = tallies[c];
            const int ok = right[q * nk * nw + c];
            t.right_per_round[r] += ok;
            t.tested_per_round[r] += 1;
            t.right_per_class[s.label_id] += ok;
            t.tested_per_class[s.label_id] += 1;
          }
        }
        for (size_t a = 0; a < nk; ++a) {
          for (size_t b = 0; b < nw; ++b) tallies[a * nw + b].k_used.push_back(k_of[a]);
        }
      }
      for (size_t a = 0; a < nk; ++a) {
        for (size_t b = 0; b < nw; ++b) {
          const Tally& t = tallies[a * nw + b];
          int right_all = 0, tested_all = 0;
          std::vector<double> fold_acc;
          for (int r = 0; r < data.folds; ++r) {
            right_all += t.right_per_round[r];
            tested_all += t.tested_per_round[r];
            fold_acc.push_back(t.tested_per_round[r] > 0
                                   ? 100.0 * t.right_per_round[r] / t.tested_per_round[r]
                                   : 0.0);
          }
          double mean = 0, var = 0, class_mean = 0;
          for (double x : fold_acc) mean += x / static_cast<double>(fold_acc.size());
          for (double x : fold_acc)
            var += (x - mean) * (x - mean) / static_cast<double>(fold_acc.size());
          std::string per_class;
          int classes = 0;
          for (size_t c = 0; c < num_labels; ++c) {
            if (t.tested_per_class[c] == 0) continue;
            const double acc = 100.0 * t.right_per_class[c] / t.tested_per_class[c];
            class_mean += acc;
            ++classes;
            absl::StrAppend(&per_class, per_class.empty() ? "" : ",", JsonString(data.labels[c]),
                            ":", absl::StrFormat("%.4f", acc));
          }
          class_mean = classes > 0 ? class_mean / classes : 0;
          std::vector<int> k_used = t.k_used;
          std::sort(k_used.begin(), k_used.end());
          k_used.erase(std::unique(k_used.begin(), k_used.end()), k_used.end());
          const std::string line = absl::StrCat(
              "{\"dataset\":", JsonString(data.name), ",\"protocol\":", JsonString(data.protocol),
              ",\"group\":", JsonString(entry.group), ",\"spec\":", JsonString(entry.name),
              ",\"augment\":", JsonString(AugmentOptionsToString(entry.augment)),
              ",\"default\":", entry.is_default ? "true" : "false",
              ",\"gallery_vectors\":", gallery_vectors, ",\"query_poses_mean\":",
              absl::StrFormat("%.3f", queries.micros.empty()
                                          ? 0.0
                                          : static_cast<double>(queries.vectors) /
                                                static_cast<double>(queries.micros.size())),
              ",\"dimension\":", descriptor.dimension(), ",\"k\":", JsonString(settings.ks[a].name),
              ",\"k_used\":[", absl::StrJoin(k_used, ","), "],\"weighting\":",
              JsonString(std::string(VoteWeightingName(settings.weightings[b]))),
              ",\"scaling\":", JsonString(std::string(FeatureScalingName(scaling))),
              ",\"perturbation\":", JsonString(perturbation_name), ",\"accuracy\":",
              absl::StrFormat("%.4f", tested_all > 0 ? 100.0 * right_all / tested_all : 0.0),
              ",\"mean_class_accuracy\":", absl::StrFormat("%.4f", class_mean),
              ",\"fold_accuracy\":", FoldList(fold_acc),
              ",\"fold_mean\":", absl::StrFormat("%.4f", mean),
              ",\"fold_std\":", absl::StrFormat("%.4f", std::sqrt(var)), ",\"correct\":", right_all,
              ",\"tested\":", tested_all, ",\"train\":[", absl::StrJoin(train_sizes, ","),
              "],\"describe_failed\":", queries.failed,
              ",\"kept_fraction\":", absl::StrFormat("%.4f", kept), ",\"kept_fraction_range\":[",
              absl::StrFormat("%.4f,%.4f", kept_min, kept_max),
              "],\"describe_us_median\":", absl::StrFormat("%.2f", Median(queries.micros)),
              ",\"describe_us_1024\":", absl::StrFormat("%.2f", micros_1024),
              ",\"class_accuracy\":{", per_class, "},\"seed\":", settings.seed, "}\n");
          std::fputs(line.c_str(), settings.out);
        }
      }
    }
  }
  std::fflush(settings.out);
  return !mismatch;
}

// Every spec on one dataset. Returns the exit status.
int RunDataset(const Dataset& data, const std::vector<SpecEntry>& specs,
               const PointCloud& cloud_1024, const Settings& settings) {
  const auto start = Clock::now();
  size_t tests = 0;
  for (const Sample& s : data.samples) tests += !(data.protocol == "holdout" && s.train);

  // Perturbed test clouds, made once and described by every spec.
  std::vector<PerturbedSet> sets;
  for (const Perturbation& p : settings.perturbations) {
    if (p.kind == Perturbation::Kind::kNone) continue;
    sets.push_back(Perturb(data, p, settings.seed, settings.threads));
    Progress(absl::StrFormat(
        "%s: %s test clouds made (%zu), %.1f %% of the points kept on average (%.1f to %.1f %%)",
        data.name, p.name, tests, 100 * sets.back().kept_fraction, 100 * sets.back().kept_min,
        100 * sets.back().kept_max));
  }
  std::vector<bool> train(data.samples.size(), false);
  std::vector<const PointCloud*> test_clouds(data.samples.size(), nullptr);
  for (size_t i = 0; i < data.samples.size(); ++i) {
    const bool trains = data.protocol == "kfold" || data.samples[i].train;
    train[i] = trains;
    if (!(data.protocol == "holdout" && trains)) test_clouds[i] = &data.samples[i].cloud;
  }
  for (size_t s = 0; s < specs.size(); ++s) {
    const SpecEntry& entry = specs[s];
    const Described gallery =
        DescribeGallery(*entry.descriptor, data, train, entry.augment, settings.threads);
    const Described clean = DescribeAll(*entry.descriptor, test_clouds, settings.threads);
    std::vector<Described> described;
    described.reserve(sets.size());
    for (const PerturbedSet& set : sets) {
      std::vector<const PointCloud*> clouds(data.samples.size(), nullptr);
      for (size_t i = 0; i < set.clouds.size(); ++i) {
        const bool tested = !(data.protocol == "holdout" && data.samples[i].train);
        if (tested) clouds[i] = &set.clouds[i];  // a failed perturbation is an empty cloud
      }
      described.push_back(DescribeAll(*entry.descriptor, clouds, settings.threads));
    }
    std::vector<const PerturbedSet*> order;
    std::vector<const Described*> order_features;
    size_t next_set = 0;
    for (const Perturbation& p : settings.perturbations) {
      if (p.kind == Perturbation::Kind::kNone) {
        order.push_back(nullptr);
        order_features.push_back(&clean);
      } else {
        order.push_back(&sets[next_set]);
        order_features.push_back(&described[next_set]);
        ++next_set;
      }
    }
    const double micros_1024 = TimeOne(*entry.descriptor, cloud_1024);
    if (!EvaluateSpec(data, entry, gallery, clean, order, order_features, micros_1024, settings)) {
      std::fprintf(stderr,
                   "accuracy_grid: INTERNAL ERROR: a vote derived from the neighbor list differs "
                   "from KnnIndex::Classify (%s on %s)\n",
                   entry.name.c_str(), data.name.c_str());
      return kExitMismatch;
    }
    Progress(absl::StrFormat("%s: [%zu/%zu] %s  (%.0f us/cloud, %zu not described) %.1f s",
                             data.name, s + 1, specs.size(), entry.name, Median(clean.micros),
                             clean.failed,
                             std::chrono::duration<double>(Clock::now() - start).count()));
  }
  return 0;
}

// A 1,024-point cloud for the describe time: the first cloud with at least that many points,
// subsampled to exactly 1,024.
PointCloud Cloud1024(const std::vector<Dataset>& datasets) {
  for (const Dataset& d : datasets) {
    for (const Sample& s : d.samples) {
      if (s.cloud.size() >= 1024) return RandomSubsample(s.cloud, 1024, 1);
    }
  }
  return datasets.front().samples.front().cloud;
}

int Main(int argc, char** argv) {
  CLI::App app{
      "Accuracy grid: descriptor specs x k x weighting x scaling x test perturbation, "
      "on ModelNet10 (hold-out) and DALES Objects (stratified k-fold); JSON Lines"};
  const fs::path shared = fs::path(SHAPEID_SOURCE_DIR) / ".." / "shared" / "data";
  std::string modelnet_dir = (shared / "modelnet10").string();
  std::string dales_dir = (shared / "dales-objects").string();
  std::vector<std::string> dataset_names = {"modelnet10", "dales"};
  std::vector<std::string> spec_texts, specs_files;
  std::vector<std::string> k_names = {"1", "5", "9", "ln"};
  std::vector<std::string> weighting_names = {"uniform", "distance"};
  std::vector<std::string> scaling_names = {"none", "zscore", "maxabs"};
  std::vector<std::string> perturbation_names = {"clean"};
  std::string out_path = "-";
  Settings settings;
  int folds = 5;
  bool quick = false;
  app.add_option("--modelnet", modelnet_dir, "ModelNet10: <class>/{train,test}/*")
      ->capture_default_str();
  app.add_option("--dales", dales_dir, "DALES Objects: <class>/*")->capture_default_str();
  app.add_option("--datasets", dataset_names, "modelnet10, dales")
      ->delimiter(',')
      ->capture_default_str();
  app.add_option("--spec", spec_texts,
                 "a descriptor spec, optionally followed by the gallery's view augmentation: "
                 "'dfsd:frame=box +views=8 [+pose=random]' (repeatable)");
  app.add_option(
      "--specs-file", specs_files,
      "specs, one per line; '#' comments; '[name]' starts a section (the records' group)");
  app.add_option("--k", k_names, "neighbor counts; 'ln' = round(ln N_train)")
      ->delimiter(',')
      ->capture_default_str();
  app.add_option("--weighting", weighting_names, "uniform, distance")
      ->delimiter(',')
      ->capture_default_str();
  app.add_option("--scaling", scaling_names, "none, zscore, maxabs")
      ->delimiter(',')
      ->capture_default_str();
  app.add_option(
         "--perturb", perturbation_names,
         "test-cloud perturbations: clean, yaw, rot3d, noise1, noise3, sub256, sub128, partial, "
         "robot (one side, 1 % noise, 300-500 points, random pose)")
      ->delimiter(',')
      ->capture_default_str();
  app.add_option("--seed", settings.seed, "fold assignment and perturbation seed")
      ->capture_default_str();
  app.add_option("--folds", folds, "DALES folds")->capture_default_str()->check(CLI::Range(2, 100));
  app.add_option("--threads", settings.threads, "worker threads")
      ->capture_default_str()
      ->check(CLI::Range(1, 256));
  app.add_option("--verify-every", settings.verify_every,
                 "check every n-th query's derived votes against KnnIndex::Classify")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  app.add_option("--out", out_path, "JSON Lines output ('-': stdout)")->capture_default_str();
  app.add_flag("--quick", quick,
               "a slice for CI: 4 train + 2 test clouds per ModelNet10 class, 6 per DALES class, "
               "the three default specs unless given, every perturbation, every query verified");
  CLI11_PARSE(app, argc, argv);

  const auto usage = [](const std::string& message) {
    std::fprintf(stderr, "accuracy_grid: %s\n", message.c_str());
    return kExitUsage;
  };
  if (quick) {
    settings.verify_every = 1;
    if (app.count("--perturb") == 0) {
      perturbation_names = {"clean",  "yaw",    "rot3d",   "noise1", "noise3",
                            "sub256", "sub128", "partial", "robot"};
    }
    if (app.count("--k") == 0) k_names = {"1", "3", "ln"};
  }

  // Specs: command line, then files; duplicates (same canonical spec) run once.
  std::vector<std::pair<std::string, std::string>> raw;
  for (const std::string& s : spec_texts) raw.emplace_back("", s);
  for (const std::string& f : specs_files) {
    if (absl::Status s = ReadSpecsFile(f, &raw); !s.ok()) return usage(std::string(s.message()));
  }
  if (raw.empty() && quick) {
    for (const char* s : {"rphsd", "comsd", "cnsd", "dfsd:frame=box +views=2"}) {
      raw.emplace_back("", s);
    }
  }
  if (raw.empty()) return usage("no descriptor spec: give --spec or --specs-file");
  std::vector<SpecEntry> specs;
  for (const auto& [group, text] : raw) {
    std::string spec_text;
    AugmentOptions augment;
    if (absl::Status s = ParseSpecLine(text, &spec_text, &augment); !s.ok()) {
      return usage(absl::StrCat("spec \"", text, "\": ", s.message()));
    }
    absl::StatusOr<std::unique_ptr<Descriptor>> d = CreateDescriptor(spec_text);
    if (!d.ok()) return usage(absl::StrCat("spec \"", text, "\": ", d.status().message()));
    const std::string canonical = (*d)->spec().ToString();
    std::string name = canonical;
    if (augment.enabled()) {
      absl::StrAppend(&name, " +views=", augment.views,
                      augment.sensor.random_pose ? " +pose=random" : "");
    }
    bool seen = false;
    for (const SpecEntry& e : specs) seen |= e.name == name;
    if (seen) continue;
    const bool is_default =
        !augment.enabled() &&
        canonical == (*CreateDescriptor(kDefaultDescriptorSpec))->spec().ToString();
    specs.push_back({group.empty() ? (*d)->spec().kind : group, std::move(*d), canonical, augment,
                     name, is_default});
  }
  for (const std::string& k : k_names) {
    int value = 0;
    if (absl::AsciiStrToLower(k) == "ln") {
      settings.ks.push_back({"ln", 0});
    } else if (absl::SimpleAtoi(k, &value) && value >= 1) {
      settings.ks.push_back({absl::StrCat(value), value});
    } else {
      return usage(absl::StrCat("--k: \"", k, "\" is neither a positive number nor ln"));
    }
  }
  for (const std::string& w : weighting_names) {
    absl::StatusOr<VoteWeighting> v = ParseVoteWeighting(w);
    if (!v.ok()) return usage(std::string(v.status().message()));
    settings.weightings.push_back(*v);
  }
  for (const std::string& s : scaling_names) {
    absl::StatusOr<FeatureScaling> v = ParseFeatureScaling(s);
    if (!v.ok()) return usage(std::string(v.status().message()));
    settings.scalings.push_back(*v);
  }
  for (const std::string& p : perturbation_names) {
    absl::StatusOr<Perturbation> v = ParsePerturbation(p);
    if (!v.ok()) return usage(std::string(v.status().message()));
    settings.perturbations.push_back(*v);  // partial: uniform over the sphere; yaw about +z
  }

  const auto start = Clock::now();
  std::vector<Dataset> datasets;
  std::vector<std::string> skipped;
  for (const std::string& name : dataset_names) {
    const std::string& dir = name == "modelnet10" ? modelnet_dir : dales_dir;
    if (name != "modelnet10" && name != "dales") {
      return usage(absl::StrCat("--datasets: unknown \"", name, "\"; known: modelnet10, dales"));
    }
    if (!fs::is_directory(dir)) {
      skipped.push_back(absl::StrCat("no ", name, " data at ", dir));
      continue;
    }
    absl::StatusOr<Dataset> d = name == "modelnet10"
                                    ? LoadModelNet(dir, quick, settings.threads)
                                    : LoadDales(dir, quick, folds, settings.seed, settings.threads);
    if (!d.ok()) return usage(std::string(d.status().message()));
    Progress(absl::StrFormat("%s: %zu clouds read (%s, %d round%s)", name, d->samples.size(),
                             d->protocol, d->folds, d->folds > 1 ? "s" : ""));
    datasets.push_back(std::move(*d));
  }
  if (datasets.empty()) {
    std::printf("SKIPPED: %s\n", absl::StrJoin(skipped, "; ").c_str());
    return kExitSkip;
  }
  for (const std::string& s : skipped) Progress(absl::StrCat("skipping: ", s));

  std::FILE* out = stdout;
  if (out_path != "-") {
    out = std::fopen(out_path.c_str(), "w");
    if (out == nullptr) return usage(absl::StrCat(out_path, ": cannot write"));
  }
  settings.out = out;
  const PointCloud cloud_1024 = Cloud1024(datasets);
  int status = 0;
  for (const Dataset& d : datasets) {
    status = RunDataset(d, specs, cloud_1024, settings);
    if (status != 0) break;
  }
  if (out != stdout && std::fclose(out) != 0)
    return usage(absl::StrCat(out_path, ": write failed"));
  Progress(absl::StrFormat("done in %.1f s",
                           std::chrono::duration<double>(Clock::now() - start).count()));
  return status;
}

}  // namespace
}  // namespace shapeid

int main(int argc, char** argv) { return shapeid::Main(argc, argv); }
