#include "core/io/scene_files.h"

#include <algorithm>
#include <filesystem>
#include <sstream>
#include <utility>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_split.h"
#include "core/io/file_writer.h"
#include "core/io/pcd_writer.h"
#include "core/io/point_cloud_reader.h"

namespace shapeid {

std::vector<std::string> ListSceneFiles(const std::string& dir) {
  std::vector<std::string> names;
  for (const auto& entry : std::filesystem::directory_iterator(dir)) {
    if (entry.path().extension() == ".pcd") names.push_back(entry.path().stem().string());
  }
  std::sort(names.begin(), names.end());
  return names;
}

absl::StatusOr<SceneFile> ReadSceneFile(const std::string& dir, const std::string& name) {
  const std::string base = (std::filesystem::path(dir) / name).string();
  SceneFile scene;
  scene.name = name;
  ReadOptions read;
  read.recenter = false;  // the frame's origin is the sensor's: the plane's up depends on it
  absl::StatusOr<ReadResult> cloud = ReadPointCloud(base + ".pcd", read);
  if (!cloud.ok()) return cloud.status();
  scene.frame = std::move(cloud->cloud);

  absl::StatusOr<std::string> csv = ReadFileContents(base + ".objects.csv");
  if (!csv.ok()) return csv.status();
  std::vector<std::string> lines = absl::StrSplit(*csv, '\n', absl::SkipWhitespace());
  if (lines.empty() || lines[0].rfind("object,label,role,source", 0) != 0) {
    return absl::InvalidArgumentError(
        absl::StrCat(base, ".objects.csv: the header must be object,label,role,source"));
  }
  for (size_t i = 1; i < lines.size(); ++i) {
    std::string line = lines[i];
    if (!line.empty() && line.back() == '\r') line.pop_back();
    const std::vector<std::string> fields = absl::StrSplit(line, absl::MaxSplits(',', 3));
    if (fields.size() != 4 || fields[0] != std::to_string(i) ||
        (fields[2] != "gallery" && fields[2] != "clutter")) {
      return absl::InvalidArgumentError(absl::StrCat(base, ".objects.csv line ", i + 1, ": want `",
                                                     i, ",label,gallery|clutter,source`"));
    }
    scene.objects.push_back({fields[1], fields[2] == "clutter", fields[3]});
  }

  absl::StatusOr<std::string> truth = ReadFileContents(base + ".truth.u16");
  if (!truth.ok()) return truth.status();
  if (truth->size() != 2 * scene.frame.size()) {
    return absl::InvalidArgumentError(absl::StrCat(base, ".truth.u16 has ", truth->size(),
                                                   " bytes; want 2 per point, ",
                                                   2 * scene.frame.size()));
  }
  scene.truth.resize(scene.frame.size());
  for (size_t i = 0; i < scene.truth.size(); ++i) {
    const auto lo = static_cast<uint8_t>((*truth)[2 * i]);
    const auto hi = static_cast<uint8_t>((*truth)[2 * i + 1]);
    scene.truth[i] = static_cast<uint16_t>(lo | (hi << 8));
    if (scene.truth[i] > scene.objects.size()) {
      return absl::InvalidArgumentError(absl::StrCat(base, ".truth.u16: point ", i, " has id ",
                                                     scene.truth[i], " but there are ",
                                                     scene.objects.size(), " objects"));
    }
  }
  return scene;
}

absl::Status WriteSceneFile(const std::string& dir, const SceneFile& scene) {
  const std::string base = (std::filesystem::path(dir) / scene.name).string();
  if (scene.truth.size() != scene.frame.size()) {
    return absl::InvalidArgumentError(absl::StrCat(
        base, ": ", scene.truth.size(), " truth ids for ", scene.frame.size(), " points"));
  }
  for (const SceneFileObject& object : scene.objects) {
    if (object.label.find_first_of(",\r\n") != std::string::npos) {
      return absl::InvalidArgumentError(
          absl::StrCat(base, ": the label '", object.label, "' holds a comma or a newline"));
    }
  }
  if (absl::Status s = WritePcd(base + ".pcd", scene.frame); !s.ok()) return s;
  std::ostringstream csv;
  csv << "object,label,role,source\n";
  for (size_t i = 0; i < scene.objects.size(); ++i) {
    csv << i + 1 << "," << scene.objects[i].label << ","
        << (scene.objects[i].clutter ? "clutter" : "gallery") << "," << scene.objects[i].source
        << "\n";
  }
  std::string truth(2 * scene.truth.size(), '\0');
  for (size_t i = 0; i < scene.truth.size(); ++i) {
    truth[2 * i] = static_cast<char>(scene.truth[i] & 0xff);
    truth[2 * i + 1] = static_cast<char>(scene.truth[i] >> 8);
  }
  if (absl::Status s = WriteFileAtomically(base + ".objects.csv", csv.str()); !s.ok()) return s;
  return WriteFileAtomically(base + ".truth.u16", truth);
}

}  // namespace shapeid
