#include "client/cli/eval_rounds.h"

#include <map>
#include <utility>

#include "absl/strings/str_cat.h"
#include "core/random.h"

namespace shapeid {

std::vector<int> StratifiedFolds(const std::vector<LabeledFile>& files, int folds, uint64_t seed) {
  std::map<std::string, std::vector<size_t>> by_label;
  for (size_t i = 0; i < files.size(); ++i) by_label[files[i].label].push_back(i);
  std::vector<int> fold(files.size(), 0);
  SplitMix64 rng(seed);
  int next = 0;  // continue dealing across labels so small classes do not all start at fold 0
  for (auto& [label, members] : by_label) {
    for (size_t i = members.size(); i > 1; --i) {
      const size_t j = static_cast<size_t>(rng.Next() % i);
      std::swap(members[i - 1], members[j]);
    }
    for (size_t index : members) {
      fold[index] = next;
      next = (next + 1) % folds;
    }
  }
  return fold;
}

absl::StatusOr<EvalPlan> PlanEval(const std::string& dataset, bool against_gallery, int folds,
                                  uint64_t seed) {
  EvalPlan plan;
  const bool split_layout = HasTrainTestSplit(dataset);
  if (against_gallery) {
    plan.mode = "gallery";
    absl::StatusOr<std::vector<LabeledFile>> test =
        LabeledFiles(dataset, split_layout ? Split::kTest : Split::kAll, &plan.unsupported);
    if (!test.ok()) return test.status();
    plan.rounds.push_back({{}, std::move(test).value()});
    return plan;
  }
  if (folds == 0 && split_layout) {
    plan.mode = "holdout";
    absl::StatusOr<std::vector<LabeledFile>> train =
        LabeledFiles(dataset, Split::kTrain, &plan.unsupported);
    if (!train.ok()) return train.status();
    absl::StatusOr<std::vector<LabeledFile>> test =
        LabeledFiles(dataset, Split::kTest, &plan.unsupported);
    if (!test.ok()) return test.status();
    plan.rounds.push_back({std::move(train).value(), std::move(test).value()});
    return plan;
  }
  plan.mode = "kfold";
  const int k = folds == 0 ? 5 : folds;
  if (k < 2) return absl::InvalidArgumentError("--folds must be at least 2");
  absl::StatusOr<std::vector<LabeledFile>> files =
      LabeledFiles(dataset, Split::kAll, &plan.unsupported);
  if (!files.ok()) return files.status();
  if (files->size() < static_cast<size_t>(k)) {
    return absl::InvalidArgumentError(
        absl::StrCat(dataset, ": ", files->size(), " files cannot make ", k, " folds"));
  }
  plan.folds = k;
  const std::vector<int> fold = StratifiedFolds(*files, k, seed);
  plan.rounds.resize(static_cast<size_t>(k));
  for (size_t i = 0; i < files->size(); ++i) {
    for (int f = 0; f < k; ++f) {
      EvalRound& round = plan.rounds[static_cast<size_t>(f)];
      (f == fold[i] ? round.test : round.train).push_back((*files)[i]);
    }
  }
  return plan;
}

}  // namespace shapeid
