#ifndef SHAPEID_CLIENT_CLI_EVAL_BACKEND_H_
#define SHAPEID_CLIENT_CLI_EVAL_BACKEND_H_

// Where `shapeid eval` trains and classifies: a server (eval_server.h) or this process
// (eval_local.h). RunEval plans the rounds (eval_rounds.h), drives a backend through them and
// renders the EvalRun; a backend only turns files into a trained classifier and predictions.

#include <string>
#include <vector>

#include "absl/status/status.h"
#include "client/cli/cli_common.h"
#include "client/cli/eval_metrics.h"
#include "client/cli/input_files.h"

namespace shapeid {

// The outcome of one step. Not OK: the evaluation stops, with "shapeid: <what>: <message>"
// on stderr and ExitCodeForStatus(status) as the exit code. A file that fails is not a
// stopped step: it is counted in EvalRun::failed_files and the step goes on.
struct EvalStep {
  std::string what;
  absl::Status status;
  bool ok() const { return status.ok(); }
};

class EvalBackend {
 public:
  virtual ~EvalBackend() = default;

  // The server's address, for the hint printed with an unreachable server; empty in-process.
  virtual std::string target() const = 0;

  // Makes round `round`'s classifier: a fresh gallery trained on `train`, or (against an
  // existing gallery, `train` empty) that gallery. Sets run.descriptor_spec and run.k; adds
  // to run.train_samples and run.train_seconds (wall time, file reading included), or against
  // an existing gallery sets run.gallery and run.train_samples to its name and sample count;
  // appends unusable files to run.failed_files, after one line each on stderr through
  // `progress`. Replaces the previous round's classifier.
  virtual EvalStep Train(int round, const std::vector<LabeledFile>& train, Progress& progress,
                         EvalRun& run) = 0;

  // Classifies every file of `test` against the round's classifier. Appends one
  // EvalPrediction per classified file (fold = round), in the order of `test`, whatever the
  // parallelism; failed files to run.failed_files (one line each on stderr); the wall time to
  // run.test_seconds.
  virtual EvalStep Test(int round, const std::vector<LabeledFile>& test, Progress& progress,
                        EvalRun& run) = 0;

  // Sets run.server_version: the server's shapeid version, left empty in-process or when the
  // server does not tell (best effort: never stops the evaluation).
  virtual void IdentifyServer(EvalRun& run) = 0;
};

}  // namespace shapeid

#endif  // SHAPEID_CLIENT_CLI_EVAL_BACKEND_H_
