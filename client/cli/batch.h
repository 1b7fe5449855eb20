#ifndef SHAPEID_CLIENT_CLI_BATCH_H_
#define SHAPEID_CLIENT_CLI_BATCH_H_

// The two batch engines behind `shapeid train`, `classify` and `eval`: many files, read here,
// sent to the server on parallel streams, one bad file reported and skipped, a server-wide
// failure (server gone, gallery missing) stopping the batch at once.

#include <cstdint>
#include <functional>
#include <map>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "client/cli/cli_common.h"
#include "client/cli/input_files.h"
#include "client/client.h"
#include "core/io/read_options.h"

namespace shapeid {

struct BatchOptions {
  int jobs = 4;                   // parallel streams: reading and describing overlap the network
  size_t train_batch = 32;        // samples per Train stream (all-or-nothing on the server)
  ReadOptions read;               // how files become clouds (non-finite points, mesh sampling)
  bool skip_unsupported = false;  // folders' files of other formats: ignored, not reported
  // Train: key/value provenance given to every sample (its source is always its file's
  // absolute path).
  std::map<std::string, std::string> metadata;
  v1::SensorFrame sensor_frame;  // the sensor's frame for Train (Classify's is in its options)
};

// A file the batch could not use, with the reason ("a.pcd: line 3: ...").
struct FailedInput {
  std::string path;
  absl::Status status;
};

// A file trained into the gallery, and the sample id it was given (client-chosen, so known
// before the server answers): what traces a neighbor in a later Classify back to its file.
struct TrainedFile {
  std::string path;
  std::string label;
  uint64_t sample_id = 0;
};

struct TrainOutcome {
  uint64_t trained = 0;               // samples added
  std::vector<TrainedFile> files;     // the trained files, in input order
  std::vector<FailedInput> failed;    // skipped files
  absl::Status stopped;               // non-OK when the batch stopped early (StopsBatch)
  uint64_t gallery_sample_count = 0;  // after the last successful stream
  double seconds = 0;
};

// Adds `files` to `gallery`, train_batch samples per stream, `jobs` streams at once, each
// sample with its file's absolute path as its source (so a neighbor can be traced to its
// file from any directory) and options.metadata. A stream refused for one bad sample is
// resent one sample per stream so that only the bad file is skipped. Errors go to `err` as they
// happen (through `progress`).
TrainOutcome TrainFiles(Client& client, const std::string& gallery,
                        const std::vector<LabeledFile>& files, const BatchOptions& options,
                        Progress& progress, std::FILE* err);

struct ClassifyOutcome {
  size_t classified = 0;
  std::vector<FailedInput> failed;
  absl::Status stopped;
  double seconds = 0;
};

// Classifies every file against `gallery` with the per-call `call` options (k, exact), `jobs`
// at once. `on_result(index, response, seconds)` runs for each success and `on_failure(index,
// status)` for each failed file, in the order of `paths` (results are held back until the
// ones before them are out, so output streams in input order), on one thread at a time.
ClassifyOutcome ClassifyFiles(
    Client& client, const std::string& gallery, const Client::ClassifyOptions& call,
    const std::vector<std::string>& paths, const BatchOptions& options, Progress& progress,
    const std::function<void(size_t, const v1::ClassifyResponse&, double)>& on_result,
    const std::function<void(size_t, const absl::Status&)>& on_failure);

}  // namespace shapeid

#endif  // SHAPEID_CLIENT_CLI_BATCH_H_
