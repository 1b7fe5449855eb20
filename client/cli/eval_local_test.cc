// `shapeid eval --local`: the evaluation in this process, no server anywhere. Hold-out and
// k-fold on a small labeled folder, every output format, answers that do not depend on the
// number of threads, bad files counted, and the usage errors.

#include "client/cli/eval_local.h"

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <regex>
#include <string>

#include "client/cli/cli_testing.h"
#include "client/cli/eval_command.h"
#include "client/cli/eval_report.h"
#include "client/cli/eval_testing.h"
#include "core/io/pcd_writer.h"
#include "core/testing/test_clouds.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"

namespace shapeid {
namespace {

namespace fs = std::filesystem;
using cli_testing::Captured;
using eval_testing::CountOf;
using ::testing::AllOf;
using ::testing::HasSubstr;
using ::testing::MatchesRegex;
using ::testing::Not;
using ::testing::StartsWith;

// Eval's JSON without what the clock decides: the timings and the start time, which moves on
// when two runs straddle a second.
std::string WithoutClock(const std::string& json) {
  static const std::regex kStarted(R"re("started":"[^"]*")re");
  return std::regex_replace(cli_testing::WithoutTimes(json), kStarted, "\"started\":\"\"");
}

class EvalLocalTest : public ::testing::Test {
 protected:
  void SetUp() override { root_ = cli_testing::ScratchDir("eval_local"); }
  void TearDown() override { fs::remove_all(root_); }

  // Nothing listens at this address: a local evaluation must not need it.
  CliContext Context(Captured& out, OutputFormat format = OutputFormat::kJson) {
    CliContext context;
    context.out = out.get();
    context.err = err_.get();
    context.format = format;
    context.progress = ProgressMode::kOff;
    context.client.target = "127.0.0.1:1";
    return context;
  }
  EvalOptions Local(const std::string& dataset) {
    EvalOptions eval;
    eval.local = true;
    eval.dataset = (root_ / dataset).string();
    eval.create.spec = "rphsd:refs=cross7,bins=10";
    eval.with_predictions = true;
    return eval;
  }

  fs::path root_;
  Captured err_;
};

TEST_F(EvalLocalTest, HoldOutInEveryFormatWithoutAServer) {
  cli_testing::WriteLabeledDataset(root_ / "split", /*split=*/true);
  EvalOptions eval = Local("split");
  eval.report_html = (root_ / "report.html").string();
  Captured json;
  ASSERT_EQ(RunEval(eval, Context(json)), kExitOk) << err_.contents();
  const std::string text = json.contents();
  // 9 clouds per label: 6 train, 3 test.
  EXPECT_THAT(text, AllOf(StartsWith("{\"mode\":\"holdout\""),
                          HasSubstr("\"descriptor_spec\":\"rphsd:refs=cross7,bins=10,"),
                          HasSubstr("\"k\":1,\"folds\":1,"), HasSubstr("\"tests\":9,"),
                          HasSubstr("\"train_samples\":18,"), HasSubstr("\"failed_files\":[]"),
                          HasSubstr("\"predictions\":[{\"file\":")));
  // Each answer names its nearest training sample and the file it came from.
  EXPECT_THAT(text, MatchesRegex(".*\"neighbors\":\\[\\{\"sample_id\":[0-9]+,\"label\":\"[a-z]+\","
                                 "\"distance\":[-0-9.e]+,\"view\":0,\"file\":\"[^\"]*/train/[^\"]*"
                                 "\\.pcd\"\\}\\].*"));
  // Times are measured: the predictions' own describe + classify, and both phases.
  EXPECT_THAT(text, Not(HasSubstr("\"median_call_seconds\":0,")));
  EXPECT_THAT(text, Not(HasSubstr("\"train_seconds\":0,")));
  EXPECT_THAT(text, Not(HasSubstr("\"test_seconds\":0,")));
  std::ifstream html(eval.report_html);
  const std::string page((std::istreambuf_iterator<char>(html)), std::istreambuf_iterator<char>());
  EXPECT_THAT(page, AllOf(HasSubstr("<html"), HasSubstr("<dd>hold-out"), HasSubstr("sphere")));

  Captured table, csv;
  eval.report_html.clear();
  ASSERT_EQ(RunEval(eval, Context(table, OutputFormat::kTable)), kExitOk);
  EXPECT_THAT(table.contents(),
              AllOf(StartsWith("eval holdout  dataset "), HasSubstr("confusion matrix"),
                    HasSubstr("training 18 samples")));
  ASSERT_EQ(RunEval(eval, Context(csv, OutputFormat::kCsv)), kExitOk);
  EXPECT_THAT(csv.contents(), AllOf(StartsWith("label,tests,correct,recall,precision\n"),
                                    HasSubstr("\n__overall__,9,")));
  EXPECT_EQ(err_.contents(), "");
}

// Box, sphere and rod, 4 clean training clouds and 2 test clouds each, and a sphere filed
// under box/test/: one error, whose nearest training sample is a sphere.
void WriteCleanDatasetWithOneError(const fs::path& dir) {
  for (int label = 0; label < 3; ++label) {
    for (int i = 0; i < 6; ++i) {
      const fs::path folder = dir / testing_clouds::kShapeNames[label] / (i < 4 ? "train" : "test");
      fs::create_directories(folder);
      ASSERT_TRUE(WritePcd((folder / absl::StrCat(i, ".pcd")).string(),
                           testing_clouds::ShapeCloud(label, 10 * label + i + 1, 300))
                      .ok());
    }
  }
  ASSERT_TRUE(
      WritePcd((dir / "box/test/misfiled.pcd").string(), testing_clouds::ShapeCloud(1, 99, 300))
          .ok());
}

TEST_F(EvalLocalTest, TheReportTracesAnErrorToTheTrainingFileItMatched) {
  WriteCleanDatasetWithOneError(root_ / "clean");
  EvalOptions eval = Local("clean");
  eval.report_html = (root_ / "report.html").string();
  Captured json;
  ASSERT_EQ(RunEval(eval, Context(json)), kExitOk) << err_.contents();
  EXPECT_THAT(json.contents(), AllOf(HasSubstr("\"tests\":7,\"correct\":6,"),
                                     HasSubstr("\"gallery\":\"\",\"started\":\"20"),
                                     HasSubstr("\"server\":\"\",\"client_version\":\""),
                                     HasSubstr("\"server_version\":\"\"")));
  std::ifstream html(eval.report_html);
  const std::string page((std::istreambuf_iterator<char>(html)), std::istreambuf_iterator<char>());
  // The header: where and with what it ran.
  EXPECT_THAT(page, AllOf(HasSubstr("<dt>gallery</dt><dd>a fresh in-process gallery per round"),
                          HasSubstr("<dt>server</dt><dd>in-process (--local)</dd>"),
                          HasSubstr("<dt>shapeid</dt><dd>client "),
                          HasSubstr("<dt>descriptor spec</dt><dd>rphsd:refs=cross7,bins=10,"),
                          HasSubstr("<dt>k</dt><dd>1</dd>")));
  EXPECT_THAT(page, MatchesRegex("(.|\n)*<dt>started</dt><dd>20[0-9][0-9]-[01][0-9]-[0-3][0-9]T"
                                 "[0-2][0-9]:[0-5][0-9]:[0-6][0-9]Z</dd>(.|\n)*"));
  // k = 1: no vote share column; the error row names the sphere it matched, by file.
  EXPECT_THAT(page, Not(HasSubstr("<th class=\"num\">confidence</th>")));
  const std::string sphere_train = (root_ / "clean/sphere/train/").string();
  EXPECT_THAT(page, MatchesRegex("(.|\n)*<tr id=\"e1\"><td class=\"num\"><a href=\"#p1\">1</a>"
                                 "</td><td class=\"path\">[^<]*/box/test/misfiled.pcd</td>"
                                 "<td>box</td><td>sphere</td><td class=\"path\">" +
                                 sphere_train +
                                 "[0-3].pcd</td><td>sphere</td><td class=\"num\">[0-9.e-]+</td>"
                                 "<td class=\"num\">[0-9]+</td></tr>(.|\n)*"));
  // Its picture beside the training sample's, both read and embedded.
  EXPECT_THAT(page, HasSubstr("<div class=\"pair\" id=\"p1\">"));
  EXPECT_EQ(CountOf(page, "<img class=\"cloud\" src=\"data:image/png;base64,iVBORw0KGgo"), 2u);
  EXPECT_THAT(page, Not(HasSubstr("No picture")));
  EXPECT_LT(page.size(), 40000u);

  // A training file gone since: the page says so in place of its picture.
  for (int i = 0; i < 4; ++i) fs::remove(root_ / absl::StrCat("clean/sphere/train/", i, ".pcd"));
  EvalRun run;
  run.k = 1;
  EvalPrediction p;
  p.file = (root_ / "clean/box/test/misfiled.pcd").string();
  p.truth = "box";
  p.predicted = "sphere";
  p.neighbors = {{7, "sphere", 0.5, 0, sphere_train + "0.pcd"}};
  run.predictions.push_back(p);
  const std::string gone =
      RenderEvalHtml(run, ComputeEvalMetrics(run), ErrorPicturesFromFiles(ReadOptions()));
  EXPECT_EQ(CountOf(gone, "<img class=\"cloud\""), 1u);
  EXPECT_THAT(gone, HasSubstr("<div class=\"missing\">No picture: the training file of sample 7 (" +
                              sphere_train + "0.pcd) cannot be read here"));
}

TEST_F(EvalLocalTest, KFoldTestsEveryFileOnceAndTheAnswersDoNotDependOnTheThreads) {
  cli_testing::WriteLabeledDataset(root_ / "flat", /*split=*/false, /*per_label=*/12);
  EvalOptions eval = Local("flat");
  eval.folds = 4;
  eval.seed = 3;
  eval.create.k = 3;
  eval.create.weighting = "distance";
  eval.batch.jobs = 1;
  Captured one;
  ASSERT_EQ(RunEval(eval, Context(one)), kExitOk) << err_.contents();
  EXPECT_THAT(one.contents(),
              AllOf(StartsWith("{\"mode\":\"kfold\""), HasSubstr("\"k\":3,\"folds\":4,\"seed\":3,"),
                    HasSubstr("\"tests\":36,"), HasSubstr("\"train_samples\":108,")));
  // The label noise makes mistakes: the comparisons below are not between two perfect runs.
  EXPECT_THAT(one.contents(), Not(HasSubstr("\"correct\":36,")));
  for (int jobs : {2, 5}) {
    eval.batch.jobs = jobs;
    Captured many;
    ASSERT_EQ(RunEval(eval, Context(many)), kExitOk) << err_.contents();
    EXPECT_EQ(WithoutClock(many.contents()), WithoutClock(one.contents())) << jobs << " jobs";
  }
}

TEST_F(EvalLocalTest, ABadFileIsCountedAndTheEvaluationGoesOn) {
  cli_testing::WriteLabeledDataset(root_ / "split", /*split=*/true);
  std::ofstream((root_ / "split/box/train/broken.pcd").string()) << "not a pcd file\n";
  std::ofstream((root_ / "split/rod/test/tiny.xyz").string()) << "0 0 0\n1 1 1\n";  // 2 points
  EvalOptions eval = Local("split");
  eval.batch.jobs = 3;
  Captured json;
  EXPECT_EQ(RunEval(eval, Context(json)), kExitSomeInputsFailed);
  const std::string errors = err_.contents();
  EXPECT_THAT(errors, AllOf(HasSubstr("broken.pcd"), HasSubstr("tiny.xyz")));
  EXPECT_EQ(std::count(errors.begin(), errors.end(), '\n'), 2) << errors;  // one line each
  EXPECT_THAT(
      json.contents(),
      AllOf(HasSubstr("\"tests\":9,"), HasSubstr("\"train_samples\":18,"),
            HasSubstr("\"failed_files\":[\"" + (root_ / "split/box/train/broken.pcd").string() +
                      "\",\"" + (root_ / "split/rod/test/tiny.xyz").string() + "\"]")));
}

TEST_F(EvalLocalTest, UsageErrorsBeforeAnyFileIsRead) {
  cli_testing::WriteLabeledDataset(root_ / "split", /*split=*/true);
  Captured out;
  EvalOptions eval = Local("split");
  eval.gallery = "parts";
  EXPECT_EQ(RunEval(eval, Context(out)), kExitUsage);
  EXPECT_EQ(err_.contents(),
            "shapeid: eval: --gallery needs the server; drop --local (or drop --gallery to "
            "evaluate on temporary in-process galleries)\n");

  eval.gallery.clear();
  eval.create.spec = "nosuchdescriptor";
  EXPECT_EQ(RunEval(eval, Context(out)), kExitUsage);
  EXPECT_THAT(err_.contents(), HasSubstr("nosuchdescriptor"));
  eval.create.spec.clear();
  eval.create.scaling = "log";
  EXPECT_EQ(RunEval(eval, Context(out)), kExitUsage);
  EXPECT_THAT(err_.contents(), HasSubstr("--scaling \"log\""));
  eval.create.scaling.clear();
  eval.folds = 100;
  EXPECT_EQ(RunEval(eval, Context(out)), kExitUsage);
  EXPECT_THAT(err_.contents(), HasSubstr("cannot make 100 folds"));
  EXPECT_EQ(out.contents(), "");
}

TEST_F(EvalLocalTest, NoUsableTrainingFileStopsTheEvaluation) {
  for (const char* label : {"a", "b"}) {
    for (const char* part : {"train", "test"}) {
      fs::create_directories(root_ / "bad" / label / part);
      std::ofstream((root_ / "bad" / label / part / "0.xyz").string()) << "0 0 0\n";
    }
  }
  Captured out;
  EXPECT_EQ(RunEval(Local("bad"), Context(out)), kExitRefused);
  EXPECT_THAT(err_.contents(),
              HasSubstr("shapeid: eval: no training file could be used; nothing to evaluate"));
  EXPECT_EQ(out.contents(), "");
}

}  // namespace
}  // namespace shapeid
