#include "client/cli/views_command.h"

#include <filesystem>
#include <system_error>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "client/cli/describe_command.h"
#include "client/cli/input_files.h"
#include "core/io/pcd_writer.h"
#include "core/io/point_cloud_reader.h"
#include "core/json.h"
#include "core/views/scan_simulator.h"
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

}  // namespace

int RunViews(const ViewsOptions& options, const CliContext& context) {
  if (options.min_elevation > options.max_elevation) {
    WriteAll(context.err, "shapeid: views: --min-elevation is above --max-elevation\n");
    return kExitUsage;
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
  std::fflush(context.out);
  return failed ? kExitSomeInputsFailed : kExitOk;
}

}  // namespace shapeid
