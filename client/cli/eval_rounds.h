#ifndef SHAPEID_CLIENT_CLI_EVAL_ROUNDS_H_
#define SHAPEID_CLIENT_CLI_EVAL_ROUNDS_H_

// Which clouds `shapeid eval` trains on and tests, round by round: the part of an evaluation
// that does not depend on where the classifier runs (a server or this process).

#include <cstdint>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "client/cli/input_files.h"

namespace shapeid {

// One round: a fresh classifier trained on `train`, then asked about every file of `test`.
struct EvalRound {
  std::vector<LabeledFile> train;  // empty against an existing gallery
  std::vector<LabeledFile> test;
};

struct EvalPlan {
  std::string mode;  // "gallery", "holdout" or "kfold" (EvalRun::mode)
  int folds = 1;     // K for kfold, else 1
  std::vector<EvalRound> rounds;
  std::vector<std::string> unsupported;  // the dataset's files in no format shapeid reads
};

// The rounds for a labeled folder (input_files.h):
//  - against_gallery: one round, no training, testing DIR/<label>/test/ when every label has
//    train/ and test/, else every file under DIR/<label>/;
//  - folds == 0 and DIR/<label>/{train,test}/: one hold-out round;
//  - otherwise stratified k-fold (folds, or 5 when 0) with StratifiedFolds(seed): round f
//    tests fold f and trains on the others, every list in the folder's order.
// InvalidArgument for folds < 2 (other than 0), fewer files than folds or a folder without
// labeled files; NotFound for a missing folder. All are usage errors: nothing was done.
absl::StatusOr<EvalPlan> PlanEval(const std::string& dataset, bool against_gallery, int folds,
                                  uint64_t seed);

// Stratified fold assignment: within each label, files are shuffled with `seed`
// (Fisher-Yates over splitmix64, the same on every platform) and dealt round-robin into
// `folds` folds, so each fold holds ~1/folds of every class. Returns the fold of each file.
std::vector<int> StratifiedFolds(const std::vector<LabeledFile>& files, int folds, uint64_t seed);

}  // namespace shapeid

#endif  // SHAPEID_CLIENT_CLI_EVAL_ROUNDS_H_
