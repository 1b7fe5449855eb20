#ifndef SHAPEID_CLIENT_CLI_EVAL_TESTING_H_
#define SHAPEID_CLIENT_CLI_EVAL_TESTING_H_

// Test-only runs for the tests of eval's metrics and renderings.

#include <cstddef>
#include <string>

#include "absl/strings/str_cat.h"
#include "absl/strings/string_view.h"
#include "client/cli/eval_metrics.h"

namespace shapeid::eval_testing {

// Appends a prediction for file "TRUTH/N.pcd" (N: its index), confidence 0.75, 50 ms.
inline void Add(EvalRun& run, const std::string& truth, const std::string& predicted,
                int fold = 0) {
  EvalPrediction p;
  p.file = absl::StrCat(truth, "/", run.predictions.size(), ".pcd");
  p.truth = truth;
  p.predicted = predicted;
  p.confidence = 0.75;
  p.seconds = 0.05;
  p.fold = fold;
  run.predictions.push_back(p);
}

// bench 3/4 (one taken for a chair), chair 2/3 (one for a table), table 2/3 (one for a bench).
// Added out of order so that the sorting is exercised.
inline EvalRun ThreeClassRun() {
  EvalRun run;
  run.mode = "holdout";
  run.dataset = "data/furniture";
  run.descriptor_spec = "rphsd:bins=8";
  run.k = 3;
  run.train_samples = 90;
  run.train_seconds = 2.5;
  run.test_seconds = 0.5;
  Add(run, "table", "table");
  Add(run, "chair", "chair");
  Add(run, "bench", "bench");
  Add(run, "bench", "chair");
  Add(run, "table", "bench");
  Add(run, "chair", "table");
  Add(run, "bench", "bench");
  Add(run, "table", "table");
  Add(run, "chair", "chair");
  Add(run, "bench", "bench");
  return run;
}

// How often `needle` occurs in `text`, overlaps included.
inline size_t CountOf(absl::string_view text, absl::string_view needle) {
  size_t count = 0;
  for (size_t at = text.find(needle); at != absl::string_view::npos;
       at = text.find(needle, at + 1)) {
    ++count;
  }
  return count;
}

}  // namespace shapeid::eval_testing

#endif  // SHAPEID_CLIENT_CLI_EVAL_TESTING_H_
