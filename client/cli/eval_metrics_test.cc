#include "client/cli/eval_metrics.h"

#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <string>
#include <vector>

#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_split.h"
#include "client/cli/eval_testing.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"

namespace shapeid {
namespace {

using ::shapeid::eval_testing::Add;
using ::shapeid::eval_testing::CountOf;
using ::shapeid::eval_testing::ThreeClassRun;
using ::testing::ElementsAre;
using ::testing::EndsWith;
using ::testing::HasSubstr;
using ::testing::Not;
using ::testing::StartsWith;

// A Python 3 to check the JSON with a real parser: Debian's when present (a version-manager
// shim on the PATH can take a second to start), else whatever python3 the PATH has.
std::string Python() {
  return access("/usr/bin/python3", X_OK) == 0 ? "/usr/bin/python3" : "python3";
}

bool HavePython() {
  return std::system(absl::StrCat(Python(), " -c pass >/dev/null 2>&1").c_str()) == 0;
}

// Runs `script` with python3; `json` is loaded as `d`. True when the script exits 0.
bool PythonCheck(const std::string& json, const std::string& script) {
  char path[] = "/tmp/eval_metrics_test_XXXXXX";
  const int fd = mkstemp(path);
  if (fd < 0) return false;
  std::FILE* file = fdopen(fd, "w");
  std::fwrite(json.data(), 1, json.size(), file);
  std::fclose(file);
  const std::string py_path = absl::StrCat(path, ".py");
  std::ofstream(py_path) << "import json, sys\nd = json.load(open(sys.argv[1]))\n"
                         << script << "\n";
  const int status = std::system(absl::StrCat(Python(), " ", py_path, " ", path).c_str());
  std::remove(path);
  std::remove(py_path.c_str());
  return status == 0;
}

// The line of `text` that starts with `prefix`, or "".
std::string LineStartingWith(const std::string& text, absl::string_view prefix) {
  for (absl::string_view line : absl::StrSplit(text, '\n')) {
    if (absl::StartsWith(line, prefix)) return std::string(line);
  }
  return "";
}

TEST(EvalMetricsTest, ThreeClassesNumberByNumber) {
  const EvalMetrics m = ComputeEvalMetrics(ThreeClassRun());
  EXPECT_THAT(m.labels, ElementsAre("bench", "chair", "table"));
  ASSERT_EQ(m.confusion.size(), 3u);
  EXPECT_THAT(m.confusion[0], ElementsAre(3, 1, 0));
  EXPECT_THAT(m.confusion[1], ElementsAre(0, 2, 1));
  EXPECT_THAT(m.confusion[2], ElementsAre(1, 0, 2));
  ASSERT_EQ(m.classes.size(), 3u);
  EXPECT_EQ(m.classes[0].label, "bench");
  EXPECT_EQ(m.classes[0].tests, 4u);
  EXPECT_EQ(m.classes[0].correct, 3u);
  EXPECT_EQ(m.classes[0].predicted, 4u);
  EXPECT_DOUBLE_EQ(m.classes[0].recall, 0.75);
  EXPECT_DOUBLE_EQ(m.classes[0].precision, 0.75);
  EXPECT_EQ(m.classes[1].label, "chair");
  EXPECT_EQ(m.classes[1].tests, 3u);
  EXPECT_EQ(m.classes[1].correct, 2u);
  EXPECT_EQ(m.classes[1].predicted, 3u);
  EXPECT_DOUBLE_EQ(m.classes[1].recall, 2.0 / 3);
  EXPECT_DOUBLE_EQ(m.classes[1].precision, 2.0 / 3);
  EXPECT_EQ(m.classes[2].label, "table");
  EXPECT_EQ(m.classes[2].tests, 3u);
  EXPECT_EQ(m.classes[2].correct, 2u);
  EXPECT_EQ(m.classes[2].predicted, 3u);
  EXPECT_DOUBLE_EQ(m.classes[2].recall, 2.0 / 3);
  EXPECT_DOUBLE_EQ(m.classes[2].precision, 2.0 / 3);
  EXPECT_EQ(m.tests, 10u);
  EXPECT_EQ(m.correct, 7u);
  EXPECT_DOUBLE_EQ(m.accuracy, 0.7);
  EXPECT_DOUBLE_EQ(m.mean_class_accuracy, (0.75 + 2.0 / 3 + 2.0 / 3) / 3);
  EXPECT_DOUBLE_EQ(m.seconds_per_cloud, 0.05);
  EXPECT_TRUE(m.fold_accuracy.empty());  // not kfold
  EXPECT_EQ(m.fold_accuracy_mean, 0);
  EXPECT_EQ(m.fold_accuracy_std, 0);
}

TEST(EvalMetricsTest, LabelsOutsideTheTruthsBecomeExtraColumns) {
  EvalRun run = ThreeClassRun();
  Add(run, "chair", "unknown");
  Add(run, "table", "unknown");
  Add(run, "bench", "armchair");  // sorts before the truths, but goes after them
  const EvalMetrics m = ComputeEvalMetrics(run);
  EXPECT_THAT(m.labels, ElementsAre("bench", "chair", "table", "armchair", "unknown"));
  ASSERT_EQ(m.confusion.size(), 5u);
  EXPECT_THAT(m.confusion[0], ElementsAre(3, 1, 0, 1, 0));
  EXPECT_THAT(m.confusion[1], ElementsAre(0, 2, 1, 0, 1));
  EXPECT_THAT(m.confusion[2], ElementsAre(1, 0, 2, 0, 1));
  EXPECT_THAT(m.confusion[3], ElementsAre(0, 0, 0, 0, 0));  // never a truth
  EXPECT_THAT(m.confusion[4], ElementsAre(0, 0, 0, 0, 0));
  ASSERT_EQ(m.classes.size(), 3u);  // only truth classes are scored
  EXPECT_EQ(m.classes[1].tests, 4u);
  EXPECT_DOUBLE_EQ(m.classes[1].recall, 0.5);
  EXPECT_DOUBLE_EQ(m.classes[1].precision, 2.0 / 3);  // rejections do not count against it
  EXPECT_EQ(m.tests, 13u);
  EXPECT_EQ(m.correct, 7u);
  EXPECT_DOUBLE_EQ(m.accuracy, 7.0 / 13);

  const std::string table = FormatEvalTable(run, m);
  const std::string header = LineStartingWith(table, "     ");  // the matrix column header
  EXPECT_THAT(header, EndsWith("bench  chair  table  armchair  unknown"));
}

TEST(EvalMetricsTest, KfoldMeanAndSampleStd) {
  EvalRun run;
  run.mode = "kfold";
  run.folds = 3;
  // Fold 0: 4 of 5, fold 1: 3 of 5, fold 2: 5 of 5.
  for (int i = 0; i < 5; ++i) Add(run, "a", i < 4 ? "a" : "b", 0);
  for (int i = 0; i < 5; ++i) Add(run, "b", i < 3 ? "b" : "a", 1);
  for (int i = 0; i < 5; ++i) Add(run, i % 2 ? "a" : "b", i % 2 ? "a" : "b", 2);
  const EvalMetrics m = ComputeEvalMetrics(run);
  ASSERT_EQ(m.fold_accuracy.size(), 3u);
  EXPECT_DOUBLE_EQ(m.fold_accuracy[0], 0.8);
  EXPECT_DOUBLE_EQ(m.fold_accuracy[1], 0.6);
  EXPECT_DOUBLE_EQ(m.fold_accuracy[2], 1.0);
  EXPECT_DOUBLE_EQ(m.fold_accuracy_mean, 0.8);
  EXPECT_NEAR(m.fold_accuracy_std, 0.2, 1e-12);
  EXPECT_DOUBLE_EQ(m.accuracy, 0.8);
  EXPECT_THAT(FormatEvalTable(run, m),
              HasSubstr("fold accuracy 80.00 % \xC2\xB1 20.00 %  (3 folds: 80.00 60.00 100.00)"));

  EvalRun one_fold;
  one_fold.mode = "kfold";
  Add(one_fold, "a", "a");
  Add(one_fold, "a", "b");
  const EvalMetrics single = ComputeEvalMetrics(one_fold);
  EXPECT_THAT(single.fold_accuracy, ElementsAre(0.5));
  EXPECT_DOUBLE_EQ(single.fold_accuracy_mean, 0.5);
  EXPECT_EQ(single.fold_accuracy_std, 0);
}

TEST(EvalMetricsTest, EmptyRunIsAllZerosAndRenders) {
  EvalRun run;
  run.mode = "kfold";
  run.test_seconds = 1.0;
  run.failed_files = {"bad.pcd"};
  const EvalMetrics m = ComputeEvalMetrics(run);
  EXPECT_TRUE(m.labels.empty());
  EXPECT_TRUE(m.confusion.empty());
  EXPECT_TRUE(m.classes.empty());
  EXPECT_EQ(m.tests, 0u);
  EXPECT_EQ(m.correct, 0u);
  EXPECT_EQ(m.accuracy, 0);
  EXPECT_EQ(m.mean_class_accuracy, 0);
  EXPECT_TRUE(m.fold_accuracy.empty());
  EXPECT_EQ(m.fold_accuracy_mean, 0);
  EXPECT_EQ(m.fold_accuracy_std, 0);
  EXPECT_EQ(m.seconds_per_cloud, 0);

  const std::string table = FormatEvalTable(run, m);
  EXPECT_THAT(table, HasSubstr("accuracy 0.00 % (0/0)"));
  EXPECT_THAT(table, HasSubstr("failed files (1):\n  bad.pcd\n"));
  EXPECT_THAT(table, Not(HasSubstr("nan")));
  const std::string json = FormatEvalJson(run, m, true);
  EXPECT_THAT(json, Not(HasSubstr("null")));
  EXPECT_THAT(json, HasSubstr("\"labels\":[],\"confusion\":[],\"failed_files\":[\"bad.pcd\"]"));
  EXPECT_EQ(FormatEvalCsv(m), "label,tests,correct,recall,precision\n__overall__,0,0,0,0\n");
  if (HavePython()) {
    EXPECT_TRUE(PythonCheck(json, "assert d['tests'] == 0 and d['predictions'] == []"));
  }
}

TEST(EvalMetricsTest, TableHasHeadlineAlignedClassesAndMatrix) {
  EvalRun run = ThreeClassRun();
  run.failed_files = {"broken/one.pcd", "broken/two.ply"};
  const std::string table = FormatEvalTable(run, ComputeEvalMetrics(run));
  EXPECT_THAT(table, StartsWith("eval holdout  dataset data/furniture\n"));
  EXPECT_THAT(table, HasSubstr("accuracy 70.00 % (7/10)  mean class accuracy 69.44 %  k=3  "
                               "spec rphsd:bins=8\n"));
  EXPECT_THAT(table, HasSubstr("time per cloud 50 ms (median call 50 ms)  training 90 samples "
                               "in 2.5 s  testing 500 ms  failed 2\n"));
  EXPECT_THAT(table, Not(HasSubstr("fold accuracy")));

  const std::string header = LineStartingWith(table, "class ");
  const std::string chair = LineStartingWith(table, "chair ");
  EXPECT_EQ(header, "class    tests  correct  recall %  precision %");
  EXPECT_EQ(chair, "chair        3        2     66.67        66.67");
  EXPECT_EQ(LineStartingWith(table, "overall "), "overall     10        7     70.00");

  EXPECT_THAT(table, HasSubstr("confusion matrix (rows: truth, columns: predicted, . = 0)\n"
                               "       bench  chair  table\n"
                               "bench      3      1      .\n"
                               "chair      .      2      1\n"
                               "table      1      .      2\n"));
  EXPECT_THAT(table, EndsWith("failed files (2):\n  broken/one.pcd\n  broken/two.ply\n"));
}

TEST(EvalMetricsTest, TableAgainstAGalleryNamesItAndItsSamples) {
  EvalRun run = ThreeClassRun();
  run.mode = "gallery";
  run.gallery = "mn10";
  run.train_samples = 3991;
  run.train_seconds = 0;
  const EvalMetrics m = ComputeEvalMetrics(run);
  const std::string table = FormatEvalTable(run, m);
  EXPECT_THAT(table,
              StartsWith("eval gallery  dataset data/furniture  gallery mn10 (3991 samples)\n"));
  EXPECT_THAT(table, HasSubstr("time per cloud 50 ms (median call 50 ms)  testing 500 ms\n"));
  EXPECT_THAT(FormatEvalJson(run, m, false),
              HasSubstr("\"seed\":0,\"gallery\":\"mn10\",\"started\":\"\",\"server\":\"\","));
  EXPECT_THAT(FormatEvalJson(run, m, false), HasSubstr("\"train_samples\":3991,"));
}

TEST(EvalMetricsTest, TableUsesKeysForManyLongLabels) {
  EvalRun run;
  run.mode = "holdout";
  std::vector<std::string> labels;
  for (int c = 0; c < 25; ++c) {
    labels.push_back(absl::StrCat("homedecor_category_number_", c < 10 ? "0" : "", c));
  }
  for (int c = 0; c < 25; ++c) {
    for (int i = 0; i < 12; ++i) Add(run, labels[c], i == 0 ? labels[(c + 1) % 25] : labels[c]);
  }
  Add(run, labels[3], "unknown");
  for (int i = 0; i < 30; ++i) run.failed_files.push_back(absl::StrCat("bad", i, ".pcd"));
  const EvalMetrics m = ComputeEvalMetrics(run);
  const std::string table = FormatEvalTable(run, m);
  for (absl::string_view line : absl::StrSplit(table, '\n')) {
    EXPECT_LE(line.size(), 150u) << line;
  }
  EXPECT_THAT(table, HasSubstr("\nc1  homedecor_category_number_00  11   1   .   ."));
  EXPECT_THAT(table, HasSubstr("\nc26 = unknown\n"));
  EXPECT_THAT(LineStartingWith(table, "    "), EndsWith("c24 c25 c26"));
  EXPECT_THAT(table, HasSubstr("  bad19.pcd\n  ... and 10 more"));
  EXPECT_THAT(table, Not(HasSubstr("bad20.pcd")));
}

TEST(EvalMetricsTest, JsonIsValidAndHasTheValues) {
  EvalRun run = ThreeClassRun();
  run.mode = "kfold";
  run.folds = 2;
  run.seed = 42;
  run.failed_files = {"we\"ird\\name\n.pcd"};
  run.started = "2026-11-28T15:05:00Z";
  run.server = "host:1";
  run.client_version = "1.2.3";
  run.server_version = "1.2.0";
  run.predictions[0].fold = 1;
  run.predictions[0].neighbors = {{1, "table", 0.25, 3, "train/table/7.pcd"},
                                  {9, "bench", 0.5, 0, ""}};
  Add(run, "chair", "unknown", 1);
  const EvalMetrics m = ComputeEvalMetrics(run);
  const std::string json = FormatEvalJson(run, m, false);
  EXPECT_THAT(json, StartsWith("{\"mode\":\"kfold\",\"dataset\":\"data/furniture\","));
  EXPECT_THAT(json, EndsWith("}\n"));
  EXPECT_EQ(CountOf(json, "\n"), 1u);
  EXPECT_THAT(json, HasSubstr("\"tests\":11,\"correct\":7,"));
  EXPECT_THAT(json, HasSubstr("\"labels\":[\"bench\",\"chair\",\"table\",\"unknown\"]"));
  EXPECT_THAT(json, HasSubstr("\"confusion\":[[3,1,0,0],[0,2,1,1],[1,0,2,0],[0,0,0,0]]"));
  EXPECT_THAT(json, Not(HasSubstr("predictions")));
  const std::string with_predictions = FormatEvalJson(run, m, true);
  EXPECT_THAT(
      with_predictions,
      HasSubstr("\"predictions\":[{\"file\":\"table/0.pcd\",\"truth\":\"table\","
                "\"predicted\":\"table\",\"confidence\":0.75,\"seconds\":0.050000000000000003,"
                "\"fold\":1,\"neighbors\":[{\"sample_id\":1,\"label\":\"table\",\"distance\":0.25,"
                "\"view\":3,\"file\":\"train/table/7.pcd\"},{\"sample_id\":9,\"label\":\"bench\","
                "\"distance\":0.5,\"view\":0}]},"));

  if (!HavePython()) GTEST_SKIP() << "python3 not found; JSON checked by substrings only";
  EXPECT_TRUE(PythonCheck(json, R"py(
keys = ["mode", "dataset", "descriptor_spec", "k", "folds", "seed", "gallery", "started",
        "server", "client_version", "server_version", "tests", "correct",
        "accuracy", "mean_class_accuracy", "fold_accuracy", "fold_accuracy_mean",
        "fold_accuracy_std", "seconds_per_cloud", "median_call_seconds", "train_samples", "train_seconds",
        "test_seconds", "classes", "labels", "confusion", "failed_files"]
assert list(d) == keys, list(d)
assert (d["k"], d["folds"], d["seed"], d["tests"], d["correct"]) == (3, 2, 42, 11, 7)
assert abs(d["accuracy"] - 7 / 11) < 1e-15
# fold 0: 6 of 9 correct; fold 1: 1 of 2
assert d["fold_accuracy"] == [6 / 9, 0.5], d["fold_accuracy"]
assert abs(d["fold_accuracy_std"] - abs(6 / 9 - 0.5) / 2 ** 0.5) < 1e-15
assert d["classes"][1] == {"label": "chair", "tests": 4, "correct": 2, "recall": 0.5,
                           "precision": 2 / 3}, d["classes"][1]
assert d["failed_files"] == ["we\"ird\\name\n.pcd"]
assert (d["train_samples"], d["train_seconds"], d["test_seconds"]) == (90, 2.5, 0.5)
assert (d["gallery"], d["started"], d["server"]) == ("", "2026-11-28T15:05:00Z", "host:1")
assert (d["client_version"], d["server_version"]) == ("1.2.3", "1.2.0")
)py"));
  EXPECT_TRUE(PythonCheck(with_predictions, R"py(
p = d["predictions"]
assert len(p) == 11 and p[-1] == {"file": "chair/10.pcd", "truth": "chair",
    "predicted": "unknown", "confidence": 0.75, "seconds": 0.05, "fold": 1,
    "neighbors": []}, p[-1]
assert p[0]["neighbors"][1] == {"sample_id": 9, "label": "bench", "distance": 0.5, "view": 0}
)py"));
}

TEST(EvalMetricsTest, CsvQuotesLikeRfc4180) {
  EvalRun run;
  Add(run, "plain", "plain");
  Add(run, "a,b", "a,b");
  Add(run, "say \"hi\"", "plain");
  Add(run, "two\nlines", "two\nlines");
  const std::string csv = FormatEvalCsv(ComputeEvalMetrics(run));
  EXPECT_EQ(csv,
            "label,tests,correct,recall,precision\n"
            "\"a,b\",1,1,1,1\n"
            "plain,1,1,1,0.5\n"
            "\"say \"\"hi\"\"\",1,0,0,0\n"
            "\"two\nlines\",1,1,1,1\n"
            "__overall__,4,3,0.75,0.75\n");
}

}  // namespace
}  // namespace shapeid
