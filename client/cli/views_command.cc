#include "client/cli/views_command.h"

#include <algorithm>
#include <filesystem>
#include <string>
#include <system_error>
#include <tuple>
#include <utility>
#include <vector>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "client/cli/describe_command.h"
#include "client/cli/input_files.h"
#include "core/io/pcd_writer.h"
#include "core/io/point_cloud_reader.h"
#include "core/io/scene_files.h"
#include "core/json.h"
#include "core/random.h"
#include "core/views/scan_simulator.h"
#include "core/views/scene_composer.h"
#include "core/views/view_directions.h"

namespace shapeid {
namespace fs = std::filesystem;

void AddViewsFlags(CLI::App* command, ViewsOptions* options) {
  command->add_option("MODEL", options->models, "Mesh or cloud files: .off .obj .ply .pcd ...")
      ->required()
      ->type_name("");
  command->add_option("--out,-o", options->out, "Output folder (created)")->required();
  command->add_option("--train-views", options->train_views, "Views per model for training")
      ->check(CLI::Range(0, 10000))
      ->capture_default_str();
  command
      ->add_option("--test-views", options->test_views,
                   "Views per model for testing, from directions between the training ones")
      ->check(CLI::Range(0, 10000))
      ->capture_default_str();
  command
      ->add_option("--min-elevation", options->min_elevation,
                   "Lowest sensor elevation, degrees above the horizontal")
      ->check(CLI::Range(-89.0, 89.0))
      ->capture_default_str();
  command
      ->add_option("--max-elevation", options->max_elevation, "Highest sensor elevation, degrees")
      ->check(CLI::Range(-89.0, 89.0))
      ->capture_default_str();
  command->add_option("--up", options->up, "The models' up axis")
      ->check(CLI::IsMember({"x", "y", "z"}))
      ->capture_default_str();
  command
      ->add_option("--noise", options->depth_noise,
                   "Depth noise along each ray, in object radii (std dev)")
      ->check(CLI::Range(0.0, 1.0))
      ->capture_default_str();
  command->add_option("--width", options->width, "Depth image width (pixels)")
      ->check(CLI::Range(8, 4096))
      ->capture_default_str();
  command->add_option("--height", options->height, "Depth image height (pixels)")
      ->check(CLI::Range(8, 4096))
      ->capture_default_str();
  command
      ->add_option("--max-points", options->max_points,
                   "Subsample each view to at most this many points (0: keep all)")
      ->capture_default_str();
  command
      ->add_option("--surface-points", options->surface_points,
                   "Points sampled on each mesh before rendering")
      ->check(CLI::Range(size_t{1000}, size_t{10000000}))
      ->capture_default_str();
  command->add_option("--seed", options->seed, "Seed of sampling and noise")->capture_default_str();
  command
      ->add_option("--scenes", options->scenes,
                   "Also compose this many tabletop frames of the models, with each point's "
                   "truth, into OUT/scenes/ (docs/scenes.md)")
      ->check(CLI::Range(0, 100000))
      ->capture_default_str();
  command
      ->add_option("--scene-objects", options->scene_objects,
                   "Models per frame, drawn without repeating (all of them when fewer)")
      ->check(CLI::Range(1, 64))
      ->capture_default_str();
  command
      ->add_option("--touching", options->touching,
                   "Chance that each object of a frame leans on one placed before it")
      ->check(CLI::Range(0.0, 1.0))
      ->capture_default_str();
  command
      ->add_option("--clutter", options->clutter,
                   "A model placed in the frames as clutter (in no gallery), one per frame in "
                   "turn; repeat the flag for more")
      ->type_name("FILE")
      ->allow_extra_args(false);
}

namespace {

Eigen::Vector3d UpAxis(const std::string& up) {
  if (up == "x") return Eigen::Vector3d::UnitX();
  if (up == "z") return Eigen::Vector3d::UnitZ();
  return Eigen::Vector3d::UnitY();
}

// Renders `count` views of `surface` into `dir`; returns the points written per view.
absl::Status RenderSet(ScanSimulator& simulator, const ViewsOptions& options, int count,
                       double azimuth_offset, uint64_t seed, const fs::path& dir, size_t* points) {
  if (count == 0) return absl::OkStatus();
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) return absl::UnknownError(absl::StrCat(dir.string(), ": ", ec.message()));
  const Eigen::Vector3d up = UpAxis(options.up);
  absl::StatusOr<std::vector<Eigen::Vector3d>> directions = ViewDirections(
      static_cast<size_t>(count), up, options.min_elevation, options.max_elevation, azimuth_offset);
  if (!directions.ok()) return directions.status();
  for (size_t v = 0; v < directions->size(); ++v) {
    ScanOptions scan;
    scan.direction = (*directions)[v];
    scan.up = up;
    scan.width = options.width;
    scan.height = options.height;
    scan.depth_noise = options.depth_noise;
    scan.max_points = options.max_points;
    scan.seed = seed * 1000003 + v;
    absl::StatusOr<PointCloud> view = simulator.Scan(scan);
    if (!view.ok()) return view.status();
    const fs::path file = dir / absl::StrFormat("view-%03d.pcd", v);
    if (absl::Status written = WritePcd(file.string(), *view, PcdEncoding::kBinary);
        !written.ok()) {
      return written;
    }
    *points += view->size();
  }
  return absl::OkStatus();
}

// One scene model per file: its surface sampled as for views, labeled by its file name.
absl::StatusOr<SceneObjectModel> SceneModel(const std::string& file, const ViewsOptions& options,
                                            SceneRole role) {
  ReadOptions read;
  read.sample_points = options.surface_points;
  read.sample_seed = options.seed;
  absl::StatusOr<ReadResult> result = ReadInputCloud(file, read);
  if (!result.ok()) return result.status();
  SceneObjectModel model;
  model.label = fs::path(file).stem().string();
  model.role = role;
  model.surface = std::move(result->cloud);
  model.up = UpAxis(options.up);
  return model;
}

// Frame `index` of the scene set: `models` drawn without repeating, plus one clutter model,
// composed and written as NNNN.pcd, NNNN.objects.csv and NNNN.truth.u16 under `dir`.
absl::StatusOr<ComposedScene> WriteScene(const std::vector<SceneObjectModel>& models,
                                         const std::vector<std::string>& model_files,
                                         const std::vector<SceneObjectModel>& clutter,
                                         const std::vector<std::string>& clutter_files,
                                         const ViewsOptions& options, int index,
                                         const fs::path& dir) {
  SplitMix64 random(options.seed * 1000003 + static_cast<uint64_t>(index));
  std::vector<size_t> order(models.size());
  for (size_t i = 0; i < order.size(); ++i) order[i] = i;
  for (size_t i = order.size(); i > 1; --i) {  // Fisher-Yates
    std::swap(order[i - 1], order[static_cast<size_t>(random.Uniform() * i)]);
  }
  order.resize(std::min(order.size(), static_cast<size_t>(options.scene_objects)));
  std::vector<SceneObjectModel> chosen;
  std::vector<std::string> sources;
  for (const size_t m : order) {
    chosen.push_back(models[m]);
    sources.push_back(model_files[m]);
  }
  if (!clutter.empty()) {
    const size_t c = static_cast<size_t>(index) % clutter.size();
    chosen.push_back(clutter[c]);
    sources.push_back(clutter_files[c]);
  }
  SceneComposerOptions compose;
  compose.touch_probability = options.touching;
  compose.seed = options.seed * 7919 + static_cast<uint64_t>(index);
  absl::StatusOr<ComposedScene> scene = ComposeScene(chosen, compose);
  if (!scene.ok()) return scene.status();
  SceneFile file;
  file.name = absl::StrFormat("%04d", index);
  file.frame = scene->frame;
  file.truth = scene->truth;
  for (const ComposedObject& object : scene->objects) {
    file.objects.push_back(
        {object.label, object.role == SceneRole::kClutter, sources[object.model]});
  }
  if (absl::Status s = WriteSceneFile(dir.string(), file); !s.ok()) return s;
  return scene;
}

// The --scenes part of RunViews: one line per frame, or the first error.
int RunScenes(const ViewsOptions& options, const CliContext& context) {
  std::vector<SceneObjectModel> models, clutter;
  for (const auto& [files, role, into] :
       {std::tuple(&options.models, SceneRole::kGallery, &models),
        std::tuple(&options.clutter, SceneRole::kClutter, &clutter)}) {
    for (const std::string& file : *files) {
      absl::StatusOr<SceneObjectModel> model = SceneModel(file, options, role);
      if (!model.ok()) {
        WriteAll(context.err, FileErrorLine(file, model.status()));
        return kExitSomeInputsFailed;
      }
      into->push_back(*std::move(model));
    }
  }
  const fs::path dir = fs::path(options.out) / "scenes";
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) {
    WriteAll(context.err, absl::StrCat("shapeid: views: ", dir.string(), ": ", ec.message(), "\n"));
    return kExitSomeInputsFailed;
  }
  Table table{
      {"FRAME", "OBJECTS", "CLUTTER", "TOUCHING", "POINTS"}, {}, {false, true, true, true, true}};
  for (int s = 0; s < options.scenes; ++s) {
    absl::StatusOr<ComposedScene> scene =
        WriteScene(models, options.models, clutter, options.clutter, options, s, dir);
    if (!scene.ok()) {
      WriteAll(context.err,
               absl::StrCat("shapeid: views: frame ", s, ": ", scene.status().message(), "\n"));
      return kExitSomeInputsFailed;
    }
    size_t placed_clutter = 0, touching = 0;
    for (const ComposedObject& object : scene->objects) {
      placed_clutter += object.role == SceneRole::kClutter;
      touching += !object.separated;
    }
    table.rows.push_back({(dir / absl::StrFormat("%04d.pcd", s)).string(),
                          absl::StrCat(scene->objects.size()), absl::StrCat(placed_clutter),
                          absl::StrCat(touching), absl::StrCat(scene->frame.size())});
  }
  WriteAll(context.out,
           context.format == OutputFormat::kCsv ? RenderCsv(table) : RenderTable(table));
  return kExitOk;
}

}  // namespace

