#ifndef SHAPEID_CLIENT_CLI_INPUT_FILES_H_
#define SHAPEID_CLIENT_CLI_INPUT_FILES_H_

// Turning the paths on a command line into the files a batch works on: plain lists, and
// labelled folders (one sub-folder per class, the layout of ModelNet and of most datasets).

#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"

namespace shapeid {

// True for an extension ReadPointCloud knows (.pcd .ply .off .obj .xyz .txt .csv, any case).
bool IsPointCloudFile(absl::string_view path);

// Files as given stay, whatever their extension and even when missing: the reader reports
// each as one failed input, and a batch goes on. A directory is walked recursively for
// point-cloud files, sorted by path, hidden entries skipped; InvalidArgument for a directory
// with no point-cloud file.
absl::StatusOr<std::vector<std::string>> ExpandInputs(const std::vector<std::string>& paths);

struct LabelledFile {
  std::string path;
  std::string label;
};

// Which part of a labelled folder to take.
enum class Split {
  kAll,    // every point-cloud file under DIR/<label>/
  kTrain,  // DIR/<label>/train/ where it exists, else every file under DIR/<label>/
  kTest,   // DIR/<label>/test/ only
};

// The files of a labelled folder: each sub-folder of `dir` is a label (hidden ones skipped)
// and holds its clouds, at any depth. Sorted by label, then path. InvalidArgument when `dir`
// has no sub-folder or no file at all (with the layout expected in the message), NotFound
// when it does not exist. A label folder without files for `split` is skipped silently; the
// caller sees it missing from the result.
absl::StatusOr<std::vector<LabelledFile>> LabelledFiles(const std::string& dir, Split split);

// True when every label folder of `dir` has both a train/ and a test/ sub-folder (hold-out
// layout, as ../shared/data/modelnet10); false for a flat <label>/ layout.
bool HasTrainTestSplit(const std::string& dir);

}  // namespace shapeid

#endif  // SHAPEID_CLIENT_CLI_INPUT_FILES_H_
