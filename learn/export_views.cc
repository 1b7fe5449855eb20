// Writes the training data of a point network: every training cloud of a dataset folder, whole
// and as the gallery's own synthetic sensor views (core/views/augment.h), each laid in the
// network's frame by MakeCanonicalPoints, the preparation the `learned` descriptor applies at
// inference. Python (learn/train_point_network.py) only learns; it never prepares points.
//
//   shapeid_export_views --data ../shared/data/modelnet10 --views 12 --out build/learn/mn10.views
//
// Folder layouts: LABEL/train/* (ModelNet10's split; only train/ is read), else LABEL/*.
// Output (little-endian): "SHPDVIEW", u32 labels, each a u32-prefixed name; u32 records, each
// u32 label, u32 object, u32 view (0: the whole cloud), u32 ambiguous bits
// (CanonicalPoints), u32 m, then m points as float32 x, y, z.

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "CLI/CLI.hpp"
#include "core/binary_codec.h"
#include "core/descriptors/learned.h"
#include "core/io/point_cloud_reader.h"
#include "core/parallel_ranges.h"
#include "core/views/augment.h"

namespace shapeid {
namespace {

struct Source {
  int label = 0;
  std::string path;
};

struct Record {
  uint32_t label, object, view, ambiguous;
  Eigen::Matrix3Xf points;
};

int Run(int argc, char** argv) {
  CLI::App app{"Writes a point network's training views, prepared as the learned descriptor does"};
  std::string data, out_path, frame_name = "box", mix = "varied";
  int views = 12, threads = 2;
  uint32_t max_points = 512, min_view_points = 150, max_view_points = 1000;
  uint64_t seed = 1;
  app.add_option("--data", data, "dataset folder (LABEL/train/* or LABEL/*)")->required();
  app.add_option("--out", out_path, "file to write")->required();
  app.add_option("--views", views, "synthetic views per training cloud, besides the whole cloud");
  app.add_option("--frame", frame_name, "box | upright")->check(CLI::IsMember({"box", "upright"}));
  app.add_option("--mix", mix, "camera | varied (AugmentOptions::mix)")
      ->check(CLI::IsMember({"camera", "varied"}));
  app.add_option("--max-points", max_points, "points the network reads (its max_points)");
  app.add_option("--view-points", min_view_points, "fewest points a view keeps");
  app.add_option("--view-points-max", max_view_points, "most points a view keeps");
  app.add_option("--seed", seed, "augmentation seed");
  app.add_option("--threads", threads, "worker threads");
  CLI11_PARSE(app, argc, argv);

  const PointNetwork::Frame frame =
      frame_name == "upright" ? PointNetwork::Frame::kUpright : PointNetwork::Frame::kBox;
  AugmentOptions augment;
  augment.views = views;
  augment.seed = seed;
  augment.mix = mix == "camera" ? ViewMix::kCamera : ViewMix::kVaried;
  augment.sensor.min_points = min_view_points;
  augment.sensor.max_points = max_view_points;
  if (frame == PointNetwork::Frame::kUpright) {
    // Gravity known: views from the side or above (elevation 0-60 degrees), the object upright.
    augment.sensor.view.min_up = 0.0;
    augment.sensor.view.max_up = 0.87;
  }
  if (absl::Status valid = ValidateAugmentOptions(augment); !valid.ok()) {
    std::fprintf(stderr, "%s\n", std::string(valid.message()).c_str());
    return 2;
  }

  namespace fs = std::filesystem;
  std::vector<std::string> labels;
  for (const auto& entry : fs::directory_iterator(data)) {
    if (entry.is_directory()) labels.push_back(entry.path().filename().string());
  }
  std::sort(labels.begin(), labels.end());
  std::vector<Source> sources;
  for (size_t l = 0; l < labels.size(); ++l) {
    fs::path folder = fs::path(data) / labels[l];
    if (fs::is_directory(folder / "train")) folder /= "train";
    std::vector<std::string> files;
    for (const auto& entry : fs::directory_iterator(folder)) {
      if (entry.is_regular_file() || entry.is_symlink()) files.push_back(entry.path().string());
    }
    std::sort(files.begin(), files.end());
    for (const std::string& file : files) sources.push_back({static_cast<int>(l), file});
  }
  std::fprintf(stderr, "%zu labels, %zu training clouds, %d views each\n", labels.size(),
               sources.size(), views);

  std::vector<std::vector<Record>> per_source(sources.size());
  std::vector<int> failures(static_cast<size_t>(std::max(threads, 1)), 0);
  ParallelRanges(
      static_cast<int64_t>(sources.size()), threads, 1, [&](int part, int64_t begin, int64_t end) {
        for (int64_t s = begin; s < end; ++s) {
          absl::StatusOr<ReadResult> read = ReadPointCloud(sources[s].path);
          if (!read.ok()) {
            ++failures[part];
            continue;
          }
          std::vector<PointCloud> clouds;
          clouds.push_back(std::move(read->cloud));
          absl::StatusOr<std::vector<PointCloud>> extra =
              AugmentedViews(clouds[0], augment, static_cast<uint64_t>(s));
          if (extra.ok()) {
            for (PointCloud& view : *extra) clouds.push_back(std::move(view));
          }
          for (size_t v = 0; v < clouds.size(); ++v) {
            absl::StatusOr<CanonicalPoints> canonical =
                MakeCanonicalPoints(clouds[v], frame, max_points);
            if (!canonical.ok()) continue;
            per_source[s].push_back({static_cast<uint32_t>(sources[s].label),
                                     static_cast<uint32_t>(s), static_cast<uint32_t>(v),
                                     canonical->ambiguous, std::move(canonical->points)});
          }
        }
      });

  ByteWriter out;
  out.Bytes("SHPDVIEW");
  out.U32(static_cast<uint32_t>(labels.size()));
  for (const std::string& label : labels) out.String(label);
  size_t records = 0;
  for (const auto& list : per_source) records += list.size();
  out.U32(static_cast<uint32_t>(records));
  for (const auto& list : per_source) {
    for (const Record& r : list) {
      out.U32(r.label);
      out.U32(r.object);
      out.U32(r.view);
      out.U32(r.ambiguous);
      out.U32(static_cast<uint32_t>(r.points.cols()));
      out.Floats(r.points.data(), r.points.size());
    }
  }
  const std::string bytes = std::move(out).Finish();
  std::ofstream file(out_path, std::ios::binary);
  file.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  int failed = 0;
  for (int f : failures) failed += f;
  std::fprintf(stderr, "%zu records to %s (%d unreadable files)\n", records, out_path.c_str(),
               failed);
  return file.good() ? 0 : 1;
}

}  // namespace
}  // namespace shapeid

int main(int argc, char** argv) { return shapeid::Run(argc, argv); }
