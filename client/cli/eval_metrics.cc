#include "client/cli/eval_metrics.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <set>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
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
constexpr size_t kMaxHtmlRows = 500;

double Ratio(uint64_t part, uint64_t whole) {
  return whole == 0 ? 0.0 : static_cast<double>(part) / static_cast<double>(whole);
}

std::string Percent(double ratio) { return absl::StrFormat("%.2f", 100.0 * ratio); }

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
  absl::StrAppend(&out, "\naccuracy ", Percent(metrics.accuracy), " % (", metrics.correct, "/",
                  metrics.tests, ")  mean class accuracy ", Percent(metrics.mean_class_accuracy),
                  " %  k=", run.k, "  spec ", run.descriptor_spec, "\n");
  if (!metrics.fold_accuracy.empty()) {
    absl::StrAppend(&out, "fold accuracy ", Percent(metrics.fold_accuracy_mean), " % \xC2\xB1 ",
                    Percent(metrics.fold_accuracy_std), " %  (", metrics.fold_accuracy.size(),
                    " folds:");
    for (double a : metrics.fold_accuracy) absl::StrAppend(&out, " ", Percent(a));
    out += ")\n";
  }
  absl::StrAppend(&out, "time per cloud ", FormatSeconds(metrics.seconds_per_cloud),
                  " (median call ", FormatSeconds(metrics.median_call_seconds), ")");
  if (run.train_samples > 0 || run.train_seconds > 0) {
    absl::StrAppend(&out, "  training ", run.train_samples, " samples in ",
                    FormatSeconds(run.train_seconds));
  }
  absl::StrAppend(&out, "  testing ", FormatSeconds(run.test_seconds));
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
                                    Percent(c.recall), Percent(c.precision)));
  }
  absl::StrAppend(&out, class_row("overall", absl::StrCat(metrics.tests),
                                  absl::StrCat(metrics.correct), Percent(metrics.accuracy), ""));

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
      ",\"folds\":", run.folds, ",\"seed\":", run.seed, ",\"tests\":", metrics.tests,
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
                  ",\"test_seconds\":", JsonNumber(run.test_seconds), ",\"classes\":[");
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
      absl::StrAppend(&out, i == 0 ? "" : ",", "{\"file\":", JsonString(p.file),
                      ",\"truth\":", JsonString(p.truth),
                      ",\"predicted\":", JsonString(p.predicted),
                      ",\"confidence\":", JsonNumber(p.confidence),
                      ",\"seconds\":", JsonNumber(p.seconds), ",\"fold\":", p.fold, "}");
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

std::string HtmlEscape(absl::string_view text) {
  std::string out;
  out.reserve(text.size());
  for (char c : text) {
    switch (c) {
      case '&':
        out += "&amp;";
        break;
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '"':
        out += "&quot;";
        break;
      case '\'':
        out += "&#39;";
        break;
      default:
        out += c;
    }
  }
  return out;
}

