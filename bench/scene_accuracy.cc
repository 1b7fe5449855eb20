// Scene recognition accuracy (issue 29, "Done when" 1): tabletop frames with the truth of
// every point, recognized by RecognizeScene against a ModelNet10 gallery, scored per object.
// Protocol, figures and what was tuned on what: docs/accuracy.md, "Scenes".
//
//   scene_accuracy                                    # calibrate, then test scenes A
//   scene_accuracy --calibrate-only --spec dfsd       # compare gallery configurations
//   scene_accuracy --scenes build/independent-scenes  # also test scenes B from disk
//   scene_accuracy --frames 20 --write-scenes /tmp/a  # write scenes A in the on-disk format
//   scene_accuracy --instances --frames 0 --scenes build/independent-scenes
//                                                     # B against a gallery of its own objects
//
// The gallery: the TRAIN split (--instances: the TEST split, for instance recognition of
// scenes B), trained in-process with view augmentation as a gallery does.
// Every 10th training file per class is held out to calibrate: frames composed from those
// objects (no clutter) give the nearest-neighbor distances of known, unseen objects, whose
// --reject-percentile is the gallery's reject distance; the held-out files then join the
// gallery. Scenes A: TEST-split objects and clutter in no gallery (primitives from
// core/views/test_surfaces.h and DALES objects), composed by core/views/scene_composer.h and
// seen by the project's simulator. Scenes B: a set on disk (core/io/scene_files.h).
//
// Exit status: 0 done (or skipped: no data), 2 bad arguments or data.

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <string>
#include <unordered_map>
#include <vector>

#include "CLI/CLI.hpp"
#include "bench/host_info.h"
#include "bench/percentile.h"
#include "core/gallery/gallery.h"
#include "core/io/point_cloud_reader.h"
#include "core/io/scene_files.h"
#include "core/random.h"
#include "core/scene/scene_recognition.h"
#include "core/views/perturb.h"
#include "core/views/scene_composer.h"
#include "core/views/test_surfaces.h"

namespace fs = std::filesystem;
using namespace shapeid;
using shapeid::SceneFile;
using shapeid::SceneFileObject;

