#ifndef SHAPEID_CLIENT_CLI_EVAL_METRICS_H_
#define SHAPEID_CLIENT_CLI_EVAL_METRICS_H_

// Scoring of a labeled evaluation (`shapeid eval`): the confusion matrix, overall and
// per-class accuracy, timing, and its text renderings (table, JSON, CSV; the HTML page is in
// eval_report.h). Pure functions over plain structs: the eval command fills an EvalRun, these
// render it.

#include <cstdint>
#include <string>
#include <vector>

namespace shapeid {

// One of a prediction's nearest samples, for tracing an answer to the training data.
struct EvalNeighbor {
  uint64_t sample_id = 0;
  std::string label;
  double distance = 0;  // descriptor distance, as Classify reports it
  uint32_t view = 0;    // 0: the trained cloud; i >= 1: its i-th synthetic view
  // The training file: its path as trained (eval --local: as listed; a server's gallery: the
  // sample's source as the training client gave it). Empty when the gallery does not know it.
  std::string file;
};

// One classified test cloud.
struct EvalPrediction {
  std::string file;
  std::string truth;      // the class the folder layout gives
  std::string predicted;  // the label the classifier returned; "unknown" when it rejected
  double confidence = 0;  // vote share of the winning label, in [0, 1]
  double seconds = 0;     // wall time of the classification seen by the caller
  int fold = 0;           // 0-based fold (hold-out: always 0)
  std::vector<EvalNeighbor> neighbors;  // nearest first, as many as k
};

// Everything one eval produced. The metrics below are computed from `predictions`.
struct EvalRun {
  std::string mode;             // "holdout", "gallery" (against an existing gallery) or "kfold"
  std::string dataset;          // the folder evaluated, as given
  std::string descriptor_spec;  // canonical spec of the gallery(ies)
  uint32_t k = 0;               // neighbors used
  int folds = 1;                // K for kfold, else 1
  uint64_t seed = 0;            // kfold shuffle seed
  // The existing gallery classified against ("gallery" mode); empty when each round trains
  // a fresh one.
  std::string gallery;
  // The samples the classifiers held: total over folds; in "gallery" mode the gallery's own
  // sample count (trained before the run, so train_seconds stays 0).
  uint64_t train_samples = 0;
  std::string started;         // when the run started: UTC, ISO 8601 ("2026-11-28T15:05:00Z")
  std::string server;          // the server's address; empty in-process (eval --local)
  std::string client_version;  // this CLI's shapeid version
  std::string server_version;  // the server's shapeid version; empty in-process or unknown
  double train_seconds = 0;    // wall time spent training, total over folds
  double test_seconds = 0;     // wall time spent classifying, total over folds
  // --learn mlp: each round's gallery fitted its trained head (core/gallery/gallery_head.h)
  // before testing; fit time and the heads' held-out rows (and those answered right), summed
  // over rounds. Empty `learn`: the kNN vote alone.
  std::string learn;
  double fit_seconds = 0;
  uint64_t head_holdout_rows = 0;
  uint64_t head_holdout_right = 0;
  std::vector<std::string> failed_files;  // files that could not be read or classified
  std::vector<EvalPrediction> predictions;
};

struct ClassScore {
  std::string label;
  uint64_t tests = 0;      // test clouds whose truth is this class
  uint64_t correct = 0;    // of those, predicted as this class
  uint64_t predicted = 0;  // test clouds predicted as this class (any truth)
  double recall = 0;       // correct / tests (the per-class accuracy); 0 when tests == 0
  double precision = 0;    // correct / predicted; 0 when predicted == 0
};

struct EvalMetrics {
  // Sorted: every truth class, then any predicted label that is not a truth class (e.g.
  // "unknown"), each once. Rows of `confusion` are truths, columns predictions, both indexed
  // by `labels` (so the matrix is square; the rows of the extra labels are all zero).
  std::vector<std::string> labels;
  std::vector<std::vector<uint64_t>> confusion;
  std::vector<ClassScore> classes;  // one per truth class, sorted by label
  uint64_t tests = 0;
  uint64_t correct = 0;
  double accuracy = 0;             // correct / tests (overall, micro)
  double mean_class_accuracy = 0;  // mean of recall over truth classes (macro)
  // kfold only (else empty / 0): accuracy of each fold, in fold order, their mean and sample
  // std deviation (n - 1; 0 for a single fold). A fold with no predictions has no entry.
  std::vector<double> fold_accuracy;
  double fold_accuracy_mean = 0;
  double fold_accuracy_std = 0;
  // Wall time of testing per test cloud (test_seconds / tests): with parallel streams, the
  // inverse of throughput. 0 when tests == 0.
  double seconds_per_cloud = 0;
  // Median of the predictions' own call times: what one caller waits for one answer
  // (network, descriptor and search included; file reading excluded).
  double median_call_seconds = 0;
};

EvalMetrics ComputeEvalMetrics(const EvalRun& run);

// Human-readable summary for a terminal: the run (with the gallery's name and sample count
// in "gallery" mode), headline figures, the per-class table, the confusion matrix (truth rows
// only; columns keyed c1..cN with a legend when full names would make a line wider than 150
// characters) and the failed files (the first 20 and a count).
std::string FormatEvalTable(const EvalRun& run, const EvalMetrics& metrics);
// One JSON object (then '\n') with the run's parameters (gallery, start time, server and
// versions included), the metrics, the confusion matrix and the failed files; not the individual
// predictions unless `with_predictions`. Ratios are in [0, 1], times in seconds.
std::string FormatEvalJson(const EvalRun& run, const EvalMetrics& metrics, bool with_predictions);
// CSV with a header row: one row per class (label,tests,correct,recall,precision), then a row
// "__overall__" with the totals (its recall and precision are the micro averages, both equal to
// the accuracy). Fields are quoted as RFC 4180 says; lines end in '\n'.
std::string FormatEvalCsv(const EvalMetrics& metrics);

}  // namespace shapeid

#endif  // SHAPEID_CLIENT_CLI_EVAL_METRICS_H_