namespace {

constexpr absl::string_view kHtmlStyle = R"css(
:root{--fg:#1f2937;--muted:#6b7280;--line:#e5e7eb;--bg:#f6f7f9;--card:#fff}
*{box-sizing:border-box}
body{margin:0;padding:24px 32px 48px;color:var(--fg);background:var(--bg);
  font:14px/1.45 system-ui,-apple-system,"Segoe UI",Roboto,Helvetica,Arial,sans-serif}
h1{font-size:22px;margin:0 0 2px}
h2{font-size:16px;margin:32px 0 8px}
.sub,.note{color:var(--muted);margin:0 0 16px;overflow-wrap:anywhere}
.cards{display:flex;flex-wrap:wrap;gap:12px}
.card{background:var(--card);border:1px solid var(--line);border-radius:10px;
  padding:12px 16px;min-width:150px}
.card .k{color:var(--muted);font-size:12px;text-transform:uppercase;letter-spacing:.04em}
.card .v{font-size:26px;font-weight:600;font-variant-numeric:tabular-nums}
.card .s{color:var(--muted);font-size:12px}
.card.bad .v{color:#b91c1c}
table{border-collapse:collapse;background:var(--card)}
.list{border:1px solid var(--line)}
.list th,.list td{padding:4px 12px;border-bottom:1px solid var(--line);text-align:left}
.list th{background:#f9fafb;font-weight:600}
.list td.path{overflow-wrap:anywhere;max-width:640px}
.num{text-align:right!important;font-variant-numeric:tabular-nums}
.rc{white-space:nowrap;font-variant-numeric:tabular-nums}
.rc .pct{display:inline-block;min-width:76px;text-align:right}
.bar{display:inline-block;width:110px;height:8px;border-radius:4px;background:#e5e7eb;
  overflow:hidden;vertical-align:middle}
.bar i{display:block;height:100%}
.scroll{overflow:auto;max-width:100%;border:1px solid var(--line);border-radius:8px;
  background:var(--card);display:inline-block}
.cm{font-variant-numeric:tabular-nums;font-size:12px}
.cm td,.cm th{border:1px solid #eef0f3}
.cm td{min-width:30px;height:26px;padding:0 4px;text-align:center}
.cm th{font-weight:500}
.cm th.col{vertical-align:bottom;padding:6px 2px;height:180px}
.cm th.col span{writing-mode:vertical-rl;transform:rotate(180deg);white-space:nowrap;
  display:inline-block;max-height:170px;overflow:hidden;text-overflow:ellipsis}
.cm th.col.extra span{font-style:italic;color:#b45309}
.cm th.row{text-align:right;padding:0 8px;white-space:nowrap;max-width:280px;overflow:hidden;
  text-overflow:ellipsis}
.cm .tot{color:var(--muted);padding:0 8px;background:#fafafa}
.cm th.corner{font-size:11px;color:var(--muted);vertical-align:bottom;text-align:right;
  padding:6px 8px}
.legend{display:flex;gap:18px;margin:8px 0 0;color:var(--muted);font-size:12px}
.legend span::before{content:"";display:inline-block;width:12px;height:12px;border-radius:2px;
  margin-right:6px;vertical-align:-2px;background:var(--sw)}
dl{display:inline-grid;grid-template-columns:max-content auto;gap:4px 24px;margin:0;
  background:var(--card);border:1px solid var(--line);border-radius:8px;padding:12px 16px}
dt{color:var(--muted)}
dd{margin:0;overflow-wrap:anywhere}
)css";

// Cell colours: green for correct, red for a confusion with another test class, amber for a
// label outside the test classes (a rejection such as "unknown"). The shade is the cell's share
// of its row, with a floor so that a single mistake still shows.
std::string CellStyle(uint64_t count, uint64_t row_total, bool diagonal, bool extra) {
  if (count == 0) return "";
  const double share = Ratio(count, row_total);
  const double alpha = 0.12 + 0.88 * share;
  const char* rgb = diagonal ? "22,163,74" : extra ? "217,119,6" : "220,38,38";
  return absl::StrFormat(" style=\"background:rgba(%s,%.3f)%s\"", rgb, alpha,
                         alpha > 0.55 ? ";color:#fff" : "");
}

std::string Card(absl::string_view key, absl::string_view value, absl::string_view sub,
                 bool bad = false) {
  return absl::StrCat("<div class=\"card", bad ? " bad" : "", "\"><div class=\"k\">", key,
                      "</div><div class=\"v\">", value, "</div><div class=\"s\">", sub,
                      "</div></div>\n");
}

// hsl hue 0 (red) to 120 (green).
std::string RecallBar(double recall) {
  return absl::StrFormat(
      "<span class=\"bar\"><i style=\"width:%.1f%%;background:hsl(%.0f,65%%,45%%)\"></i></span>",
      100.0 * recall, 120.0 * recall);
}

}  // namespace

std::string RenderEvalHtml(const EvalRun& run, const EvalMetrics& metrics) {
  const std::string dataset = HtmlEscape(run.dataset);
  std::string out = absl::StrCat(
      "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n"
      "<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n"
      "<title>shapeid eval \xC2\xB7 ",
      dataset, "</title>\n<style>", kHtmlStyle,
      "</style>\n</head>\n<body>\n<h1>shapeid eval</h1>\n", "<p class=\"sub\">", dataset,
      " \xC2\xB7 ", HtmlEscape(run.mode), " \xC2\xB7 k=", run.k, " \xC2\xB7 ",
      HtmlEscape(run.descriptor_spec), "</p>\n<div class=\"cards\">\n");

  const uint64_t errors = metrics.tests - metrics.correct;
  absl::StrAppend(
      &out,
      Card("accuracy", absl::StrCat(Percent(metrics.accuracy), " %"),
           absl::StrCat(metrics.correct, " of ", metrics.tests, " correct")),
      Card("mean class accuracy", absl::StrCat(Percent(metrics.mean_class_accuracy), " %"),
           absl::StrCat("over ", metrics.classes.size(), " classes")));
  if (!metrics.fold_accuracy.empty()) {
    absl::StrAppend(&out,
                    Card("fold accuracy", absl::StrCat(Percent(metrics.fold_accuracy_mean), " %"),
                         absl::StrCat("\xC2\xB1 ", Percent(metrics.fold_accuracy_std), " % over ",
                                      metrics.fold_accuracy.size(), " folds")));
  }
  absl::StrAppend(&out,
                  Card("time per cloud", FormatSeconds(metrics.seconds_per_cloud),
                       absl::StrCat(FormatSeconds(run.test_seconds), " in total")),
                  Card("training samples", absl::StrCat(run.train_samples),
                       absl::StrCat(FormatSeconds(run.train_seconds), " to train")),
                  Card("errors", absl::StrCat(errors), "misclassified test clouds", errors > 0),
                  Card("failed files", absl::StrCat(run.failed_files.size()),
                       "could not be read or classified", !run.failed_files.empty()),
                  "</div>\n");

  // Per-class table.
  absl::StrAppend(&out,
                  "<h2>Per class</h2>\n<table class=\"list\">\n<thead><tr><th>class</th>"
                  "<th class=\"num\">tests</th><th class=\"num\">correct</th><th>recall</th>"
                  "<th class=\"num\">precision</th></tr></thead>\n<tbody>\n");
  for (const ClassScore& c : metrics.classes) {
    absl::StrAppend(&out, "<tr><td>", HtmlEscape(c.label), "</td><td class=\"num\">", c.tests,
                    "</td><td class=\"num\">", c.correct, "</td><td class=\"rc\">",
                    RecallBar(c.recall), "<span class=\"pct\">", Percent(c.recall),
                    " %</span></td><td class=\"num\">", Percent(c.precision), " %</td></tr>\n");
  }
  absl::StrAppend(&out, "</tbody>\n</table>\n");

  // Confusion matrix, truth rows only (see FormatEvalTable).
  const size_t rows = metrics.classes.size();
  const size_t cols = metrics.labels.size();
  absl::StrAppend(&out,
                  "<h2>Confusion matrix</h2>\n<p class=\"note\">Rows are the true classes, "
                  "columns the predicted labels; a cell's shade is its share of the row. "
                  "Hover a cell or header for details.</p>\n");
  if (rows > 0) {
    absl::StrAppend(&out,
                    "<div class=\"scroll\"><table class=\"cm\">\n<thead><tr>"
                    "<th class=\"corner\">truth \xE2\x86\x93 / predicted \xE2\x86\x92</th>");
    for (size_t j = 0; j < cols; ++j) {
      const std::string label = HtmlEscape(metrics.labels[j]);
      absl::StrAppend(&out, "<th class=\"col", j >= rows ? " extra" : "", "\" title=\"", label,
                      "\"><span>", label, "</span></th>");
    }
    absl::StrAppend(&out, "<th class=\"col\"><span>total</span></th></tr></thead>\n<tbody>\n");
    for (size_t i = 0; i < rows; ++i) {
      const std::string truth = HtmlEscape(metrics.labels[i]);
      const uint64_t total = metrics.classes[i].tests;
      absl::StrAppend(&out, "<tr><th class=\"row\" title=\"", truth, "\">", truth, "</th>");
      for (size_t j = 0; j < cols; ++j) {
        const uint64_t n = metrics.confusion[i][j];
        absl::StrAppend(&out, "<td class=\"cm-cell\"", CellStyle(n, total, i == j, j >= rows));
        if (n > 0) {
          absl::StrAppend(&out, " title=\"", truth, " \xE2\x86\x92 ", HtmlEscape(metrics.labels[j]),
                          ": ", n, " of ", total, " (", Percent(Ratio(n, total)), " %)\">", n);
        } else {
          out += ">";
        }
        out += "</td>";
      }
      absl::StrAppend(&out, "<td class=\"tot\">", total, "</td></tr>\n");
    }
    absl::StrAppend(&out, "<tr><th class=\"row\">predicted total</th>");
    for (size_t j = 0; j < cols; ++j) {
      uint64_t n = 0;
      for (size_t i = 0; i < rows; ++i) n += metrics.confusion[i][j];
      absl::StrAppend(&out, "<td class=\"tot\">", n, "</td>");
    }
    absl::StrAppend(&out, "<td class=\"tot\">", metrics.tests,
                    "</td></tr>\n</tbody>\n</table></div>\n<div class=\"legend\">"
                    "<span style=\"--sw:rgb(22,163,74)\">correct</span>"
                    "<span style=\"--sw:rgb(220,38,38)\">confused with another class</span>"
                    "<span style=\"--sw:rgb(217,119,6)\">label outside the test classes</span>"
                    "</div>\n");
  } else {
    out += "<p class=\"note\">No predictions.</p>\n";
  }

  // Misclassified files, grouped by truth then prediction so that one confusion reads as a block.
  std::vector<const EvalPrediction*> wrong;
  for (const EvalPrediction& p : run.predictions) {
    if (p.truth != p.predicted) wrong.push_back(&p);
  }
  std::stable_sort(wrong.begin(), wrong.end(),
                   [](const EvalPrediction* a, const EvalPrediction* b) {
                     return std::tie(a->truth, a->predicted) < std::tie(b->truth, b->predicted);
                   });
  absl::StrAppend(&out, "<h2>Misclassified files (", wrong.size(), ")</h2>\n");
  if (!wrong.empty()) {
    absl::StrAppend(&out,
                    "<table class=\"list\">\n<thead><tr><th>file</th><th>truth</th>"
                    "<th>predicted</th><th class=\"num\">confidence</th></tr></thead>\n<tbody>\n");
    const size_t shown = std::min(wrong.size(), kMaxHtmlRows);
    for (size_t i = 0; i < shown; ++i) {
      const EvalPrediction& p = *wrong[i];
      absl::StrAppend(&out, "<tr><td class=\"path\">", HtmlEscape(p.file), "</td><td>",
                      HtmlEscape(p.truth), "</td><td>", HtmlEscape(p.predicted),
                      "</td><td class=\"num\">", absl::StrFormat("%.2f", p.confidence),
                      "</td></tr>\n");
    }
    out += "</tbody>\n</table>\n";
    if (shown < wrong.size()) {
      absl::StrAppend(&out, "<p class=\"note\">Showing the first ", shown, " of ", wrong.size(),
                      "; the JSON output with predictions lists all.</p>\n");
    }
  }

  absl::StrAppend(&out, "<h2>Failed files (", run.failed_files.size(), ")</h2>\n");
  if (!run.failed_files.empty()) {
    out += "<table class=\"list\">\n<tbody>\n";
    const size_t shown = std::min(run.failed_files.size(), kMaxHtmlRows);
    for (size_t i = 0; i < shown; ++i) {
      absl::StrAppend(&out, "<tr><td class=\"path\">", HtmlEscape(run.failed_files[i]),
                      "</td></tr>\n");
    }
    out += "</tbody>\n</table>\n";
    if (shown < run.failed_files.size()) {
      absl::StrAppend(&out, "<p class=\"note\">Showing the first ", shown, " of ",
                      run.failed_files.size(), ".</p>\n");
    }
  }

  absl::StrAppend(&out, "<h2>Parameters</h2>\n<dl>\n<dt>mode</dt><dd>", HtmlEscape(run.mode),
                  "</dd>\n<dt>dataset</dt><dd>", dataset, "</dd>\n<dt>descriptor spec</dt><dd>",
                  HtmlEscape(run.descriptor_spec), "</dd>\n<dt>k</dt><dd>", run.k, "</dd>\n");
  if (run.mode == "kfold") {
    absl::StrAppend(&out, "<dt>folds</dt><dd>", run.folds, "</dd>\n<dt>seed</dt><dd>", run.seed,
                    "</dd>\n");
  }
  absl::StrAppend(&out, "<dt>training samples</dt><dd>", run.train_samples,
                  "</dd>\n<dt>training time</dt><dd>", FormatSeconds(run.train_seconds),
                  "</dd>\n<dt>testing time</dt><dd>", FormatSeconds(run.test_seconds),
                  "</dd>\n<dt>test clouds</dt><dd>", metrics.tests,
                  "</dd>\n</dl>\n</body>\n</html>\n");
  return out;
}

}  // namespace shapeid