namespace {

std::vector<fs::path> SortedEntries(const fs::path& dir) {
  std::vector<fs::path> entries;
  if (!fs::is_directory(dir)) return entries;
  for (const auto& entry : fs::directory_iterator(dir)) entries.push_back(entry.path());
  std::sort(entries.begin(), entries.end());
  return entries;
}

[[noreturn]] void Fail(const std::string& what, const absl::Status& status) {
  std::fprintf(stderr, "scene_accuracy: %s: %s\n", what.c_str(),
               std::string(status.message()).c_str());
  std::exit(2);
}

struct Model {
  std::string label;
  std::string source;
  PointCloud cloud;
};

// Per-object outcome counts over a set of frames.
struct Tally {
  int frames = 0, objects = 0, hidden = 0;  // hidden: fewer visible points than counted
  int separated = 0, separated_found = 0, visible = 0, found = 0;
  int gallery_found = 0, correct = 0, wrong = 0, rejected = 0, merged = 0;
  int clutter_found = 0, clutter_unknown = 0;
  int stray_clusters = 0;               // clusters mostly table or a mix of objects
  std::vector<double> known_distances;  // nearest neighbor of each found gallery object
  std::vector<double> seconds;          // RecognizeScene per frame
};

double Rate(int a, int b) { return b == 0 ? 0 : 100.0 * a / b; }

// An object's points within `distance` of another object's: not separated.
std::vector<bool> SeparatedObjects(const PointCloud& frame, const std::vector<uint16_t>& truth,
                                   size_t objects, double distance) {
  std::unordered_map<int64_t, std::vector<uint32_t>> cells;
  const auto cell = [distance](float v) { return static_cast<int64_t>(std::floor(v / distance)); };
  const auto key = [](int64_t x, int64_t y, int64_t z) {
    return (x * 73856093) ^ (y * 19349663) ^ (z * 83492791);
  };
  for (uint32_t i = 0; i < frame.size(); ++i) {
    if (truth[i] == 0 || !frame.point(i).allFinite()) continue;
    const auto p = frame.point(i);
    cells[key(cell(p.x()), cell(p.y()), cell(p.z()))].push_back(i);
  }
  std::vector<bool> separated(objects + 1, true);
  const double d2 = distance * distance;
  for (const auto& [k, members] : cells) {
    (void)k;
    for (const uint32_t i : members) {
      if (!separated[truth[i]]) continue;
      const auto p = frame.point(i);
      const int64_t cx = cell(p.x()), cy = cell(p.y()), cz = cell(p.z());
      for (int64_t dz = -1; dz <= 1 && separated[truth[i]]; ++dz) {
        for (int64_t dy = -1; dy <= 1 && separated[truth[i]]; ++dy) {
          for (int64_t dx = -1; dx <= 1 && separated[truth[i]]; ++dx) {
            const auto found = cells.find(key(cx + dx, cy + dy, cz + dz));
            if (found == cells.end()) continue;
            for (const uint32_t j : found->second) {
              if (truth[j] != truth[i] && (frame.point(j) - p).squaredNorm() < d2) {
                separated[truth[i]] = separated[truth[j]] = false;
                break;
              }
            }
          }
        }
      }
    }
  }
  return separated;
}

// Scores one recognized frame. An object is found when one cluster holds >= 50 % of its
// points; a cluster speaks for the object holding most of its points, and a found object is
// labeled by its cluster only if the cluster speaks for it (else: merged).
void Score(const PointCloud& frame, const std::vector<uint16_t>& truth,
           const std::vector<SceneFileObject>& objects, const SceneRecognition& recognition,
           size_t min_points, double separation, bool verbose, Tally* tally) {
  const size_t n = objects.size();
  std::vector<size_t> points(n + 1);
  for (const uint16_t t : truth) ++points[t];
  const std::vector<bool> separated = SeparatedObjects(frame, truth, n, separation);
  std::vector<int> cluster_of(n + 1, -1), speaks_for(recognition.objects.size(), 0);
  for (size_t c = 0; c < recognition.objects.size(); ++c) {
    std::vector<size_t> counts(n + 1);
    for (const uint32_t i : recognition.objects[c].indices) ++counts[truth[i]];
    size_t best = 0;  // the object with the most points here, 0: none
    for (size_t k = 1; k <= n; ++k) {
      if (counts[k] > (best == 0 ? 0 : counts[best])) best = k;
      if (cluster_of[k] < 0 && counts[k] > 0 && 2 * counts[k] >= points[k]) {
        cluster_of[k] = static_cast<int>(c);
      }
    }
    speaks_for[c] = static_cast<int>(best);
    if (best == 0 || 2 * counts[best] < recognition.objects[c].indices.size()) {
      ++tally->stray_clusters;
    }
  }
  ++tally->frames;
  for (size_t k = 1; k <= n; ++k) {
    ++tally->objects;
    if (points[k] < min_points) {
      ++tally->hidden;
      continue;
    }
    const bool found = cluster_of[k] >= 0;
    if (!found && separated[k] && verbose) {
      size_t in_clusters = 0, best = 0;
      for (const RecognizedObject& o : recognition.objects) {
        size_t here = 0;
        for (const uint32_t i : o.indices) here += truth[i] == k ? 1 : 0;
        in_clusters += here;
        best = std::max(best, here);
      }
      std::printf(
          "# missed separated object %zu (%s, %s): %zu points, %zu in clusters, at most "
          "%zu in one\n",
          k, objects[k - 1].label.c_str(), objects[k - 1].source.c_str(), points[k], in_clusters,
          best);
    }
    ++tally->visible;
    tally->found += found;
    if (separated[k]) {
      ++tally->separated;
      tally->separated_found += found;
    }
    if (!found) continue;
    const RecognizedObject& answer = recognition.objects[static_cast<size_t>(cluster_of[k])];
    const bool own = speaks_for[static_cast<size_t>(cluster_of[k])] == static_cast<int>(k);
    const GalleryClassification& c = answer.classification;
    if (objects[k - 1].clutter) {
      ++tally->clutter_found;
      tally->clutter_unknown += own && c.unknown;
      continue;
    }
    ++tally->gallery_found;
    if (!own) {
      ++tally->merged;
    } else if (c.unknown) {
      ++tally->rejected;
    } else if (c.label == objects[k - 1].label) {
      ++tally->correct;
    } else {
      ++tally->wrong;
    }
    if (own && !c.knn.neighbors.empty()) {
      tally->known_distances.push_back(c.knn.neighbors.front().distance);
    }
  }
}

void Report(const std::string& name, const Tally& t, const std::string& config) {
  std::printf(
      "%-12s frames %3d objects %4d (hidden %3d) | found %5.1f %% of separated (%d/%d), %5.1f "
      "%% of all (%d/%d) | label correct %5.1f %% of found gallery objects (%d/%d), wrong "
      "%5.1f %%, unknown %5.1f %%, merged %5.1f %% | clutter unknown %5.1f %% (%d/%d) | stray "
      "clusters %d | %.1f ms/frame median\n",
      name.c_str(), t.frames, t.objects, t.hidden, Rate(t.separated_found, t.separated),
      t.separated_found, t.separated, Rate(t.found, t.visible), t.found, t.visible,
      Rate(t.correct, t.gallery_found), t.correct, t.gallery_found, Rate(t.wrong, t.gallery_found),
      Rate(t.rejected, t.gallery_found), Rate(t.merged, t.gallery_found),
      Rate(t.clutter_unknown, t.clutter_found), t.clutter_unknown, t.clutter_found,
      t.stray_clusters, 1e3 * bench::Percentile(t.seconds, 0.5));
  std::printf(
      "{\"set\":\"%s\",%s,\"frames\":%d,\"objects\":%d,\"hidden\":%d,\"separated\":%d,"
      "\"separated_found\":%d,\"visible\":%d,\"found\":%d,\"gallery_found\":%d,\"correct\":%d,"
      "\"wrong\":%d,\"unknown\":%d,\"merged\":%d,\"clutter_found\":%d,\"clutter_unknown\":%d,"
      "\"found_separated_rate\":%.4f,\"correct_rate\":%.4f,\"wrong_rate\":%.4f,"
      "\"clutter_unknown_rate\":%.4f,\"median_ms\":%.2f}\n",
      name.c_str(), config.c_str(), t.frames, t.objects, t.hidden, t.separated, t.separated_found,
      t.visible, t.found, t.gallery_found, t.correct, t.wrong, t.rejected, t.merged,
      t.clutter_found, t.clutter_unknown, Rate(t.separated_found, t.separated) / 100,
      Rate(t.correct, t.gallery_found) / 100, Rate(t.wrong, t.gallery_found) / 100,
      Rate(t.clutter_unknown, t.clutter_found) / 100, 1e3 * bench::Percentile(t.seconds, 0.5));
  std::fflush(stdout);
}

SceneRecognition Recognize(const GallerySnapshot& gallery, const PointCloud& frame,
                           const SceneRecognitionOptions& options, Tally* tally) {
  const auto start = std::chrono::steady_clock::now();
  absl::StatusOr<SceneRecognition> r = RecognizeScene(gallery, frame, options);
  tally->seconds.push_back(
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
  if (!r.ok()) Fail("RecognizeScene", r.status());
  return std::move(*r);
}

// Frame f of a composed set: 3-10 objects; odd frames lean objects on each other.
SceneFile ComposeFrame(int f, uint64_t seed, const std::map<std::string, std::vector<Model>>& known,
                       const std::vector<Model>& clutter, double clutter_share,
                       const SceneComposerOptions& base) {
  SplitMix64 rng(DeriveSeed(seed, "frame" + std::to_string(f)));
  const int count = 3 + static_cast<int>(rng.Uniform() * 8);
  std::vector<SceneObjectModel> models;
  std::vector<std::string> sources;
  for (int i = 0; i < count; ++i) {
    SceneObjectModel m;
    const Model* pick;
    if (!clutter.empty() && rng.Uniform() < clutter_share) {
      pick = &clutter[static_cast<size_t>(rng.Uniform() * static_cast<double>(clutter.size()))];
      m.role = SceneRole::kClutter;
    } else {
      auto cls = known.begin();
      std::advance(cls, static_cast<long>(rng.Uniform() * static_cast<double>(known.size())));
      pick = &cls->second[static_cast<size_t>(rng.Uniform() *
                                              static_cast<double>(cls->second.size()))];
    }
    m.label = pick->label;
    m.surface = pick->cloud;
    models.push_back(std::move(m));
    sources.push_back(pick->source);
  }
  SceneComposerOptions options = base;
  options.touch_probability = f % 2 == 1 ? 0.5 : 0;
  options.seed = rng.Next();
  absl::StatusOr<ComposedScene> scene = ComposeScene(models, options);
  if (!scene.ok()) Fail("ComposeScene", scene.status());
  SceneFile file;
  char name[16];
  std::snprintf(name, sizeof(name), "%04d", f);
  file.name = name;
  file.frame = std::move(scene->frame);
  file.truth = std::move(scene->truth);
  for (const ComposedObject& o : scene->objects) {
    file.objects.push_back({o.label, o.role == SceneRole::kClutter, sources[o.model]});
  }
  return file;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Scene recognition accuracy on composed and on-disk tabletop frames"};
  std::string data = fs::path(SHAPEID_SOURCE_DIR) / ".." / "shared" / "data" / "modelnet10";
  std::string dales = fs::path(SHAPEID_SOURCE_DIR) / ".." / "shared" / "data" / "dales-objects";
  std::string spec = "dfsd:frame=upright";
  std::string scenes_dir, write_dir;
  int views = 8, k = 1, frames = 100, calibration_frames = 60;
  uint64_t seed = 1;
  double percentile = 95, reject = -1, clutter_share = 0.25, separation = 0.05;
  bool calibrate_only = false, verbose = false, instances = false;
  std::vector<std::string> dales_classes = {"car", "tree"};
  double min_elevation = -90, max_elevation = 90;
  SceneRecognitionOptions recognition;
  recognition.segmentation.cluster_tolerance = 0.03f;
  recognition.segmentation.min_cluster_points = 50;
  app.add_option("--data", data, "ModelNet10: <class>/{train,test}/*.pcd")->capture_default_str();
  app.add_option("--dales", dales,
                 "DALES objects for clutter (<class>/*.xyz); absent: primitives only")
      ->capture_default_str();
  app.add_option("--dales-classes", dales_classes,
                 "DALES classes used as clutter (fence, pole, building: thin or roof-only aerial "
                 "scans, not surface samplings)")
      ->delimiter(',')
      ->capture_default_str();
  app.add_option("--spec", spec, "gallery descriptor spec")->capture_default_str();
  app.add_option("--augment-views", views, "synthetic views per training cloud")
      ->capture_default_str()
      ->check(CLI::Range(0, AugmentOptions::kMaxViews));
  app.add_option("--view-min-elevation", min_elevation,
                 "augmentation viewpoints from this elevation (degrees) above the object")
      ->capture_default_str();
  app.add_option("--view-max-elevation", max_elevation, "... up to this one")
      ->capture_default_str();
  app.add_option("--k", k, "neighbors")->capture_default_str()->check(CLI::PositiveNumber);
  app.add_option("--frames", frames, "test frames A (even: separated, odd: some touching)")
      ->capture_default_str();
  app.add_option("--calibration-frames", calibration_frames,
                 "frames of held-out training objects for the reject distance")
      ->capture_default_str();
  app.add_option("--seed", seed, "seeds every frame")->capture_default_str();
  app.add_option("--reject-percentile", percentile,
                 "reject distance: this percentile of known objects' nearest distances on the "
                 "calibration frames")
      ->capture_default_str();
  app.add_option("--reject-distance", reject, "use this reject distance (0: off) instead");
  app.add_option("--clutter-share", clutter_share, "chance that an object of A is clutter")
      ->capture_default_str();
  app.add_option("--separation", separation,
                 "an object with a point this close to another object's is not separated (m)")
      ->capture_default_str();
  app.add_option("--cluster-tolerance", recognition.segmentation.cluster_tolerance)
      ->capture_default_str();
  app.add_option("--plane-distance", recognition.segmentation.plane_distance)
      ->capture_default_str();
  app.add_option("--min-cluster-points", recognition.segmentation.min_cluster_points,
                 "also the fewest visible points for an object to be counted")
      ->capture_default_str();
  app.add_option("--scenes", scenes_dir, "scene set on disk (test scenes B)");
  app.add_option("--write-scenes", write_dir, "write test scenes A there, in the same format");
  app.add_flag("--instances", instances,
               "instance recognition: train the gallery on the TEST split (the objects scenes B "
               "show; needs --frames 0, as scenes A would be the augmentation's own simulator)");
  app.add_flag("--calibrate-only", calibrate_only, "stop after the calibration frames");
  app.add_flag("--verbose", verbose, "name each separated object that was not found");
  CLI11_PARSE(app, argc, argv);
  if (instances && frames > 0) {
    std::fprintf(stderr, "scene_accuracy: --instances needs --frames 0\n");
    return 2;
  }

  if (!fs::is_directory(data)) {
    std::printf("SKIPPED: no ModelNet10 data at %s\n", data.c_str());
    return 0;
  }
  std::printf("# %s, load %s\n", bench::CpuModel().c_str(), bench::LoadAverages().c_str());

  // ModelNet10: training clouds (every 10th per class held out) and test clouds.
  std::vector<LabeledCloud> train, held_out;
  std::map<std::string, std::vector<Model>> held_out_models, test_models;
  for (const fs::path& cls : SortedEntries(data)) {
    if (!fs::is_directory(cls)) continue;
    const std::string label = cls.filename().string();
    for (const char* split : {"train", "test"}) {
      // --instances: the gallery is the test split's objects themselves.
      const bool gallery_split = std::string(split) == (instances ? "test" : "train");
      if (instances && !gallery_split) continue;
      int index = 0;
      for (const fs::path& file : SortedEntries(cls / split)) {
        absl::StatusOr<ReadResult> read = ReadPointCloud(file.string());
        if (!read.ok()) Fail(file.string(), read.status());
        const std::string source = fs::path(file).lexically_relative(data).generic_string();
        if (!gallery_split) {
          test_models[label].push_back({label, source, std::move(read->cloud)});
        } else if (index++ % 10 == 0) {
          held_out_models[label].push_back({label, source, read->cloud});
          held_out.push_back({0, label, std::move(read->cloud), {}});
        } else {
          train.push_back({0, label, std::move(read->cloud), {}});
        }
      }
    }
  }
  // Clutter: primitives, and DALES objects of the chosen classes (odd files; outdoor
  // classes, none in ModelNet10).
  std::vector<Model> clutter;
  for (uint32_t i = 0; i < 6; ++i) {
    const Eigen::Vector3f half(0.5f + 0.2f * i, 1.0f, 0.3f + 0.25f * i);
    clutter.push_back({"box", "box", test_surfaces::BoxSurface({0, 0, 0}, half, 3000, 100 + i)});
    clutter.push_back({"sphere", "sphere", test_surfaces::SphereSurface(3000, 200 + i)});
  }
  for (const fs::path& cls : SortedEntries(dales)) {
    if (std::find(dales_classes.begin(), dales_classes.end(), cls.filename().string()) ==
        dales_classes.end()) {
      continue;
    }
    int index = 0;
    for (const fs::path& file : SortedEntries(cls)) {
      if (index++ % 2 == 0 || index > 40) continue;
      absl::StatusOr<ReadResult> read = ReadPointCloud(file.string());
      if (!read.ok()) Fail(file.string(), read.status());
      if (read->cloud.size() < 100) continue;
      clutter.push_back(
          {cls.filename().string(),
           "dales-objects/" + cls.filename().string() + "/" + file.filename().string(),
           std::move(read->cloud)});
    }
  }
  std::printf(
      "# ModelNet10 train %zu (+%zu held out for calibration), test %zu classes; "
      "clutter models %zu\n",
      train.size(), held_out.size(), test_models.size(), clutter.size());

  GalleryOptions gallery_options;
  gallery_options.descriptor_spec = spec;
  gallery_options.knn.k = k;
  gallery_options.augment.views = views;
  constexpr double kDegrees = 3.14159265358979323846 / 180;
  gallery_options.augment.sensor.view.min_up = std::sin(min_elevation * kDegrees);
  gallery_options.augment.sensor.view.max_up = std::sin(max_elevation * kDegrees);
  absl::StatusOr<std::shared_ptr<Gallery>> gallery =
      Gallery::Create("modelnet10", gallery_options, {}, nullptr);
  if (!gallery.ok()) Fail("gallery", gallery.status());
  const auto train_start = std::chrono::steady_clock::now();
  {
    absl::StatusOr<CommitResult> done = (*gallery)->Train(train);
    if (!done.ok()) Fail("training", done.status());
  }
  const double train_seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - train_start).count();

  SceneComposerOptions composer;
  char config[512];
  std::snprintf(config, sizeof(config),
                "\"spec\":\"%s\",\"views\":%d,\"view_elevation\":[%g,%g],\"k\":%d,\"seed\":%llu,"
                "\"cluster_tolerance\":%.4f,"
                "\"plane_distance\":%.4f,\"min_cluster_points\":%zu",
                (*gallery)->Snapshot()->options().descriptor_spec.c_str(), views, min_elevation,
                max_elevation, k, static_cast<unsigned long long>(seed),
                recognition.segmentation.cluster_tolerance, recognition.segmentation.plane_distance,
                recognition.segmentation.min_cluster_points);
  std::printf("# gallery %s, %d views, k %d: trained in %.1f s\n",
              (*gallery)->Snapshot()->options().descriptor_spec.c_str(), views, k, train_seconds);

  // Calibration: held-out training objects, no clutter, the gallery without rejection.
  Tally calibration;
  for (int f = 0; f < calibration_frames; ++f) {
    const SceneFile scene = ComposeFrame(f, seed ^ 0xca11b7a7e, held_out_models, {}, 0, composer);
    const SceneRecognition r =
        Recognize(*(*gallery)->Snapshot(), scene.frame, recognition, &calibration);
    Score(scene.frame, scene.truth, scene.objects, r, recognition.segmentation.min_cluster_points,
          separation, verbose, &calibration);
  }
  Report("calibration", calibration, config);
  if (reject < 0) reject = bench::Percentile(calibration.known_distances, percentile / 100);
  std::printf("# reject distance %.4f (%s)\n", reject,
              reject == bench::Percentile(calibration.known_distances, percentile / 100)
                  ? "the calibration percentile"
                  : "given");
  if (calibrate_only) return 0;

  // The full gallery: the held-out clouds join, then the reject distance is set.
  {
    absl::StatusOr<CommitResult> done = (*gallery)->Train(held_out);
    if (!done.ok()) Fail("training", done.status());
  }
  StoredGallery stored = (*gallery)->Snapshot()->ToStored();
  stored.options.reject_distance = reject;
  absl::StatusOr<std::shared_ptr<Gallery>> full = Gallery::Restore(stored, {}, nullptr);
  if (!full.ok()) Fail("gallery", full.status());
  const std::shared_ptr<const GallerySnapshot> snapshot = (*full)->Snapshot();
  const std::string config_reject =
      std::string(config) + ",\"reject_distance\":" + std::to_string(reject);

  Tally a, a_separated, a_touching;
  if (!write_dir.empty()) fs::create_directories(write_dir);
  for (int f = 0; f < frames; ++f) {
    const SceneFile scene = ComposeFrame(f, seed, test_models, clutter, clutter_share, composer);
    if (!write_dir.empty()) {
      if (absl::Status s = WriteSceneFile(write_dir, scene); !s.ok()) Fail(write_dir, s);
    }
    const SceneRecognition r = Recognize(*snapshot, scene.frame, recognition, &a);
    Score(scene.frame, scene.truth, scene.objects, r, recognition.segmentation.min_cluster_points,
          separation, verbose, &a);
    Tally& half = f % 2 == 0 ? a_separated : a_touching;
    half.seconds.push_back(a.seconds.back());
    Score(scene.frame, scene.truth, scene.objects, r, recognition.segmentation.min_cluster_points,
          separation, false, &half);
  }
  if (!write_dir.empty()) {
    std::ofstream(fs::path(write_dir) / "README.txt")
        << "Test scenes A of bench/scene_accuracy.cc (core/views/scene_composer.h, the project's "
           "simulator), seed "
        << seed << ", " << frames
        << " frames: ModelNet10 test objects (gallery: ModelNet10 train split) and clutter "
           "(primitives, DALES objects). Frames in the camera's optical frame.\n";
  }
  if (frames > 0) {
    Report("A", a, config_reject);
    Report("A-separated", a_separated, config_reject);
    Report("A-touching", a_touching, config_reject);
  }

  if (!scenes_dir.empty()) {
    Tally b;
    for (const std::string& name : ListSceneFiles(scenes_dir)) {
      absl::StatusOr<SceneFile> scene = ReadSceneFile(scenes_dir, name);
      if (!scene.ok()) Fail(name, scene.status());
      const SceneRecognition r = Recognize(*snapshot, scene->frame, recognition, &b);
      Score(scene->frame, scene->truth, scene->objects, r,
            recognition.segmentation.min_cluster_points, separation, verbose, &b);
    }
    Report("B", b, config_reject);
  }
  return 0;
}
