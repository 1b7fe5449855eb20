#include "client/cli/eval_report.h"

#include <algorithm>
#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "absl/status/statusor.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "client/cli/cli_common.h"
#include "client/cli/cloud_picture.h"
#include "client/cli/input_files.h"

namespace shapeid {

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

// Long lists are cut so that a bad run does not bury the figures (the JSON has everything).
constexpr size_t kMaxHtmlRows = 500;

double Ratio(uint64_t part, uint64_t whole) {
  return whole == 0 ? 0.0 : static_cast<double>(part) / static_cast<double>(whole);
}

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
dl.head{display:grid;max-width:980px;margin:8px 0 18px}
.errors td{white-space:nowrap}
.errors td.path{white-space:normal;min-width:240px;max-width:420px}
.muted{color:var(--muted)}
.pairs{display:flex;flex-direction:column;gap:14px}
.pair{display:flex;flex-wrap:wrap;gap:16px;background:var(--card);border:1px solid var(--line);
  border-radius:10px;padding:10px 14px}
.pic{width:400px}
.pic .cap{font-size:12px;margin:0 0 6px;overflow-wrap:anywhere;min-height:52px}
.pic img{display:block;image-rendering:pixelated}
.missing{width:300px;height:96px;display:flex;align-items:center;padding:8px;font-size:12px;
  color:#92400e;background:#fffbeb;border:1px dashed #f59e0b;overflow-wrap:anywhere}
)css";

// Cell colors: green for correct, red for a confusion with another test class, amber for a
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

// What was evaluated, against what, when, where and with which software.
std::string RunHeader(const EvalRun& run) {
  std::string mode = HtmlEscape(run.mode);
  if (run.mode == "holdout") {
    mode = "hold-out (train on DIR/&lt;label&gt;/train, test DIR/&lt;label&gt;/test)";
  } else if (run.mode == "kfold") {
    mode = absl::StrCat("stratified ", run.folds, "-fold cross-validation, seed ", run.seed);
  } else if (run.mode == "gallery") {
    mode = "against an existing gallery";
  }
  const std::string gallery =
      !run.gallery.empty()
          ? absl::StrCat(HtmlEscape(run.gallery), " (", run.train_samples, " samples)")
      : run.server.empty() ? std::string("a fresh in-process gallery per round")
                           : std::string("a fresh temporary gallery per round (deleted after)");
  const std::string server =
      run.server.empty() ? std::string("in-process (--local)") : HtmlEscape(run.server);
  std::string versions = absl::StrCat("client ", HtmlEscape(run.client_version));
  if (!run.server.empty()) {
    absl::StrAppend(&versions, ", server ",
                    run.server_version.empty() ? std::string("unknown (it did not say)")
                                               : HtmlEscape(run.server_version));
  }
  return absl::StrCat("<dl class=\"head\">\n<dt>dataset</dt><dd>", HtmlEscape(run.dataset),
                      "</dd>\n<dt>mode</dt><dd>", mode, "</dd>\n<dt>gallery</dt><dd>", gallery,
                      "</dd>\n<dt>descriptor spec</dt><dd>", HtmlEscape(run.descriptor_spec),
                      "</dd>\n<dt>k</dt><dd>", run.k, "</dd>\n<dt>started</dt><dd>",
                      run.started.empty() ? "unknown" : HtmlEscape(run.started),
                      "</dd>\n<dt>server</dt><dd>", server, "</dd>\n<dt>shapeid</dt><dd>", versions,
                      "</dd>\n</dl>\n");
}

// A picture, or why there is none.
std::string PictureOrReason(const std::string& png, const std::string& missing,
                            absl::string_view alt) {
  if (png.empty()) return absl::StrCat("<div class=\"missing\">", HtmlEscape(missing), "</div>");
  return absl::StrCat("<img class=\"cloud\" src=\"", PngDataUri(png), "\" alt=\"", alt, "\">");
}

// The nearest training sample, as the error table and the pictures name it.
std::string NeighborCaption(const EvalNeighbor& n) {
  std::string caption = absl::StrCat("sample ", n.sample_id, " \xC2\xB7 ", HtmlEscape(n.label),
                                     " \xC2\xB7 distance ", absl::StrFormat("%.4g", n.distance));
  if (n.view != 0) absl::StrAppend(&caption, " \xC2\xB7 its synthetic view ", n.view);
  return caption;
}

std::string TrainingFile(const EvalNeighbor& n) {
  return n.file.empty() ? "<span class=\"muted\">not recorded by the gallery</span>"
                        : HtmlEscape(n.file);
}

// The error table and, for its first kMaxErrorPictures rows, the pictures.
std::string ErrorSections(const EvalRun& run, const ErrorPictureSource& pictures) {
  const std::vector<const EvalPrediction*> wrong = ReportErrors(run);
  std::string out = absl::StrCat("<h2>Misclassified files (", wrong.size(), ")</h2>\n");
  if (wrong.empty()) return out;
  // At k = 1 the winner's vote share is 1 by construction; the nearest distance, always
  // shown, is what tells a close match from a far one, so the share column goes.
  const bool show_confidence = run.k > 1;
  const size_t pictured = pictures ? std::min(wrong.size(), kMaxErrorPictures) : 0;
  absl::StrAppend(
      &out,
      "<p class=\"note\">Each error names the training sample nearest to the test cloud: its "
      "id, label, descriptor distance and the training file it was made from. ",
      show_confidence
          ? "Confidence is the predicted label's share of the k neighbors' vote."
          : "With k = 1 the nearest sample alone decides (its share of the vote is always 1), "
            "so there is no confidence column: the distance says how close the match was.",
      pictured > 0 ? " The numbers link to the pictures below." : "",
      "</p>\n<div class=\"scroll\"><table class=\"list errors\">\n<thead><tr>"
      "<th class=\"num\">#</th><th>file</th>"
      "<th>truth</th><th>predicted</th>",
      show_confidence ? "<th class=\"num\">confidence</th>" : "",
      "<th>nearest training file</th><th>its label</th><th class=\"num\">distance</th>"
      "<th class=\"num\">sample id</th></tr></thead>\n<tbody>\n");
  const size_t shown = std::min(wrong.size(), kMaxHtmlRows);
  for (size_t i = 0; i < shown; ++i) {
    const EvalPrediction& p = *wrong[i];
    const std::string number = i < pictured
                                   ? absl::StrCat("<a href=\"#p", i + 1, "\">", i + 1, "</a>")
                                   : absl::StrCat(i + 1);
    absl::StrAppend(&out, "<tr id=\"e", i + 1, "\"><td class=\"num\">", number,
                    "</td><td class=\"path\">", HtmlEscape(p.file), "</td><td>",
                    HtmlEscape(p.truth), "</td><td>", HtmlEscape(p.predicted), "</td>");
    if (show_confidence) {
      absl::StrAppend(&out, "<td class=\"num\">", absl::StrFormat("%.2f", p.confidence), "</td>");
    }
    if (p.neighbors.empty()) {
      out +=
          "<td class=\"path\">no neighbor</td><td></td><td class=\"num\"></td>"
          "<td class=\"num\"></td></tr>\n";
      continue;
    }
    const EvalNeighbor& n = p.neighbors[0];
    absl::StrAppend(&out, "<td class=\"path\">", TrainingFile(n), "</td><td>", HtmlEscape(n.label),
                    "</td><td class=\"num\">", absl::StrFormat("%.4g", n.distance),
                    "</td><td class=\"num\">", n.sample_id,
                    n.view != 0 ? absl::StrCat(" (view ", n.view, ")") : "", "</td></tr>\n");
  }
  out += "</tbody>\n</table></div>\n";
  if (shown < wrong.size()) {
    absl::StrAppend(&out, "<p class=\"note\">Showing the first ", shown, " of ", wrong.size(),
                    "; the JSON output with predictions lists all.</p>\n");
  }
  if (pictured == 0) return out;

  absl::StrAppend(&out,
                  "<h2>Pictures of the errors</h2>\n<p class=\"note\">Each misclassified test "
                  "cloud beside the training sample nearest to it, each seen from the front, the "
                  "side and the top (darker points are nearer). The first ",
                  pictured, " of ", wrong.size(), " errors, in the order of the table.</p>\n",
                  "<div class=\"pairs\">\n");
  for (size_t i = 0; i < pictured; ++i) {
    const EvalPrediction& p = *wrong[i];
    const ErrorPictures pics = pictures(p);
    absl::StrAppend(&out, "<div class=\"pair\" id=\"p", i + 1,
                    "\">\n<div class=\"pic\"><p class=\"cap\"><a href=\"#e", i + 1, "\">#", i + 1,
                    "</a> test cloud, truth <b>", HtmlEscape(p.truth), "</b>, predicted <b>",
                    HtmlEscape(p.predicted), "</b><br>", HtmlEscape(p.file), "</p>",
                    PictureOrReason(pics.test_png, pics.test_missing, "the test cloud"),
                    "</div>\n<div class=\"pic\"><p class=\"cap\">nearest training ");
    if (p.neighbors.empty()) {
      absl::StrAppend(&out, "sample: none</p>");
    } else {
      absl::StrAppend(&out, NeighborCaption(p.neighbors[0]), "<br>", TrainingFile(p.neighbors[0]),
                      "</p>");
    }
    absl::StrAppend(
        &out,
        PictureOrReason(pics.neighbor_png, pics.neighbor_missing, "the nearest training sample"),
        "</div>\n</div>\n");
  }
  out += "</div>\n";
  return out;
}

}  // namespace

