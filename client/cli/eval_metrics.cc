#include "client/cli/eval_metrics.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/strings/string_view.h"
#include "absl/strings/strip.h"
#include "client/cli/cli_common.h"
#include "core/json.h"

namespace shapeid {
namespace {

// Terminal tables switch to short column keys when the full labels would be wider than this.
constexpr size_t kMaxTableWidth = 150;
// Row labels of a keyed confusion matrix are cut to this many characters (the per-class table
// above it shows them in full).
constexpr size_t kMaxMatrixRowLabel = 32;
// Long lists are cut so that a bad run does not bury the figures (the JSON has everything).
constexpr size_t kMaxTableFailedFiles = 20;

double Ratio(uint64_t part, uint64_t whole) {
  return whole == 0 ? 0.0 : static_cast<double>(part) / static_cast<double>(whole);
}

std::string PadRight(absl::string_view text, size_t width) {
  const size_t w = DisplayWidth(text);
  return absl::StrCat(text, std::string(w < width ? width - w : 0, ' '));
}

std::string PadLeft(absl::string_view text, size_t width) {
  const size_t w = DisplayWidth(text);
  return absl::StrCat(std::string(w < width ? width - w : 0, ' '), text);
}

// `text` cut to `width` characters, ending in "..." when cut (never inside a UTF-8 sequence).
std::string Truncate(absl::string_view text, size_t width) {
  if (DisplayWidth(text) <= width) return std::string(text);
  size_t chars = 0, end = 0;
  for (; end < text.size(); ++end) {
    if ((static_cast<unsigned char>(text[end]) & 0xC0) == 0x80) continue;
    if (chars++ == width - 3) break;
  }
  return absl::StrCat(text.substr(0, end), "...");
}

std::string CsvNumber(double value) { return absl::StrFormat("%.10g", value); }

}  // namespace

EvalMetrics ComputeEvalMetrics(const EvalRun& run) {
  EvalMetrics m;
  std::set<std::string> truths, extras;
  for (const EvalPrediction& p : run.predictions) truths.insert(p.truth);
  for (const EvalPrediction& p : run.predictions) {
    if (truths.count(p.predicted) == 0) extras.insert(p.predicted);
  }
  m.labels.assign(truths.begin(), truths.end());
  m.labels.insert(m.labels.end(), extras.begin(), extras.end());
  std::map<std::string, size_t> index;
  for (size_t i = 0; i < m.labels.size(); ++i) index[m.labels[i]] = i;

  m.confusion.assign(m.labels.size(), std::vector<uint64_t>(m.labels.size(), 0));
  std::map<int, std::pair<uint64_t, uint64_t>> folds;  // fold -> (correct, tests)
  for (const EvalPrediction& p : run.predictions) {
    ++m.confusion[index[p.truth]][index[p.predicted]];
    const uint64_t correct = p.truth == p.predicted ? 1 : 0;
    m.correct += correct;
    folds[p.fold].first += correct;
    ++folds[p.fold].second;
  }
  m.tests = run.predictions.size();
  m.accuracy = Ratio(m.correct, m.tests);
  m.seconds_per_cloud = m.tests == 0 ? 0.0 : run.test_seconds / static_cast<double>(m.tests);
  if (!run.predictions.empty()) {
    std::vector<double> calls;
    calls.reserve(run.predictions.size());
    for (const EvalPrediction& p : run.predictions) calls.push_back(p.seconds);
    const size_t mid = calls.size() / 2;
    std::nth_element(calls.begin(), calls.begin() + static_cast<std::ptrdiff_t>(mid), calls.end());
    m.median_call_seconds = calls[mid];
    if (calls.size() % 2 == 0) {
      m.median_call_seconds =
          0.5 *
          (m.median_call_seconds +
           *std::max_element(calls.begin(), calls.begin() + static_cast<std::ptrdiff_t>(mid)));
    }
  }

  for (size_t i = 0; i < truths.size(); ++i) {
    ClassScore score;
    score.label = m.labels[i];
    for (size_t j = 0; j < m.labels.size(); ++j) {
      score.tests += m.confusion[i][j];
      score.predicted += m.confusion[j][i];
    }
    score.correct = m.confusion[i][i];
    score.recall = Ratio(score.correct, score.tests);
    score.precision = Ratio(score.correct, score.predicted);
    m.mean_class_accuracy += score.recall;
    m.classes.push_back(std::move(score));
  }
  if (!m.classes.empty()) m.mean_class_accuracy /= static_cast<double>(m.classes.size());

  if (run.mode == "kfold") {
    // A fold without predictions (every file failed) has no accuracy; it is left out rather
    // than counted as 0, which would drag the mean down for a reason that is not accuracy.
    for (const auto& [fold, counts] : folds) {
      m.fold_accuracy.push_back(Ratio(counts.first, counts.second));
    }
    const size_t n = m.fold_accuracy.size();
    for (double a : m.fold_accuracy) m.fold_accuracy_mean += a;
    if (n > 0) m.fold_accuracy_mean /= static_cast<double>(n);
    if (n > 1) {
      double sum_sq = 0;
      for (double a : m.fold_accuracy) {
        sum_sq += (a - m.fold_accuracy_mean) * (a - m.fold_accuracy_mean);
      }
      m.fold_accuracy_std = std::sqrt(sum_sq / static_cast<double>(n - 1));
    }
  }
  return m;
}

std::string FormatEvalTable(const EvalRun& run, const EvalMetrics& metrics) {
  std::string out = absl::StrCat("eval ", run.mode, "  dataset ", run.dataset);
  if (run.mode == "kfold") absl::StrAppend(&out, "  folds ", run.folds, "  seed ", run.seed);
  if (!run.gallery.empty()) {
    absl::StrAppend(&out, "  gallery ", run.gallery, " (", run.train_samples, " samples)");
  }
  absl::StrAppend(&out, "\naccuracy ", FormatPercent(metrics.accuracy), " % (", metrics.correct,
                  "/", metrics.tests, ")  mean class accuracy ",
                  FormatPercent(metrics.mean_class_accuracy), " %  k=", run.k, "  spec ",
                  run.descriptor_spec, "\n");
  if (!metrics.fold_accuracy.empty()) {
    absl::StrAppend(&out, "fold accuracy ", FormatPercent(metrics.fold_accuracy_mean),
                    " % \xC2\xB1 ", FormatPercent(metrics.fold_accuracy_std), " %  (",
                    metrics.fold_accuracy.size(), " folds:");
    for (double a : metrics.fold_accuracy) absl::StrAppend(&out, " ", FormatPercent(a));
    out += ")\n";
  }
  absl::StrAppend(&out, "time per cloud ", FormatSeconds(metrics.seconds_per_cloud),
                  " (median call ", FormatSeconds(metrics.median_call_seconds), ")");
  if (run.gallery.empty() && (run.train_samples > 0 || run.train_seconds > 0)) {
    absl::StrAppend(&out, "  training ", run.train_samples, " samples in ",
                    FormatSeconds(run.train_seconds));
  }
  absl::StrAppend(&out, "  testing ", FormatSeconds(run.test_seconds));
  if (!run.learn.empty()) {
    absl::StrAppend(&out, "  head (", run.learn, ") fitted in ", FormatSeconds(run.fit_seconds));
    if (run.head_holdout_rows > 0) {
      absl::StrAppend(&out, ", ",
                      FormatPercent(static_cast<double>(run.head_holdout_right) /
                                    static_cast<double>(run.head_holdout_rows)),
                      " % on held-out training vectors");
    }
  }
  if (!run.failed_files.empty()) absl::StrAppend(&out, "  failed ", run.failed_files.size());
  out += "\n";

  // Per-class table.
  size_t label_width = std::string("overall").size();
  for (const ClassScore& c : metrics.classes)
    label_width = std::max(label_width, DisplayWidth(c.label));
  const size_t tests_width = std::max<size_t>(5, absl::StrCat(metrics.tests).size());
  const auto class_row = [&](absl::string_view label, absl::string_view tests,
                             absl::string_view correct, absl::string_view recall,
                             absl::string_view precision) {
    std::string row =
        absl::StrCat(PadRight(label, label_width), "  ", PadLeft(tests, tests_width), "  ",
                     PadLeft(correct, 7), "  ", PadLeft(recall, 8), "  ", PadLeft(precision, 11));
    absl::StripTrailingAsciiWhitespace(&row);
    return row + "\n";
  };
  absl::StrAppend(&out, "\n", class_row("class", "tests", "correct", "recall %", "precision %"));
  for (const ClassScore& c : metrics.classes) {
    absl::StrAppend(&out, class_row(c.label, absl::StrCat(c.tests), absl::StrCat(c.correct),
                                    FormatPercent(c.recall), FormatPercent(c.precision)));
  }
  absl::StrAppend(&out,
                  class_row("overall", absl::StrCat(metrics.tests), absl::StrCat(metrics.correct),
                            FormatPercent(metrics.accuracy), ""));

  // Confusion matrix: rows are the truth classes only (a label that is never a truth, such as
  // "unknown", has an all-zero row by construction), columns every label.
  const size_t rows = metrics.classes.size();
  const size_t cols = metrics.labels.size();
  if (rows > 0) {
    size_t count_width = 1;
    for (size_t i = 0; i < rows; ++i) {
      for (size_t j = 0; j < cols; ++j) {
        count_width = std::max(count_width, absl::StrCat(metrics.confusion[i][j]).size());
      }
    }
    // Full labels as column headers when they fit, else keys c1..cN with the rows as legend.
    std::vector<size_t> widths(cols);
    size_t row_width = 0, full_width = 0;
    for (size_t j = 0; j < cols; ++j) {
      widths[j] = std::max(count_width, DisplayWidth(metrics.labels[j]));
      full_width += 2 + widths[j];
      if (j < rows) row_width = std::max(row_width, DisplayWidth(metrics.labels[j]));
    }
    const bool keyed = row_width + full_width > kMaxTableWidth;
    std::vector<std::string> headers(cols), row_labels(rows);
    std::string sep = "  ";
    if (keyed) {
      sep = " ";
      const size_t key_width = std::max(count_width, absl::StrCat("c", cols).size());
      const size_t key_label_width = absl::StrCat("c", rows).size();
      row_width = 0;
      for (size_t j = 0; j < cols; ++j) {
        headers[j] = absl::StrCat("c", j + 1);
        widths[j] = key_width;
        if (j < rows) {
          row_labels[j] = absl::StrCat(PadRight(headers[j], key_label_width), " ",
                                       Truncate(metrics.labels[j], kMaxMatrixRowLabel));
          row_width = std::max(row_width, DisplayWidth(row_labels[j]));
        }
      }
    } else {
      headers = metrics.labels;
      row_labels.assign(metrics.labels.begin(), metrics.labels.begin() + rows);
    }
    absl::StrAppend(&out, "\nconfusion matrix (rows: truth, columns: predicted, . = 0)\n",
                    std::string(row_width, ' '));
    for (size_t j = 0; j < cols; ++j) absl::StrAppend(&out, sep, PadLeft(headers[j], widths[j]));
    out += "\n";
    for (size_t i = 0; i < rows; ++i) {
      out += PadRight(row_labels[i], row_width);
      for (size_t j = 0; j < cols; ++j) {
        const uint64_t n = metrics.confusion[i][j];
        absl::StrAppend(&out, sep, PadLeft(n == 0 ? "." : absl::StrCat(n), widths[j]));
      }
      out += "\n";
    }
    // Columns without a row need their own legend line.
    if (keyed) {
      for (size_t j = rows; j < cols; ++j) {
        absl::StrAppend(&out, headers[j], " = ", metrics.labels[j], "\n");
      }
    }
  }

  if (!run.failed_files.empty()) {
    absl::StrAppend(&out, "\nfailed files (", run.failed_files.size(), "):\n");
    const size_t shown = std::min(run.failed_files.size(), kMaxTableFailedFiles);
    for (size_t i = 0; i < shown; ++i) absl::StrAppend(&out, "  ", run.failed_files[i], "\n");
    if (shown < run.failed_files.size()) {
      absl::StrAppend(&out, "  ... and ", run.failed_files.size() - shown,
                      " more (the JSON output lists all)\n");
    }
  }
  return out;
}

std::string FormatEvalJson(const EvalRun& run, const EvalMetrics& metrics, bool with_predictions) {
  const auto strings = [](const std::vector<std::string>& values) {
    std::string out = "[";
    for (size_t i = 0; i < values.size(); ++i) {
      absl::StrAppend(&out, i == 0 ? "" : ",", JsonString(values[i]));
    }
    return out + "]";
  };
  std::string out = absl::StrCat(
      "{\"mode\":", JsonString(run.mode), ",\"dataset\":", JsonString(run.dataset),
      ",\"descriptor_spec\":", JsonString(run.descriptor_spec), ",\"k\":", run.k,
      ",\"folds\":", run.folds, ",\"seed\":", run.seed, ",\"gallery\":", JsonString(run.gallery),
      ",\"started\":", JsonString(run.started), ",\"server\":", JsonString(run.server),
      ",\"client_version\":", JsonString(run.client_version),
      ",\"server_version\":", JsonString(run.server_version), ",\"tests\":", metrics.tests,
      ",\"correct\":", metrics.correct, ",\"accuracy\":", JsonNumber(metrics.accuracy),
      ",\"mean_class_accuracy\":", JsonNumber(metrics.mean_class_accuracy), ",\"fold_accuracy\":[");
  for (size_t i = 0; i < metrics.fold_accuracy.size(); ++i) {
    absl::StrAppend(&out, i == 0 ? "" : ",", JsonNumber(metrics.fold_accuracy[i]));
  }
  absl::StrAppend(&out, "],\"fold_accuracy_mean\":", JsonNumber(metrics.fold_accuracy_mean),
                  ",\"fold_accuracy_std\":", JsonNumber(metrics.fold_accuracy_std),
                  ",\"seconds_per_cloud\":", JsonNumber(metrics.seconds_per_cloud),
                  ",\"median_call_seconds\":", JsonNumber(metrics.median_call_seconds),
                  ",\"train_samples\":", run.train_samples,
                  ",\"train_seconds\":", JsonNumber(run.train_seconds),
                  ",\"test_seconds\":", JsonNumber(run.test_seconds));
  if (!run.learn.empty()) {
    absl::StrAppend(&out, ",\"learn\":", JsonString(run.learn),
                    ",\"fit_seconds\":", JsonNumber(run.fit_seconds),
                    ",\"head_holdout_rows\":", run.head_holdout_rows,
                    ",\"head_holdout_right\":", run.head_holdout_right);
  }
  out += ",\"classes\":[";
  for (size_t i = 0; i < metrics.classes.size(); ++i) {
    const ClassScore& c = metrics.classes[i];
    absl::StrAppend(&out, i == 0 ? "" : ",", "{\"label\":", JsonString(c.label),
                    ",\"tests\":", c.tests, ",\"correct\":", c.correct,
                    ",\"recall\":", JsonNumber(c.recall),
                    ",\"precision\":", JsonNumber(c.precision), "}");
  }
  absl::StrAppend(&out, "],\"labels\":", strings(metrics.labels), ",\"confusion\":[");
  for (size_t i = 0; i < metrics.confusion.size(); ++i) {
    absl::StrAppend(&out, i == 0 ? "[" : ",[");
    for (size_t j = 0; j < metrics.confusion[i].size(); ++j) {
      absl::StrAppend(&out, j == 0 ? "" : ",", metrics.confusion[i][j]);
    }
    out += "]";
  }
  absl::StrAppend(&out, "],\"failed_files\":", strings(run.failed_files));
  if (with_predictions) {
    out += ",\"predictions\":[";
    for (size_t i = 0; i < run.predictions.size(); ++i) {
      const EvalPrediction& p = run.predictions[i];
      absl::StrAppend(
          &out, i == 0 ? "" : ",", "{\"file\":", JsonString(p.file),
          ",\"truth\":", JsonString(p.truth), ",\"predicted\":", JsonString(p.predicted),
          ",\"confidence\":", JsonNumber(p.confidence), ",\"seconds\":", JsonNumber(p.seconds),
          ",\"fold\":", p.fold, ",\"neighbors\":[");
      for (size_t j = 0; j < p.neighbors.size(); ++j) {
        const EvalNeighbor& n = p.neighbors[j];
        absl::StrAppend(&out, j == 0 ? "" : ",", "{\"sample_id\":", n.sample_id,
                        ",\"label\":", JsonString(n.label),
                        ",\"distance\":", JsonNumber(n.distance), ",\"view\":", n.view);
        if (!n.file.empty()) absl::StrAppend(&out, ",\"file\":", JsonString(n.file));
        out += "}";
      }
      out += "]}";
    }
    out += "]";
  }
  out += "}\n";
  return out;
}

std::string FormatEvalCsv(const EvalMetrics& metrics) {
  std::string out = "label,tests,correct,recall,precision\n";
  for (const ClassScore& c : metrics.classes) {
    absl::StrAppend(&out, CsvField(c.label), ",", c.tests, ",", c.correct, ",", CsvNumber(c.recall),
                    ",", CsvNumber(c.precision), "\n");
  }
  // Micro-averaged recall and precision over all predictions both equal the accuracy.
  absl::StrAppend(&out, "__overall__,", metrics.tests, ",", metrics.correct, ",",
                  CsvNumber(metrics.accuracy), ",", CsvNumber(metrics.accuracy), "\n");
  return out;
}

}  // namespace shapeid
