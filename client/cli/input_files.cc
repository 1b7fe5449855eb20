#include "client/cli/input_files.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <system_error>

#include "absl/status/status.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "core/io/point_cloud_reader.h"

namespace shapeid {
namespace fs = std::filesystem;

namespace {

bool IsHidden(const fs::path& path) {
  const std::string name = path.filename().string();
  return !name.empty() && name[0] == '.';
}

// Appends every point-cloud file under `dir` (recursively, hidden entries skipped) to `files`,
// and every other regular file to `unsupported`.
absl::Status Walk(const fs::path& dir, std::vector<std::string>* files,
                  std::vector<std::string>* unsupported) {
  std::error_code ec;
  fs::recursive_directory_iterator it(dir, fs::directory_options::follow_directory_symlink, ec);
  if (ec) return absl::UnknownError(absl::StrCat(dir.string(), ": ", ec.message()));
  for (; it != fs::recursive_directory_iterator(); it.increment(ec)) {
    if (ec) return absl::UnknownError(absl::StrCat(dir.string(), ": ", ec.message()));
    if (IsHidden(it->path())) {
      if (it->is_directory(ec)) it.disable_recursion_pending();
      continue;
    }
    if (!it->is_regular_file(ec)) continue;
    (IsPointCloudFile(it->path().string()) ? files : unsupported)->push_back(it->path().string());
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

absl::Status CheckStandardInputFormat(const std::vector<std::string>& paths,
                                      const ReadOptions& options) {
  if (options.input_format.has_value() ||
      std::find(paths.begin(), paths.end(), "-") == paths.end()) {
    return absl::OkStatus();
  }
  return absl::InvalidArgumentError(absl::StrCat(
      "standard input (\"-\") has no extension to choose a reader by; give its format with "
      "--input-format (",
      absl::StrJoin(CloudFormatNames(), ", "), ")"));
}

std::string UnsupportedFilesMessage(const std::vector<std::string>& unsupported) {
  if (unsupported.empty()) return "";
  constexpr size_t kNamed = 3;
  std::vector<std::string> first(unsupported.begin(),
                                 unsupported.begin() + std::min(kNamed, unsupported.size()));
  std::string more;
  if (unsupported.size() > kNamed)
    more = absl::StrCat(" and ", unsupported.size() - kNamed, " more");
  return absl::StrCat(unsupported.size(), unsupported.size() == 1 ? " file is" : " files are",
                      " in no format shapeid reads and ", unsupported.size() == 1 ? "was" : "were",
                      " not processed: ", absl::StrJoin(first, ", "), more, " (shapeid reads ",
                      SupportedExtensions(), "; --skip-unsupported ignores other files)");
}

bool ReportUnsupportedFiles(std::FILE* err, absl::string_view command,
                            const std::vector<std::string>& unsupported, bool skip) {
  if (unsupported.empty() || skip) return false;
  const std::string line =
      absl::StrCat("shapeid: ", command, ": ", UnsupportedFilesMessage(unsupported), "\n");
  std::fwrite(line.data(), 1, line.size(), err);
  return true;
}

absl::StatusOr<ReadResult> ReadInputCloud(const std::string& path, const ReadOptions& options) {
  absl::StatusOr<ReadResult> read = ReadPointCloud(path, options);
  // The reader counted the non-finite points; without dropping, the first is in the cloud.
  if (!read.ok() || options.drop_non_finite || read->non_finite_points == 0) return read;
  const size_t first = read->first_non_finite;
  const float* p = read->cloud.data() + 3 * first;
  int axis = 0;
  while (axis < 2 && std::isfinite(p[axis])) ++axis;
  return absl::InvalidArgumentError(absl::StrCat(
      path == "-" ? "standard input" : path, ": point ", first, " has a non-finite coordinate (",
      std::string(1, "xyz"[axis]), " is ", p[axis], "); ", read->non_finite_points, " of ",
      read->cloud.size(),
      " points are non-finite, as an organized depth-camera cloud marks missing pixels; "
      "--drop-nonfinite removes them"));
}

absl::StatusOr<std::vector<std::string>> ExpandInputs(const std::vector<std::string>& paths,
                                                      std::vector<std::string>* unsupported) {
  std::vector<std::string> files;
  for (const std::string& path : paths) {
    std::error_code ec;
    const fs::file_status status = fs::status(path, ec);
    if (!fs::is_directory(status)) {  // a file, or nothing: the reader will say which
      files.push_back(path);
      continue;
    }
    std::vector<std::string> found;
    std::vector<std::string> others;
    if (absl::Status walked = Walk(path, &found, &others); !walked.ok()) return walked;
    std::sort(others.begin(), others.end());
    if (found.empty()) {
      return absl::InvalidArgumentError(
          absl::StrCat(path, ": directory holds no point-cloud file (", SupportedExtensions(), ")",
                       others.empty() ? "" : absl::StrCat("; ", UnsupportedFilesMessage(others))));
    }
    std::sort(found.begin(), found.end());
    files.insert(files.end(), found.begin(), found.end());
    if (unsupported != nullptr)
      unsupported->insert(unsupported->end(), others.begin(), others.end());
  }
  return files;
}

absl::StatusOr<std::vector<LabeledFile>> LabeledFiles(const std::string& dir, Split split,
                                                      std::vector<std::string>* unsupported) {
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
  std::vector<LabeledFile> files;
  std::vector<std::string> others;
  for (const fs::path& label_dir : labels) {
    fs::path root = label_dir;
    if (split == Split::kTrain && fs::is_directory(label_dir / "train", ec)) {
      root = label_dir / "train";
    } else if (split == Split::kTest) {
      root = label_dir / "test";
      if (!fs::is_directory(root, ec)) continue;
    }
    std::vector<std::string> found;
    if (absl::Status walked = Walk(root, &found, &others); !walked.ok()) return walked;
    std::sort(found.begin(), found.end());
    const std::string label = label_dir.filename().string();
    for (std::string& path : found) files.push_back({std::move(path), label});
  }
  std::sort(others.begin(), others.end());
  if (files.empty()) {
    const char* layout = split == Split::kTest ? "<label>/test/<files>" : "<label>/<files>";
    return absl::InvalidArgumentError(
        absl::StrCat(dir, ": no labeled point-cloud file found; expected the layout ", dir, "/",
                     layout, " (one sub-folder per label)",
                     others.empty() ? "" : absl::StrCat("; ", UnsupportedFilesMessage(others))));
  }
  if (unsupported != nullptr) unsupported->insert(unsupported->end(), others.begin(), others.end());
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
