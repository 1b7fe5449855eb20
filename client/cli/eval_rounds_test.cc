// Round construction of `shapeid eval`: which files each round trains on and tests, for
// every mode, and the usage errors found before anything runs.

#include "client/cli/eval_rounds.h"

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <set>
#include <string>
#include <tuple>
#include <vector>

#include "absl/strings/str_cat.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"

namespace shapeid {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

class PlanEvalTest : public ::testing::Test {
 protected:
  void SetUp() override {
    // Per process and test: ctest runs tests in parallel processes.
    root_ = fs::path(::testing::TempDir()) /
            absl::StrCat("eval_rounds_", ::getpid(), "_",
                         ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(root_);
  }
  void TearDown() override { fs::remove_all(root_); }

  // An empty file: planning only looks at names.
  void Touch(const std::string& relative) {
    const fs::path path = root_ / relative;
    fs::create_directories(path.parent_path());
    std::ofstream(path.string()) << "";
  }
  std::string Path(const std::string& relative) const { return (root_ / relative).string(); }

  fs::path root_;
};

std::vector<std::string> Names(const std::vector<LabeledFile>& files) {
  std::vector<std::string> names;
  for (const LabeledFile& f : files) {
    names.push_back(absl::StrCat(f.label, ":", fs::path(f.path).filename().string()));
  }
  return names;
}

TEST_F(PlanEvalTest, HoldOutWhenEveryLabelHasTrainAndTest) {
  for (const char* f : {"a/train/1.xyz", "a/train/2.xyz", "a/test/3.xyz", "b/train/4.xyz",
                        "b/test/5.xyz", "b/test/6.xyz"}) {
    Touch(f);
  }
  absl::StatusOr<EvalPlan> plan = PlanEval(Path(""), false, 0, 1);
  ASSERT_TRUE(plan.ok()) << plan.status();
  EXPECT_EQ(plan->mode, "holdout");
  EXPECT_EQ(plan->folds, 1);
  ASSERT_EQ(plan->rounds.size(), 1u);
  EXPECT_EQ(Names(plan->rounds[0].train),
            (std::vector<std::string>{"a:1.xyz", "a:2.xyz", "b:4.xyz"}));
  EXPECT_EQ(Names(plan->rounds[0].test),
            (std::vector<std::string>{"a:3.xyz", "b:5.xyz", "b:6.xyz"}));

  // Against a gallery: the test part only, nothing to train.
  plan = PlanEval(Path(""), true, 0, 1);
  ASSERT_TRUE(plan.ok()) << plan.status();
  EXPECT_EQ(plan->mode, "gallery");
  ASSERT_EQ(plan->rounds.size(), 1u);
  EXPECT_TRUE(plan->rounds[0].train.empty());
  EXPECT_EQ(plan->rounds[0].test.size(), 3u);

  // --folds on a split folder: k-fold over every file.
  plan = PlanEval(Path(""), false, 2, 1);
  ASSERT_TRUE(plan.ok()) << plan.status();
  EXPECT_EQ(plan->mode, "kfold");
  EXPECT_EQ(plan->folds, 2);
}

TEST_F(PlanEvalTest, KFoldTestsEveryFileOnceAndTrainsOnTheOthersInFolderOrder) {
  for (int i = 0; i < 7; ++i) Touch(absl::StrCat("a/", i, ".xyz"));
  for (int i = 0; i < 4; ++i) Touch(absl::StrCat("b/", i, ".xyz"));
  absl::StatusOr<EvalPlan> plan = PlanEval(Path(""), false, 0, 7);
  ASSERT_TRUE(plan.ok()) << plan.status();
  EXPECT_EQ(plan->mode, "kfold");
  EXPECT_EQ(plan->folds, 5);  // the default
  ASSERT_EQ(plan->rounds.size(), 5u);
  std::multiset<std::string> tested;
  for (const EvalRound& round : plan->rounds) {
    EXPECT_EQ(round.train.size() + round.test.size(), 11u);
    std::set<std::string> in_test;
    for (const LabeledFile& f : round.test) {
      tested.insert(f.path);
      in_test.insert(f.path);
    }
    for (size_t i = 0; i < round.train.size(); ++i) {
      EXPECT_EQ(in_test.count(round.train[i].path), 0u);
      if (i > 0) {
        EXPECT_LT(std::tie(round.train[i - 1].label, round.train[i - 1].path),
                  std::tie(round.train[i].label, round.train[i].path));
      }
    }
  }
  EXPECT_EQ(tested.size(), 11u);
  EXPECT_EQ(std::set<std::string>(tested.begin(), tested.end()).size(), 11u);
}

TEST_F(PlanEvalTest, UsageErrors) {
  EXPECT_EQ(PlanEval(Path("missing"), false, 0, 1).status().code(), absl::StatusCode::kNotFound);
  Touch("a/1.xyz");
  Touch("a/2.xyz");
  absl::StatusOr<EvalPlan> plan = PlanEval(Path(""), false, 3, 1);
  EXPECT_EQ(plan.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(plan.status().message(), HasSubstr("2 files cannot make 3 folds"));
  plan = PlanEval(Path(""), false, 1, 1);
  EXPECT_THAT(plan.status().message(), HasSubstr("--folds must be at least 2"));
}

TEST(StratifiedFoldsTest, EveryFoldGetsItsShareOfEveryClassAndTheSeedMatters) {
  std::vector<LabeledFile> files;
  for (int i = 0; i < 10; ++i) files.push_back({absl::StrCat("a", i), "a"});
  for (int i = 0; i < 5; ++i) files.push_back({absl::StrCat("b", i), "b"});
  const std::vector<int> folds = StratifiedFolds(files, 5, 42);
  std::vector<int> a(5, 0), b(5, 0);
  for (size_t i = 0; i < files.size(); ++i) (files[i].label == "a" ? a : b)[folds[i]]++;
  for (int f = 0; f < 5; ++f) {
    EXPECT_EQ(a[f], 2);
    EXPECT_EQ(b[f], 1);
  }
  EXPECT_EQ(StratifiedFolds(files, 5, 42), folds);
  EXPECT_NE(StratifiedFolds(files, 5, 43), folds);
}

}  // namespace
}  // namespace shapeid
