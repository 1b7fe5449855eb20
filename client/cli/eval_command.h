#ifndef SHAPEID_CLIENT_CLI_EVAL_COMMAND_H_
#define SHAPEID_CLIENT_CLI_EVAL_COMMAND_H_

// `shapeid eval`: how often the server is right on a labelled folder.
//   eval --gallery G --test DIR   classify DIR's clouds against an existing gallery
//   eval DIR                      DIR/<label>/{train,test}: train a temporary gallery on the
//                                 train clouds, classify the test clouds (hold-out)
//   eval --folds K DIR            DIR/<label>/: stratified K-fold cross-validation, seeded,
//                                 one temporary gallery per fold
// Temporary galleries are deleted afterwards, also when the evaluation fails.

#include <cstdint>
#include <string>

#include "client/cli/batch.h"
#include "client/cli/cli_common.h"
#include "client/cli/eval_metrics.h"
#include "client/cli/gallery_commands.h"
#include "client/cli/input_files.h"

namespace shapeid {

struct EvalOptions {
  std::string dataset;  // the labelled folder
  std::string gallery;  // non-empty: test against this existing gallery (no training)
  int folds = 0;        // > 1: k-fold; 0: hold-out when DIR has train/test, else 5-fold
  uint64_t seed = 1;    // k-fold shuffle
  // Settings of the temporary galleries (ignored with --gallery): spec, k, weighting,
  // scaling, reject distance. `k` also overrides the gallery's k when testing.
  GalleryCreateOptions create;
  std::string report_html;        // write the HTML report here
  bool with_predictions = false;  // json: include every prediction
  BatchOptions batch;
};

int RunEval(const EvalOptions& options, const CliContext& context);

// Stratified fold assignment: within each label, files are shuffled with `seed`
// (Fisher-Yates over splitmix64, the same on every platform) and dealt round-robin into
// `folds` folds, so each fold holds ~1/folds of every class. Returns the fold of each file.
std::vector<int> StratifiedFolds(const std::vector<LabelledFile>& files, int folds, uint64_t seed);

}  // namespace shapeid

#endif  // SHAPEID_CLIENT_CLI_EVAL_COMMAND_H_
