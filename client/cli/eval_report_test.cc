#include "client/cli/eval_report.h"

#include <string>
#include <vector>

#include "client/cli/eval_metrics.h"
#include "client/cli/eval_testing.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"

namespace shapeid {
namespace {

using ::shapeid::eval_testing::Add;
using ::shapeid::eval_testing::CountOf;
using ::shapeid::eval_testing::ThreeClassRun;
using ::testing::AllOf;
using ::testing::EndsWith;
using ::testing::HasSubstr;
using ::testing::Not;
using ::testing::StartsWith;

TEST(EvalReportTest, HtmlEscapesEverything) {
  EXPECT_EQ(HtmlEscape("<script>alert(1)</script>"), "&lt;script&gt;alert(1)&lt;/script&gt;");
  EXPECT_EQ(HtmlEscape("a&b\"c'"), "a&amp;b&quot;c&#39;");
  EXPECT_EQ(HtmlEscape("caf\xC3\xA9"), "caf\xC3\xA9");

  EvalRun run = ThreeClassRun();
  run.dataset = "<script>";
  run.descriptor_spec = "a&b\"c'";
  Add(run, "<script>", "a&b\"c'");
  Add(run, "<script>", "<script>");
  run.predictions.back().file = "<img src=x onerror=alert(1)>.pcd";
  run.failed_files = {"</td><script>.pcd"};
  const std::string html = RenderEvalHtml(run, ComputeEvalMetrics(run));
  EXPECT_THAT(html, StartsWith("<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n"
                               "<meta charset=\"utf-8\">"));
  EXPECT_THAT(html, EndsWith("</html>\n"));
  EXPECT_THAT(html, Not(HasSubstr("<script")));
  EXPECT_THAT(html, Not(HasSubstr("<img")));
  EXPECT_THAT(html, Not(HasSubstr("a&b")));
  EXPECT_THAT(html, Not(HasSubstr("http")));  // nothing to fetch
  EXPECT_THAT(html, HasSubstr("&lt;script&gt;"));
  EXPECT_THAT(html, HasSubstr("a&amp;b&quot;c&#39;"));
  EXPECT_THAT(html, HasSubstr("&lt;/td&gt;&lt;script&gt;.pcd"));
}

TEST(EvalReportTest, HtmlHasOneGridCellPerMatrixEntry) {
  const EvalRun run = ThreeClassRun();
  const EvalMetrics m = ComputeEvalMetrics(run);
  const std::string html = RenderEvalHtml(run, m);
  EXPECT_EQ(CountOf(html, "class=\"cm-cell\""), 9u);
  // Diagonal green, confusions red; shade grows with the share of the row.
  EXPECT_THAT(html,
              HasSubstr("<td class=\"cm-cell\" style=\"background:rgba(22,163,74,0.780);"
                        "color:#fff\" title=\"bench \xE2\x86\x92 bench: 3 of 4 (75.00 %)\">3"));
  EXPECT_THAT(html, HasSubstr("<td class=\"cm-cell\" style=\"background:rgba(220,38,38,0.340)\" "
                              "title=\"bench \xE2\x86\x92 chair: 1 of 4 (25.00 %)\">1"));
  EXPECT_THAT(html, HasSubstr("<h2>Misclassified files (3)</h2>"));
  EXPECT_THAT(html, HasSubstr("<td class=\"path\">bench/3.pcd</td><td>bench</td><td>chair</td>"));

  // With rejections: rows stay the truth classes, every label gets a column.
  EvalRun with_unknown = run;
  Add(with_unknown, "chair", "unknown");
  const EvalMetrics mu = ComputeEvalMetrics(with_unknown);
  const std::string page = RenderEvalHtml(with_unknown, mu);
  EXPECT_EQ(CountOf(page, "class=\"cm-cell\""), mu.classes.size() * mu.labels.size());
  EXPECT_EQ(CountOf(page, "<th class=\"col extra\""), 1u);
  EXPECT_THAT(page, HasSubstr("rgba(217,119,6,"));  // the rejection color
}

TEST(EvalReportTest, EmptyRunSaysNoPredictions) {
  EvalRun run;
  run.mode = "kfold";
  run.test_seconds = 1.0;
  run.failed_files = {"bad.pcd"};
  const std::string html = RenderEvalHtml(run, ComputeEvalMetrics(run));
  EXPECT_THAT(html, HasSubstr("No predictions."));
  EXPECT_EQ(CountOf(html, "class=\"cm-cell\""), 0u);
}

TEST(EvalReportTest, HtmlCapsTheErrorListAndThePictures) {
  EvalRun run;
  for (int i = 0; i < 620; ++i) Add(run, "a", "b");
  int asked = 0;
  const std::string html = RenderEvalHtml(run, ComputeEvalMetrics(run), [&](const EvalPrediction&) {
    ++asked;
    return ErrorPictures{"png", "", "", "gone"};
  });
  EXPECT_EQ(CountOf(html, "<tr id=\"e"), 500u);
  EXPECT_THAT(html, HasSubstr("Showing the first 500 of 620"));
  EXPECT_EQ(asked, 50);
  EXPECT_EQ(CountOf(html, "<div class=\"pair\""), 50u);
  EXPECT_THAT(html, HasSubstr("The first 50 of 620 errors"));
  EXPECT_THAT(html, HasSubstr("<tr id=\"e50\"><td class=\"num\"><a href=\"#p50\">50</a>"));
  EXPECT_THAT(html, HasSubstr("<tr id=\"e51\"><td class=\"num\">51</td>"));
  // No source, no pictures.
  EXPECT_EQ(CountOf(RenderEvalHtml(run, ComputeEvalMetrics(run)), "class=\"pair\""), 0u);
}

// A run against a server's gallery, one error traced to its neighbors.
EvalRun GalleryRun() {
  EvalRun run;
  run.mode = "gallery";
  run.dataset = "scans";
  run.gallery = "mn10";
  run.train_samples = 3991;
  run.descriptor_spec = "rphsd:bins=8";
  run.k = 1;
  run.started = "2026-11-28T15:05:00Z";
  run.server = "recognizer:50051";
  run.client_version = "0.12.0";
  run.server_version = "0.11.0";
  Add(run, "chair", "chair");
  Add(run, "chair", "table");
  run.predictions.back().confidence = 1.0;
  run.predictions.back().neighbors = {{4711, "table", 0.1234567, 0, "/data/train/table/7.pcd"},
                                      {12, "chair", 0.5, 2, ""}};
  return run;
}

TEST(EvalReportTest, HeaderSaysWhatRanWhereAndWhen) {
  const EvalRun run = GalleryRun();
  const std::string html = RenderEvalHtml(run, ComputeEvalMetrics(run));
  EXPECT_THAT(html,
              HasSubstr("<dl class=\"head\">\n<dt>dataset</dt><dd>scans</dd>\n"
                        "<dt>mode</dt><dd>against an existing gallery</dd>\n"
                        "<dt>gallery</dt><dd>mn10 (3991 samples)</dd>\n"
                        "<dt>descriptor spec</dt><dd>rphsd:bins=8</dd>\n<dt>k</dt><dd>1</dd>\n"
                        "<dt>started</dt><dd>2026-11-28T15:05:00Z</dd>\n"
                        "<dt>server</dt><dd>recognizer:50051</dd>\n"
                        "<dt>shapeid</dt><dd>client 0.12.0, server 0.11.0</dd>\n</dl>"));
  EXPECT_THAT(html, HasSubstr("<div class=\"k\">gallery samples</div><div class=\"v\">3991</div>"
                              "<div class=\"s\">in mn10</div>"));
  EXPECT_THAT(html, Not(HasSubstr("training samples")));

  EvalRun unknown = run;
  unknown.server_version.clear();
  EXPECT_THAT(RenderEvalHtml(unknown, ComputeEvalMetrics(unknown)),
              HasSubstr("<dd>client 0.12.0, server unknown (it did not say)</dd>"));

  EvalRun local = ThreeClassRun();
  local.client_version = "0.12.0";
  local.mode = "kfold";
  local.folds = 5;
  local.seed = 7;
  const std::string page = RenderEvalHtml(local, ComputeEvalMetrics(local));
  EXPECT_THAT(page, AllOf(HasSubstr("<dd>stratified 5-fold cross-validation, seed 7</dd>"),
                          HasSubstr("<dd>a fresh in-process gallery per round</dd>"),
                          HasSubstr("<dt>server</dt><dd>in-process (--local)</dd>"),
                          HasSubstr("<dt>shapeid</dt><dd>client 0.12.0</dd>"),
                          HasSubstr("<dt>started</dt><dd>unknown</dd>"),
                          HasSubstr("<div class=\"k\">training samples</div>")));
  local.server = "localhost:1";
  EXPECT_THAT(RenderEvalHtml(local, ComputeEvalMetrics(local)),
              HasSubstr("<dd>a fresh temporary gallery per round (deleted after)</dd>"));
}

TEST(EvalReportTest, ErrorRowsNameTheNearestSampleAndConfidenceOnlyAboveKOne) {
  EvalRun run = GalleryRun();
  const std::string k1 = RenderEvalHtml(run, ComputeEvalMetrics(run));
  EXPECT_THAT(k1, Not(HasSubstr("confidence</th>")));
  EXPECT_THAT(k1, HasSubstr("so there is no confidence column"));
  EXPECT_THAT(k1, HasSubstr("<tr id=\"e1\"><td class=\"num\">1</td><td class=\"path\">chair/1.pcd"
                            "</td><td>chair</td><td>table</td><td class=\"path\">"
                            "/data/train/table/7.pcd</td><td>table</td><td class=\"num\">0.1235"
                            "</td><td class=\"num\">4711</td></tr>"));

  run.k = 3;
  const std::string k3 = RenderEvalHtml(run, ComputeEvalMetrics(run));
  EXPECT_THAT(k3, HasSubstr("<th class=\"num\">confidence</th>"));
  EXPECT_THAT(k3, HasSubstr("<td>table</td><td class=\"num\">1.00</td><td class=\"path\">/data/"));

  // A neighbor without a file, and a prediction without neighbors.
  run.predictions.back().neighbors.erase(run.predictions.back().neighbors.begin());
  Add(run, "chair", "unknown");
  const std::string sparse = RenderEvalHtml(run, ComputeEvalMetrics(run));
  EXPECT_THAT(sparse, HasSubstr("<td class=\"path\"><span class=\"muted\">not recorded by the "
                                "gallery</span></td><td>chair</td><td class=\"num\">0.5</td>"
                                "<td class=\"num\">12 (view 2)</td></tr>"));
  EXPECT_THAT(sparse, HasSubstr("<td class=\"path\">no neighbor</td><td></td><td class=\"num\">"
                                "</td><td class=\"num\"></td></tr>"));
}

TEST(EvalReportTest, PicturesAreEmbeddedOrSayWhyNot) {
  EvalRun run = GalleryRun();
  run.predictions.back().file = "<b>.pcd";
  std::vector<std::string> asked;
  const std::string html =
      RenderEvalHtml(run, ComputeEvalMetrics(run), [&](const EvalPrediction& p) {
        asked.push_back(p.file);
        return ErrorPictures{"\x89PNG", "", "", "cannot <read> it"};
      });
  EXPECT_EQ(asked, std::vector<std::string>{"<b>.pcd"});  // errors only
  EXPECT_THAT(html, HasSubstr("<a href=\"#p1\">1</a>"));
  EXPECT_THAT(html, HasSubstr("<div class=\"pair\" id=\"p1\">"));
  EXPECT_THAT(html, HasSubstr("<a href=\"#e1\">#1</a> test cloud, truth <b>chair</b>, predicted "
                              "<b>table</b><br>&lt;b&gt;.pcd</p><img class=\"cloud\" "
                              "src=\"data:image/png;base64,iVBORw==\" alt=\"the test cloud\">"));
  EXPECT_THAT(html,
              HasSubstr("nearest training sample 4711 \xC2\xB7 table \xC2\xB7 distance 0.1235<br>"
                        "/data/train/table/7.pcd</p><div class=\"missing\">cannot &lt;read&gt; "
                        "it</div>"));
  EXPECT_THAT(html, Not(HasSubstr("http")));
}

}  // namespace
}  // namespace shapeid