std::vector<const EvalPrediction*> ReportErrors(const EvalRun& run) {
  std::vector<const EvalPrediction*> wrong;
  for (const EvalPrediction& p : run.predictions) {
    if (p.truth != p.predicted) wrong.push_back(&p);
  }
  std::stable_sort(wrong.begin(), wrong.end(),
                   [](const EvalPrediction* a, const EvalPrediction* b) {
                     return std::tie(a->truth, a->predicted) < std::tie(b->truth, b->predicted);
                   });
  return wrong;
}

ErrorPictureSource ErrorPicturesFromFiles(const ReadOptions& read) {
  ReadOptions options = read;
  options.drop_non_finite = true;  // the pictures skip them anyway; a cloud with holes still shows
  // Training files by path: (PNG, why none). Nearest samples repeat across errors.
  auto training = std::make_shared<std::map<std::string, std::pair<std::string, std::string>>>();
  return [options, training](const EvalPrediction& p) {
    ErrorPictures out;
    absl::StatusOr<ReadResult> test = ReadInputCloud(p.file, options);
    if (test.ok()) {
      out.test_png = EncodePng(RenderCloudViews(test->cloud));
    } else {
      out.test_missing = absl::StrCat("No picture: ", test.status().message());
    }
    if (p.neighbors.empty()) {
      out.neighbor_missing = "No picture: the classifier named no neighbor.";
      return out;
    }
    const EvalNeighbor& n = p.neighbors[0];
    if (n.file.empty()) {
      out.neighbor_missing =
          absl::StrCat("No picture: the gallery does not record which file sample ", n.sample_id,
                       " was trained from.");
      return out;
    }
    auto [it, inserted] = training->try_emplace(n.file);
    if (inserted) {
      absl::StatusOr<ReadResult> cloud = ReadInputCloud(n.file, options);
      if (cloud.ok()) {
        it->second.first = EncodePng(RenderCloudViews(cloud->cloud));
      } else {
        it->second.second = absl::StrCat(
            "No picture: the training file of sample ", n.sample_id, " (", n.file,
            ") cannot be read here; it may have been trained on another machine or from "
            "another folder. ",
            cloud.status().message());
      }
    }
    out.neighbor_png = it->second.first;
    out.neighbor_missing = it->second.second;
    return out;
  };
}

