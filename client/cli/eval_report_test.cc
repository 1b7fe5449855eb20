#include "client/cli/eval_report.h"

#include <string>

#include "client/cli/eval_metrics.h"
#include "client/cli/eval_testing.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"

namespace shapeid {
namespace {

using ::shapeid::eval_testing::Add;
using ::shapeid::eval_testing::CountOf;
using ::shapeid::eval_testing::ThreeClassRun;
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
  EXPECT_THAT(page, HasSubstr("rgba(217,119,6,"));  // the rejection colour
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

TEST(EvalReportTest, HtmlCapsTheErrorList) {
  EvalRun run;
  for (int i = 0; i < 620; ++i) Add(run, "a", "b");
  const std::string html = RenderEvalHtml(run, ComputeEvalMetrics(run));
  EXPECT_EQ(CountOf(html, "<td class=\"path\">"), 500u);
  EXPECT_THAT(html, HasSubstr("Showing the first 500 of 620"));
}

}  // namespace
}  // namespace shapeid