int RunViews(const ViewsOptions& options, const CliContext& context) {
  if (options.min_elevation > options.max_elevation) {
    WriteAll(context.err, "shapeid: views: --min-elevation is above --max-elevation\n");
    return kExitUsage;
  }
  if (options.train_views == 0 && options.test_views == 0 && options.scenes > 0) {
    return RunScenes(options, context);  // frames only
  }
  ReadOptions read;
  read.sample_points = options.surface_points;
  read.sample_seed = options.seed;
  bool failed = false;
  Table table{{"MODEL", "TRAIN VIEWS", "TEST VIEWS", "POINTS/VIEW"}, {}, {false, true, true, true}};
  Progress progress(context.err, context.progress, "views", options.models.size());
  for (size_t m = 0; m < options.models.size(); ++m) {
    const std::string& model = options.models[m];
    const std::string label = fs::path(model).stem().string();
    absl::StatusOr<ReadResult> read_result = ReadInputCloud(model, read);
    size_t points = 0;
    absl::Status status = read_result.status();
    if (status.ok()) {
      // One simulator per model: it measures the surface once and reuses its buffers.
      absl::StatusOr<ScanSimulator> simulator =
          ScanSimulator::Create(std::move(read_result->cloud));
      status = simulator.status();
      // Training and test views interleave in azimuth and never share a direction.
      const double half_step = options.train_views > 0 ? 180.0 / options.train_views : 0;
      if (status.ok()) {
        status = RenderSet(*simulator, options, options.train_views, 0, options.seed,
                           fs::path(options.out) / label / "train", &points);
      }
      if (status.ok()) {
        status = RenderSet(*simulator, options, options.test_views, half_step, options.seed + 7919,
                           fs::path(options.out) / label / "test", &points);
      }
    }
    if (!status.ok()) {
      failed = true;
      progress.Interrupt([&] { WriteAll(context.err, FileErrorLine(model, status)); });
      progress.Advance(1, 1);
      continue;
    }
    const int views = options.train_views + options.test_views;
    table.rows.push_back({label, absl::StrCat(options.train_views),
                          absl::StrCat(options.test_views),
                          absl::StrCat(views > 0 ? points / static_cast<size_t>(views) : 0)});
    progress.Advance(1, 0);
  }
  progress.Finish();
  std::string text;
  if (context.format == OutputFormat::kJson) {
    for (const auto& row : table.rows) {
      absl::StrAppend(&text, "{\"model\":", JsonString(row[0]), ",\"train_views\":", row[1],
                      ",\"test_views\":", row[2], ",\"mean_points\":", row[3], "}\n");
    }
  } else {
    text = context.format == OutputFormat::kCsv ? RenderCsv(table) : RenderTable(table);
  }
  WriteAll(context.out, text);
  if (!failed && options.scenes > 0) {
    const int scenes = RunScenes(options, context);
    if (scenes != kExitOk) return scenes;
  }
  std::fflush(context.out);
  return failed ? kExitSomeInputsFailed : kExitOk;
}

}  // namespace shapeid