std::string RenderEvalHtml(const EvalRun& run, const EvalMetrics& metrics,
                           const ErrorPictureSource& pictures) {
  const std::string dataset = HtmlEscape(run.dataset);
  std::string out = absl::StrCat(
      "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n"
      "<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n"
      "<title>shapeid eval \xC2\xB7 ",
      dataset, "</title>\n<style>", kHtmlStyle,
      "</style>\n</head>\n<body>\n<h1>shapeid eval</h1>\n", RunHeader(run),
      "<div class=\"cards\">\n");

  const uint64_t errors = metrics.tests - metrics.correct;
  absl::StrAppend(
      &out,
      Card("accuracy", absl::StrCat(FormatPercent(metrics.accuracy), " %"),
           absl::StrCat(metrics.correct, " of ", metrics.tests, " correct")),
      Card("mean class accuracy", absl::StrCat(FormatPercent(metrics.mean_class_accuracy), " %"),
           absl::StrCat("over ", metrics.classes.size(), " classes")));
  if (!metrics.fold_accuracy.empty()) {
    absl::StrAppend(
        &out, Card("fold accuracy", absl::StrCat(FormatPercent(metrics.fold_accuracy_mean), " %"),
                   absl::StrCat("\xC2\xB1 ", FormatPercent(metrics.fold_accuracy_std), " % over ",
                                metrics.fold_accuracy.size(), " folds")));
  }
  absl::StrAppend(&out,
                  Card("time per cloud", FormatSeconds(metrics.seconds_per_cloud),
                       absl::StrCat(FormatSeconds(run.test_seconds), " in total")),
                  run.gallery.empty()
                      ? Card("training samples", absl::StrCat(run.train_samples),
                             absl::StrCat(FormatSeconds(run.train_seconds), " to train"))
                      : Card("gallery samples", absl::StrCat(run.train_samples),
                             absl::StrCat("in ", HtmlEscape(run.gallery))),
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
                    RecallBar(c.recall), "<span class=\"pct\">", FormatPercent(c.recall),
                    " %</span></td><td class=\"num\">", FormatPercent(c.precision),
                    " %</td></tr>\n");
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
                          ": ", n, " of ", total, " (", FormatPercent(Ratio(n, total)), " %)\">",
                          n);
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

  out += ErrorSections(run, pictures);

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

  // The run's identity is in the header; what remains is its cost.
  absl::StrAppend(&out, "<h2>Timings</h2>\n<dl>\n<dt>",
                  run.gallery.empty() ? "training samples" : "gallery samples", "</dt><dd>",
                  run.train_samples, "</dd>\n<dt>training time</dt><dd>",
                  FormatSeconds(run.train_seconds), "</dd>\n<dt>testing time</dt><dd>",
                  FormatSeconds(run.test_seconds), "</dd>\n<dt>test clouds</dt><dd>", metrics.tests,
                  "</dd>\n</dl>\n</body>\n</html>\n");
  return out;
}

}  // namespace shapeid
