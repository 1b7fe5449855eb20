#include "client/cli/scene_command.h"

#include <zlib.h>

#include <cmath>
#include <cstdio>
#include <memory>
#include <utility>

#include "absl/strings/ascii.h"
#include "absl/strings/match.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/strings/str_join.h"
#include "absl/strings/str_split.h"
#include "absl/time/clock.h"
#include "client/cli/cloud_picture.h"
#include "client/cli/describe_command.h"
#include "client/cli/input_files.h"
#include "core/io/colored_cloud_writer.h"
#include "core/io/file_writer.h"
#include "core/io/point_cloud_reader.h"
#include "core/json.h"

namespace shapeid {

const std::array<std::array<uint8_t, 3>, kSceneFirstLabel + kSceneLabelColors> kScenePalette = {{
    {255, 255, 255},  // background
    {209, 213, 219},  // view frame
    {150, 150, 150},  // plane
    {60, 60, 60},     // unassigned
    {230, 0, 230},    // unknown
    // Tableau 10 without its grey: distinct for people with the common color blindnesses.
    {31, 119, 180},
    {255, 127, 14},
    {44, 160, 44},
    {214, 39, 40},
    {148, 103, 189},
    {140, 86, 75},
    {227, 119, 194},
    {188, 189, 34},
    {23, 190, 207},
}};

namespace {

constexpr char kUnknownLabel[] = "unknown";
constexpr double kDefaultPlaneDistance = 0.01;  // SceneSegmentation.plane_distance's default

// "--region x0,y0,z0,x1,y1,z1" as a box; InvalidArgument naming the flag.
absl::StatusOr<v1::AxisAlignedBox> ParseRegion(const std::string& text) {
  std::vector<double> v;
  for (absl::string_view word : absl::StrSplit(text, ',')) {
    double value;
    if (!absl::SimpleAtod(word, &value) || !std::isfinite(value)) {
      return absl::InvalidArgumentError(
          absl::StrCat("--region: \"", word, "\" is not a finite number"));
    }
    v.push_back(value);
  }
  if (v.size() != 6) {
    return absl::InvalidArgumentError(absl::StrCat(
        "--region: ", v.size(), " numbers; expected 6, x0,y0,z0,x1,y1,z1 (two opposite corners)"));
  }
  for (int a = 0; a < 3; ++a) {
    if (v[a] > v[a + 3]) {
      return absl::InvalidArgumentError(
          absl::StrCat("--region: the first corner's ", std::string(1, "xyz"[a]), " (", v[a],
                       ") is above the second's (", v[a + 3], "): give the lower corner first"));
    }
  }
  v1::AxisAlignedBox box;
  box.mutable_min()->set_x(v[0]);
  box.mutable_min()->set_y(v[1]);
  box.mutable_min()->set_z(v[2]);
  box.mutable_max()->set_x(v[3]);
  box.mutable_max()->set_y(v[4]);
  box.mutable_max()->set_z(v[5]);
  return box;
}

// The extension of an output path, lower case, with its dot.
std::string Extension(const std::string& path) {
  const size_t dot = path.rfind('.');
  const size_t slash = path.rfind('/');
  if (dot == std::string::npos || (slash != std::string::npos && dot < slash)) return "";
  return absl::AsciiStrToLower(path.substr(dot));
}

bool Inside(const v1::AxisAlignedBox& box, const Eigen::Vector3f& p) {
  return p.x() >= box.min().x() && p.x() <= box.max().x() && p.y() >= box.min().y() &&
         p.y() <= box.max().y() && p.z() >= box.min().z() && p.z() <= box.max().z();
}

// A space before positive numbers, so that columns of coordinates line up.
std::string Triple(const v1::Vector3& v) {
  return absl::StrFormat("% .3f % .3f % .3f", v.x(), v.y(), v.z());
}

std::string JsonTriple(const v1::Vector3& v) {
  return absl::StrCat("[", JsonNumber(v.x()), ",", JsonNumber(v.y()), ",", JsonNumber(v.z()), "]");
}

std::string PlaneText(const v1::ScenePlane& plane) {
  double c[4] = {0, 0, 0, 0};
  for (int i = 0; i < plane.coefficients_size() && i < 4; ++i) c[i] = plane.coefficients(i);
  return absl::StrFormat("%.4f x %+.4f y %+.4f z %+.4f = 0", c[0], c[1], c[2], c[3]);
}

// For people: the objects as a table, then the planes and where every point went.
std::string SceneTable(const std::string& file, const v1::RecognizeSceneResponse& scene) {
  std::string text = absl::StrCat(file, ": ", scene.objects_size(),
                                  scene.objects_size() == 1 ? " object" : " objects", "\n");
  uint64_t in_objects = 0, on_planes = 0;
  if (scene.objects_size() > 0) {
    Table table;
    table.header = {
        "#",       "LABEL",   "CONFIDENCE", "POINTS", "CENTROID (x y z)", "SIZE (box axes)",
        "NEAREST", "DISTANCE"};
    table.right_aligned = {true, false, true, true, false, false, false, true};
    for (int i = 0; i < scene.objects_size(); ++i) {
      const v1::SceneObject& object = scene.objects(i);
      const v1::ClassifyResponse& c = object.classification();
      in_objects += c.num_points();
      std::string nearest = "-", distance = "-";
      if (!object.error().empty()) {
        nearest = absl::StrCat("(", object.error(), ")");
      } else if (c.neighbors_size() > 0) {
        nearest = c.neighbors(0).label();
        distance = absl::StrFormat("%.4g", c.neighbors(0).distance());
      }
      table.rows.push_back({absl::StrCat(i), c.label(),
                            absl::StrFormat("%.1f%%", 100 * c.confidence()),
                            absl::StrCat(c.num_points()), Triple(object.centroid()),
                            Triple(object.box().size()), nearest, distance});
    }
    text += RenderTable(table);
  }
  for (int i = 0; i < scene.planes_size(); ++i) {
    on_planes += scene.planes(i).num_points();
    absl::StrAppend(&text, "plane ", i, ": ", PlaneText(scene.planes(i)), ", ",
                    scene.planes(i).num_points(), " points\n");
  }
  absl::StrAppend(&text, "points: ", scene.num_points(), " in the frame, ", on_planes,
                  " on planes, ", in_objects, " in objects, ", scene.non_finite_points(),
                  " non-finite, ", scene.outside_region(), " outside the region, ",
                  scene.in_small_clusters(), " in small clusters, ", scene.in_large_clusters(),
                  " in large clusters\n");
  return text;
}

// For scripts: the whole answer, one line.
std::string SceneJsonLine(const std::string& file, const v1::RecognizeSceneResponse& scene,
                          bool with_indices, double seconds) {
  std::string objects;
  for (int i = 0; i < scene.objects_size(); ++i) {
    const v1::SceneObject& object = scene.objects(i);
    const v1::ClassifyResponse& c = object.classification();
    std::string neighbors;
    for (const v1::Neighbor& n : c.neighbors()) {
      absl::StrAppend(&neighbors, neighbors.empty() ? "" : ",", "{\"sample_id\":", n.sample_id(),
                      ",\"label\":", JsonString(n.label()),
                      ",\"distance\":", JsonNumber(n.distance()),
                      ",\"source\":", JsonString(n.source()), "}");
    }
    const v1::Quaternion& q = object.box().orientation();
    absl::StrAppend(
        &objects, i == 0 ? "" : ",", "{\"index\":", i, ",\"label\":", JsonString(c.label()),
        ",\"unknown\":", c.unknown() ? "true" : "false",
        ",\"confidence\":", JsonNumber(c.confidence()), ",\"points\":", c.num_points(),
        ",\"centroid\":", JsonTriple(object.centroid()),
        ",\"box\":{\"center\":", JsonTriple(object.box().center()), ",\"orientation\":[",
        JsonNumber(q.x()), ",", JsonNumber(q.y()), ",", JsonNumber(q.z()), ",", JsonNumber(q.w()),
        "],\"size\":", JsonTriple(object.box().size()), "},\"neighbors\":[", neighbors,
        "],\"error\":", JsonString(object.error()));
    if (with_indices) {
      absl::StrAppend(&objects, ",\"indices\":[", absl::StrJoin(object.indices(), ","), "]");
    }
    objects += '}';
  }
  std::string planes;
  for (int i = 0; i < scene.planes_size(); ++i) {
    std::string coefficients;
    for (const double c : scene.planes(i).coefficients()) {
      absl::StrAppend(&coefficients, coefficients.empty() ? "" : ",", JsonNumber(c));
    }
    absl::StrAppend(&planes, i == 0 ? "" : ",", "{\"coefficients\":[", coefficients,
                    "],\"points\":", scene.planes(i).num_points(), "}");
  }
  return absl::StrCat("{\"file\":", JsonString(file), ",\"objects\":[", objects, "],\"planes\":[",
                      planes, "],\"points\":", scene.num_points(),
                      ",\"non_finite_points\":", scene.non_finite_points(),
                      ",\"outside_region\":", scene.outside_region(),
                      ",\"in_small_clusters\":", scene.in_small_clusters(),
                      ",\"in_large_clusters\":", scene.in_large_clusters(),
                      ",\"segment_seconds\":", JsonNumber(DurationSeconds(scene.segment_time())),
                      ",\"classify_seconds\":", JsonNumber(DurationSeconds(scene.classify_time())),
                      ",\"seconds\":", JsonNumber(seconds), "}\n");
}

constexpr char kCsvHeader[] =
    "file,object,label,unknown,confidence,points,centroid_x,centroid_y,centroid_z,size_x,"
    "size_y,size_z,nearest_label,nearest_distance,nearest_source,error\r\n";

// For spreadsheets: one row per object.
std::string SceneCsvRows(const std::string& file, const v1::RecognizeSceneResponse& scene) {
  std::string rows;
  for (int i = 0; i < scene.objects_size(); ++i) {
    const v1::SceneObject& object = scene.objects(i);
    const v1::ClassifyResponse& c = object.classification();
    const v1::Vector3& m = object.centroid();
    const v1::Vector3& s = object.box().size();
    absl::StrAppend(
        &rows, CsvField(file), ",", i, ",", CsvField(c.label()), ",",
        c.unknown() ? "true" : "false", ",", absl::StrFormat("%.4f", c.confidence()), ",",
        c.num_points(), ",",
        absl::StrFormat("%.6g,%.6g,%.6g,%.6g,%.6g,%.6g", m.x(), m.y(), m.z(), s.x(), s.y(), s.z()));
    if (c.neighbors_size() > 0) {
      absl::StrAppend(&rows, ",", CsvField(c.neighbors(0).label()), ",",
                      absl::StrFormat("%.6g", c.neighbors(0).distance()), ",",
                      CsvField(c.neighbors(0).source()));
    } else {
      rows += ",,,";
    }
    absl::StrAppend(&rows, ",", CsvField(object.error()), "\r\n");
  }
  return rows;
}

// The frame's points colored and written / drawn as --colored and --picture ask.
absl::Status WriteOutputs(const SceneCommandOptions& options, const PointCloud& frame,
                          const v1::RecognizeSceneResponse& scene) {
  const double plane_distance = options.call.segmentation.has_plane_distance()
                                    ? options.call.segmentation.plane_distance()
                                    : kDefaultPlaneDistance;
  const std::vector<uint8_t> colors = SceneColors(
      frame, scene, plane_distance, options.call.region ? &*options.call.region : nullptr);
  if (!options.colored.empty()) {
    if (absl::Status s = WriteColoredFrame(options.colored, frame, colors); !s.ok()) return s;
  }
  if (!options.picture.empty()) {
    CloudPictureOptions look;
    look.view_pixels = 320;
    const std::string png = EncodePng(RenderColoredCloudViews(frame, colors, look), kScenePalette);
    if (png.empty()) return absl::ResourceExhaustedError("out of memory encoding the picture");
    if (absl::Status s = WriteFileAtomically(options.picture, png); !s.ok()) return s;
  }
  return absl::OkStatus();
}

}  // namespace

uint8_t SceneLabelColor(const std::string& label) {
  if (label == kUnknownLabel) return kSceneUnknown;
  const uLong crc =
      crc32(0, reinterpret_cast<const Bytef*>(label.data()), static_cast<uInt>(label.size()));
  return static_cast<uint8_t>(kSceneFirstLabel + crc % kSceneLabelColors);
}

std::vector<uint8_t> SceneColors(const PointCloud& frame, const v1::RecognizeSceneResponse& scene,
                                 double plane_distance, const v1::AxisAlignedBox* region) {
  constexpr uint8_t kNone = 255;
  std::vector<uint8_t> colors(frame.size(), kNone);
  for (const v1::SceneObject& object : scene.objects()) {
    const uint8_t color = SceneLabelColor(object.classification().label());
    for (const uint32_t i : object.indices()) {
      if (i < colors.size()) colors[i] = color;
    }
  }
  for (size_t i = 0; i < frame.size(); ++i) {
    if (colors[i] != kNone) continue;
    colors[i] = kSceneUnassigned;
    const Eigen::Vector3f p = frame.point(i);
    if (!p.allFinite() || (region != nullptr && !Inside(*region, p))) continue;
    for (const v1::ScenePlane& plane : scene.planes()) {
      if (plane.coefficients_size() != 4) continue;
      const double d = plane.coefficients(0) * p.x() + plane.coefficients(1) * p.y() +
                       plane.coefficients(2) * p.z() + plane.coefficients(3);
      if (std::fabs(d) < plane_distance) {
        colors[i] = kScenePlane;
        break;
      }
    }
  }
  return colors;
}

absl::Status WriteColoredFrame(const std::string& path, const PointCloud& frame,
                               absl::Span<const uint8_t> colors) {
  ColoredCloudFormat format;
  if (absl::Status s = ColoredCloudFormatOf(path, &format); !s.ok()) return s;
  if (colors.size() != frame.size()) {
    return absl::InvalidArgumentError(
        absl::StrCat(colors.size(), " colors for ", frame.size(), " points"));
  }
  std::vector<Rgb> rgb(colors.size());
  for (size_t i = 0; i < colors.size(); ++i) rgb[i] = kScenePalette[colors[i]];
  return WriteFileAtomically(
      path, EncodeColoredCloud(frame, rgb, format,
                               "shapeid scene: points colored by their object's label"));
}

void AddSceneFlags(CLI::App* command, SceneCommandOptions* options) {
  command->add_option("--gallery,-g", options->gallery, "Gallery to classify the objects against")
      ->required();
  command->add_option("--k", options->call.k, "Neighbors that vote (default: the gallery's)")
      ->check(CLI::Range(1u, 1000000u));
  command->add_flag("--exact", options->call.exact,
                    "Search every stored vector, even where the server searches the gallery "
                    "approximately");
  v1::SceneSegmentation* s = &options->call.segmentation;
  command
      ->add_option_function<uint32_t>(
          "--planes", [s](uint32_t v) { s->set_max_planes(v); },
          "Supporting planes to remove, largest first (a table, a floor), 0 to 16 (default 1)")
      ->check(CLI::Range(0u, 16u));
  command
      ->add_option_function<float>(
          "--plane-distance", [s](float v) { s->set_plane_distance(v); },
          "A point closer than this to a plane lies on it, in the frame's units (default 0.01)")
      ->check(CLI::PositiveNumber);
  command
      ->add_option_function<double>(
          "--min-plane-share", [s](double v) { s->set_min_plane_share(v); },
          "A plane is removed only if it holds at least this share of the points, in (0, 1] "
          "(default 0.05)")
      ->check(CLI::Range(1e-12, 1.0));
  command
      ->add_option_function<double>(
          "--plane-tilt", [s](double v) { s->set_max_plane_tilt_degrees(v); },
          "With --sensor-up or --sensor-transform: only planes within this many degrees of "
          "level are supports, in (0, 90] (default 15)")
      ->check(CLI::Range(1e-9, 90.0));
  command
      ->add_option_function<float>(
          "--cluster-tolerance", [s](float v) { s->set_cluster_tolerance(v); },
          "Two points closer than this belong to the same object (default 0.02)")
      ->check(CLI::PositiveNumber);
  command
      ->add_option_function<uint64_t>(
          "--min-points", [s](uint64_t v) { s->set_min_cluster_points(v); },
          "Objects of fewer points are dropped as noise (default 100)")
      ->check(CLI::PositiveNumber);
  command
      ->add_option_function<uint64_t>(
          "--max-points", [s](uint64_t v) { s->set_max_cluster_points(v); },
          "Objects of more points are dropped as background (default 1,000,000)")
      ->check(CLI::PositiveNumber);
  command->add_option_function<uint64_t>(
      "--seed", [s](uint64_t v) { s->set_seed(v); },
      "Seeds RANSAC: the same frame, parameters and seed give the same answer (default 0)");
  command->add_option("--region", options->region,
                      "Only points inside this box are considered (the work area), two opposite "
                      "corners in the frame's coordinates: x0,y0,z0,x1,y1,z1");
  command->add_flag("--indices", options->indices,
                    "json: each object's point indices in the frame (non-finite points "
                    "counted)");
  command->add_option("--colored", options->colored,
                      "Write the frame here with each point colored by its object's label "
                      "(planes grey, the rest dark): OUT.ply or OUT.pcd; one FRAME only");
  command->add_option("--picture", options->picture,
                      "Draw the colored frame here, three views side by side: OUT.png; one "
                      "FRAME only");
  command
      ->add_option("FRAME", options->frames,
                   "Point-cloud files or folders, one sensor frame each (- reads standard "
                   "input): " +
                       SupportedExtensions())
      ->required()
      ->type_name("");
}

int RunScene(const SceneCommandOptions& options, const CliContext& context) {
  SceneCommandOptions run = options;
  if (!options.region.empty()) {
    absl::StatusOr<v1::AxisAlignedBox> region = ParseRegion(options.region);
    if (!region.ok()) {
      PrintError(context.err, "scene", region.status());
      return kExitUsage;
    }
    run.call.region = *std::move(region);
  }
  if (absl::Status format = CheckStandardInputFormat(options.frames, options.read); !format.ok()) {
    PrintError(context.err, "scene", format);
    return kExitUsage;
  }
  std::vector<std::string> unsupported;
  absl::StatusOr<std::vector<std::string>> frames = ExpandInputs(options.frames, &unsupported);
  if (!frames.ok()) {
    PrintError(context.err, "scene", frames.status());
    return kExitUsage;
  }
  const bool draws = !options.colored.empty() || !options.picture.empty();
  if (draws && frames->size() != 1) {
    PrintError(context.err, "scene",
               absl::InvalidArgumentError(
                   absl::StrCat("--colored and --picture write one frame; ", frames->size(),
                                " were given: run one scene command per frame")));
    return kExitUsage;
  }
  const std::string colored_extension = Extension(options.colored);
  if (!options.colored.empty() && colored_extension != ".ply" && colored_extension != ".pcd") {
    PrintError(context.err, "scene",
               absl::InvalidArgumentError(absl::StrCat("--colored ", options.colored,
                                                       ": the file must end in .ply or .pcd")));
    return kExitUsage;
  }
  if (!options.picture.empty() && Extension(options.picture) != ".png") {
    PrintError(context.err, "scene",
               absl::InvalidArgumentError(
                   absl::StrCat("--picture ", options.picture, ": the file must end in .png")));
    return kExitUsage;
  }
  run.call.return_indices = draws || options.indices;
  // The file's own coordinates: answers, the region and the sensor's place relate to them.
  run.read.recenter = false;

  std::unique_ptr<Client> client = ConnectOrReport(context);
  if (client == nullptr) return kExitUsage;
  size_t failed =
      ReportUnsupportedFiles(context.err, "scene", unsupported, options.skip_unsupported) ? 1 : 0;
  bool written = true;
  if (context.format == OutputFormat::kCsv) written &= WriteAll(context.out, kCsvHeader);
  for (size_t f = 0; f < frames->size(); ++f) {
    const std::string& path = (*frames)[f];
    absl::StatusOr<ReadResult> read = ReadPointCloud(path, run.read);
    if (!read.ok()) {
      std::fflush(context.out);
      WriteAll(context.err, FileErrorLine(path, read.status()));
      ++failed;
      continue;
    }
    const absl::Time start = absl::Now();
    absl::StatusOr<v1::RecognizeSceneResponse> scene =
        client->RecognizeScene(options.gallery, read->cloud, run.call);
    const double seconds = absl::ToDoubleSeconds(absl::Now() - start);
    if (!scene.ok()) {
      std::fflush(context.out);
      if (StopsBatch(scene.status())) {
        PrintCallError(context, absl::StrCat("scene ", options.gallery), scene.status());
        return ExitCodeForStatus(scene.status());
      }
      WriteAll(context.err, FileErrorLine(path, scene.status()));
      ++failed;
      continue;
    }
    switch (context.format) {
      case OutputFormat::kJson:
        written &= WriteAll(context.out, SceneJsonLine(path, *scene, options.indices, seconds));
        break;
      case OutputFormat::kCsv:
        written &= WriteAll(context.out, SceneCsvRows(path, *scene));
        break;
      case OutputFormat::kTable:
        written &=
            WriteAll(context.out, absl::StrCat(f == 0 ? "" : "\n", SceneTable(path, *scene)));
        break;
    }
    if (draws) {
      if (absl::Status s = WriteOutputs(run, read->cloud, *scene); !s.ok()) {
        std::fflush(context.out);
        PrintError(context.err, "scene", s);
        ++failed;
      }
    }
  }
  if (const int code = FinishOutput(written, context); code != kExitOk) return code;
  return failed > 0 ? kExitSomeInputsFailed : kExitOk;
}

}  // namespace shapeid
