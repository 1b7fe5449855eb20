#ifndef SHAPEID_CLIENT_CLI_INPUT_FILES_H_
#define SHAPEID_CLIENT_CLI_INPUT_FILES_H_

// Turning the paths on a command line into the files a batch works on: plain lists, and
// labeled folders (one sub-folder per class, the layout of ModelNet and of most datasets).

#include <cstdio>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "core/io/read_options.h"

namespace shapeid {

// True for an extension ReadPointCloud knows (core/io/read_options.h's CloudFormat, any case).
bool IsPointCloudFile(absl::string_view path);

// Files as given stay, whatever their extension and even when missing: the reader reports
// each as one failed input, and a batch goes on; "-" is standard input. A directory is walked
// recursively for point-cloud files, sorted by path, hidden entries skipped; its other files
// are appended to `unsupported` (when given) for the command to report. InvalidArgument for a
// directory with no point-cloud file, naming what it holds instead.
absl::StatusOr<std::vector<std::string>> ExpandInputs(
    const std::vector<std::string>& paths, std::vector<std::string>* unsupported = nullptr);

// OK unless `paths` holds "-" (standard input) and `options` names no input_format: standard
// input has no extension to choose a reader by, so that is a usage error, told before any
// input is read. InvalidArgument naming --input-format and its formats.
absl::Status CheckStandardInputFormat(const std::vector<std::string>& paths,
                                      const ReadOptions& options);

// The one stderr line that reports a walk's unsupported files: how many, the first few names,
// the extensions shapeid reads, and the flag that ignores them. Empty when there are none.
std::string UnsupportedFilesMessage(const std::vector<std::string>& unsupported);

// What every command does with a walk's unsupported files, once, before its work: unless
// `skip` (--skip-unsupported) or there are none, writes "shapeid: COMMAND: " and the message
// to `err` and returns true: they count as failed inputs for the exit status.
bool ReportUnsupportedFiles(std::FILE* err, absl::string_view command,
                            const std::vector<std::string>& unsupported, bool skip);

// ReadPointCloud for the commands: as it, and a cloud with non-finite points (an organized
// cloud's missing pixels) is refused here, before any server sees it, with the count and
// the flag that removes them (--drop-nonfinite), unless options.drop_non_finite.
absl::StatusOr<ReadResult> ReadInputCloud(const std::string& path, const ReadOptions& options);

struct LabeledFile {
  std::string path;
  std::string label;
};

// Which part of a labeled folder to take.
enum class Split {
  kAll,    // every point-cloud file under DIR/<label>/
  kTrain,  // DIR/<label>/train/ where it exists, else every file under DIR/<label>/
  kTest,   // DIR/<label>/test/ only
};

// The files of a labeled folder: each sub-folder of `dir` is a label (hidden ones skipped)
// and holds its clouds, at any depth. Sorted by label, then path. InvalidArgument when `dir`
// has no sub-folder or no file at all (with the layout expected in the message), NotFound
// when it does not exist. A label folder without files for `split` is skipped silently; the
// caller sees it missing from the result. Files in formats no reader knows go to
// `unsupported` (when given), as for ExpandInputs.
absl::StatusOr<std::vector<LabeledFile>> LabeledFiles(
    const std::string& dir, Split split, std::vector<std::string>* unsupported = nullptr);

// True when every label folder of `dir` has both a train/ and a test/ sub-folder (hold-out
// layout, as ../shared/data/modelnet10); false for a flat <label>/ layout.
bool HasTrainTestSplit(const std::string& dir);

}  // namespace shapeid

#endif  // SHAPEID_CLIENT_CLI_INPUT_FILES_H_
