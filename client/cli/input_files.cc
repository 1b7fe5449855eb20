#include "client/cli/input_files.h"

#include <algorithm>
#include <filesystem>
#include <system_error>

#include "absl/status/status.h"
#include "absl/strings/str_cat.h"
#include "core/io/point_cloud_reader.h"

namespace shapeid {
namespace fs = std::filesystem;

namespace {

bool IsHidden(const fs::path& path) {
  const std::string name = path.filename().string();
  return !name.empty() && name[0] == '.';
}

// Appends every point-cloud file under `dir` (recursively, hidden entries skipped).
absl::Status Walk(const fs::path& dir, std::vector<std::string>* files) {
  std::error_code ec;
  fs::recursive_directory_iterator it(dir, fs::directory_options::follow_directory_symlink, ec);
  if (ec) return absl::UnknownError(absl::StrCat(dir.string(), ": ", ec.message()));
  for (; it != fs::recursive_directory_iterator(); it.increment(ec)) {
    if (ec) return absl::UnknownError(absl::StrCat(dir.string(), ": ", ec.message()));
    if (IsHidden(it->path())) {
      if (it->is_directory(ec)) it.disable_recursion_pending();
      continue;
    }
    if (it->is_regular_file(ec) && IsPointCloudFile(it->path().string())) {
      files->push_back(it->path().string());
    }
  }
  if (ec) return absl::UnknownError(absl::StrCat(dir.string(), ": ", ec.message()));
  return absl::OkStatus();
}

std::vector<fs::path> LabelFolders(const fs::path& dir, std::error_code& ec) {
  std::vector<fs::path> labels;
  for (fs::directory_iterator it(dir, ec); !ec && it != fs::directory_iterator();
       it.increment(ec)) {
    std::error_code type_ec;
    if (it->is_directory(type_ec) && !IsHidden(it->path())) labels.push_back(it->path());
  }
  std::sort(labels.begin(), labels.end());
  return labels;
}

}  // namespace

bool IsPointCloudFile(absl::string_view path) { return CloudFormatForPath(path).ok(); }

absl::StatusOr<std::vector<std::string>> ExpandInputs(const std::vector<std::string>& paths) {
  std::vector<std::string> files;
  for (const std::string& path : paths) {
    std::error_code ec;
    const fs::file_status status = fs::status(path, ec);
    if (!fs::is_directory(status)) {  // a file, or nothing: the reader will say which
      files.push_back(path);
      continue;
    }
    std::vector<std::string> found;
    if (absl::Status walked = Walk(path, &found); !walked.ok()) return walked;
    if (found.empty()) {
      return absl::InvalidArgumentError(
          absl::StrCat(path,
                       ": directory holds no point-cloud file (.pcd .ply .off .obj .xyz "
                       ".txt .csv)"));
    }
    std::sort(found.begin(), found.end());
    files.insert(files.end(), found.begin(), found.end());
  }
  return files;
}

absl::StatusOr<std::vector<LabelledFile>> LabelledFiles(const std::string& dir, Split split) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) {
    if (!fs::exists(dir, ec)) {
      return absl::NotFoundError(absl::StrCat(dir, ": no such directory"));
    }
    return absl::InvalidArgumentError(
        absl::StrCat(dir, ": not a directory; expected one sub-folder per label"));
  }
  const std::vector<fs::path> labels = LabelFolders(dir, ec);
  if (ec) return absl::UnknownError(absl::StrCat(dir, ": ", ec.message()));
  std::vector<LabelledFile> files;
  for (const fs::path& label_dir : labels) {
    fs::path root = label_dir;
    if (split == Split::kTrain && fs::is_directory(label_dir / "train", ec)) {
      root = label_dir / "train";
    } else if (split == Split::kTest) {
      root = label_dir / "test";
      if (!fs::is_directory(root, ec)) continue;
    }
    std::vector<std::string> found;
    if (absl::Status walked = Walk(root, &found); !walked.ok()) return walked;
    std::sort(found.begin(), found.end());
    const std::string label = label_dir.filename().string();
    for (std::string& path : found) files.push_back({std::move(path), label});
  }
  if (files.empty()) {
    const char* layout = split == Split::kTest ? "<label>/test/<files>" : "<label>/<files>";
    return absl::InvalidArgumentError(
        absl::StrCat(dir, ": no labelled point-cloud file found; expected the layout ", dir, "/",
                     layout, " (one sub-folder per label)"));
  }
  return files;
}

bool HasTrainTestSplit(const std::string& dir) {
  std::error_code ec;
  const std::vector<fs::path> labels = LabelFolders(dir, ec);
  if (ec || labels.empty()) return false;
  for (const fs::path& label_dir : labels) {
    if (!fs::is_directory(label_dir / "train", ec) || !fs::is_directory(label_dir / "test", ec)) {
      return false;
    }
  }
  return true;
}

}  // namespace shapeid
