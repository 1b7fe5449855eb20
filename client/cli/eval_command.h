#ifndef SHAPEID_CLIENT_CLI_EVAL_COMMAND_H_
#define SHAPEID_CLIENT_CLI_EVAL_COMMAND_H_

// `shapeid eval`: how often the classifier is right on a labeled folder.
//   eval --gallery G --test DIR   classify DIR's clouds against an existing gallery
//   eval DIR                      DIR/<label>/{train,test}: train a temporary gallery on the
//                                 train clouds, classify the test clouds (hold-out)
//   eval --folds K DIR            DIR/<label>/: stratified K-fold cross-validation, seeded,
//                                 one temporary gallery per fold
// On a server (the default) temporary galleries are deleted afterwards, also when the
// evaluation fails. With `local` the same rounds run in this process on core galleries
// (eval_local.h): no server, the same descriptors and kNN, so the same predictions.

#include <cstdint>
#include <string>

#include "client/cli/batch.h"
#include "client/cli/cli_common.h"
#include "client/cli/eval_metrics.h"
#include "client/cli/eval_rounds.h"
#include "client/cli/gallery_commands.h"
#include "client/cli/input_files.h"

namespace shapeid {

struct EvalOptions {
  std::string dataset;  // the labeled folder
  std::string gallery;  // non-empty: test against this existing gallery (no training)
  int folds = 0;        // > 1: k-fold; 0: hold-out when DIR has train/test, else 5-fold
  uint64_t seed = 1;    // k-fold shuffle
  // Settings of the temporary galleries (ignored with --gallery): spec, k, weighting,
  // scaling, reject distance. `k` also overrides the gallery's k when testing.
  GalleryCreateOptions create;
  // Train and classify in this process, no server. Incompatible with `gallery` (a usage
  // error). `batch.jobs` is then the number of threads describing clouds.
  bool local = false;
  // Write the HTML report here (eval_report.h); it reads the first errors' test files and
  // their nearest training files again, with batch.read, for their pictures.
  std::string report_html;
  bool with_predictions = false;  // json: include every prediction
  BatchOptions batch;
};

// Runs the evaluation and prints it (context.format) and, if asked, the HTML report. Usage
// errors (bad options, folder, spec with `local`) are found before any file is read. Returns
// kExitOk; kExitSomeInputsFailed when a file failed (one line on stderr each; the evaluation
// goes on without it) or the output could not be written; kExitUsage; or, when the server
// refuses or no training file of a round can be used, ExitCodeForStatus of that error.
int RunEval(const EvalOptions& options, const CliContext& context);

}  // namespace shapeid

#endif  // SHAPEID_CLIENT_CLI_EVAL_COMMAND_H_
