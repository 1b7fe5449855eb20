#include "client/cli/input_files.h"

#include <filesystem>
#include <fstream>
#include <string>

#include "gmock/gmock.h"
#include "gtest/gtest.h"

namespace shapeid {
namespace {

namespace fs = std::filesystem;
using ::testing::ElementsAre;
using ::testing::HasSubstr;

class InputFilesTest : public ::testing::Test {
 protected:
  void SetUp() override {
    root_ = fs::path(::testing::TempDir()) /
            ("input_files_" +
             std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()));
    fs::remove_all(root_);
    fs::create_directories(root_);
  }
  void Touch(const std::string& relative) {
    const fs::path path = root_ / relative;
    fs::create_directories(path.parent_path());
    std::ofstream(path) << "0 0 0\n";
  }
  std::string P(const std::string& relative) const { return (root_ / relative).string(); }
  fs::path root_;
};

TEST_F(InputFilesTest, RecognizesPointCloudExtensions) {
  for (const char* name :
       {"a.pcd", "b.PLY", "c.off", "d.obj", "e.xyz", "f.txt", "g.csv", "h.stl", "i.vtk", "j.las",
        "k.npy", "l.npz", "m.pts", "n.xyzn", "o.xyzrgb", "p.pcd.gz"}) {
    EXPECT_TRUE(IsPointCloudFile(name)) << name;
  }
  for (const char* name : {"readme.md", "noext", "x.pcd.bak", "t.laz", "u.gz"}) {
    EXPECT_FALSE(IsPointCloudFile(name)) << name;
  }
}

TEST_F(InputFilesTest, ExpandsFoldersRecursivelySortedSkippingHiddenAndOtherFiles) {
  Touch("scans/b.pcd");
  Touch("scans/a.pcd");
  Touch("scans/sub/c.xyz");
  Touch("scans/notes.md");
  Touch("scans/.hidden/d.pcd");
  Touch("scans/.e.pcd");
  Touch("single.ply");
  Touch("scans/tile.laz");
  std::vector<std::string> unsupported;
  const auto files = ExpandInputs({P("single.ply"), P("scans")}, &unsupported);
  ASSERT_TRUE(files.ok()) << files.status();
  EXPECT_THAT(*files, ElementsAre(P("single.ply"), P("scans/a.pcd"), P("scans/b.pcd"),
                                  P("scans/sub/c.xyz")));
  // The other files are not dropped without a word: the command reports them.
  EXPECT_THAT(unsupported, ElementsAre(P("scans/notes.md"), P("scans/tile.laz")));
}

TEST_F(InputFilesTest, UnsupportedFilesMessageCountsNamesAndGivesTheFlag) {
  EXPECT_EQ(UnsupportedFilesMessage({}), "");
  const std::string one = UnsupportedFilesMessage({"d/a.md"});
  EXPECT_THAT(one, HasSubstr("1 file is in no format shapeid reads and was not processed"));
  const std::string five = UnsupportedFilesMessage({"a.md", "b.md", "c.md", "d.md", "e.md"});
  EXPECT_THAT(five, HasSubstr("5 files are in no format shapeid reads and were not processed: "
                              "a.md, b.md, c.md and 2 more"));
  EXPECT_THAT(five, HasSubstr(".las"));
  EXPECT_THAT(five, HasSubstr("--skip-unsupported"));
  // A folder of nothing readable says what it holds.
  Touch("mix/a.e57");
  const auto none = ExpandInputs({P("mix")});
  EXPECT_TRUE(absl::IsInvalidArgument(none.status()));
  EXPECT_THAT(none.status().message(), HasSubstr("a.e57"));
  Touch("labeled/chair/a.e57");
  const auto labeled = LabeledFiles(P("labeled"), Split::kAll);
  EXPECT_TRUE(absl::IsInvalidArgument(labeled.status()));
  EXPECT_THAT(labeled.status().message(),
              HasSubstr("1 file is in no format shapeid reads and was not processed"));
}

TEST_F(InputFilesTest, NonFinitePointsNameTheFlagThatDropsThem) {
  const fs::path path = root_ / "organized.xyz";
  std::ofstream(path) << "1 2 3\nnan nan nan\n4 5 6\n7 8 9\nnan 0 0\n";
  const absl::StatusOr<ReadResult> refused = ReadInputCloud(path.string(), ReadOptions());
  ASSERT_FALSE(refused.ok());
  EXPECT_TRUE(absl::IsInvalidArgument(refused.status()));
  EXPECT_THAT(refused.status().message(), HasSubstr("point 1 has a non-finite coordinate"));
  EXPECT_THAT(refused.status().message(), HasSubstr("2 of 5 points are non-finite"));
  EXPECT_THAT(refused.status().message(), HasSubstr("--drop-nonfinite"));
  ReadOptions drop;
  drop.drop_non_finite = true;
  const absl::StatusOr<ReadResult> dropped = ReadInputCloud(path.string(), drop);
  ASSERT_TRUE(dropped.ok()) << dropped.status();
  EXPECT_EQ(dropped->cloud.size(), 3u);
  EXPECT_EQ(dropped->dropped_non_finite, 2u);
}

TEST_F(InputFilesTest, ExpandKeepsMissingFilesAndRejectsEmptyFolders) {
  // A missing path stays: the reader reports it as one failed file of the batch.
  EXPECT_THAT(*ExpandInputs({P("nope")}), ElementsAre(P("nope")));
  fs::create_directories(root_ / "empty");
  const auto empty = ExpandInputs({P("empty")});
  EXPECT_TRUE(absl::IsInvalidArgument(empty.status()));
  EXPECT_THAT(empty.status().message(), HasSubstr("no point-cloud file"));
  // A file given by name stays, whatever its extension: the reader will say what is wrong.
  Touch("weird.dat");
  EXPECT_THAT(*ExpandInputs({P("weird.dat")}), ElementsAre(P("weird.dat")));
}

TEST_F(InputFilesTest, StandardInputNeedsAnInputFormat) {
  ReadOptions options;
  EXPECT_TRUE(CheckStandardInputFormat({P("a.pcd"), P("b.ply")}, options).ok());
  const absl::Status status = CheckStandardInputFormat({P("a.pcd"), "-"}, options);
  EXPECT_TRUE(absl::IsInvalidArgument(status)) << status;
  EXPECT_THAT(status.message(), HasSubstr("standard input (\"-\")"));
  EXPECT_THAT(status.message(), HasSubstr("--input-format (pcd, ply,"));
  options.input_format = CloudFormat::kXyz;
  EXPECT_TRUE(CheckStandardInputFormat({"-"}, options).ok());
}

TEST_F(InputFilesTest, LabeledFoldersWithAndWithoutTrainTestSplit) {
  Touch("flat/chair/1.pcd");
  Touch("flat/chair/2.pcd");
  Touch("flat/table/deep/3.pcd");
  EXPECT_FALSE(HasTrainTestSplit(P("flat")));
  auto flat = LabeledFiles(P("flat"), Split::kAll);
  ASSERT_TRUE(flat.ok()) << flat.status();
  ASSERT_EQ(flat->size(), 3u);
  EXPECT_EQ((*flat)[0].label, "chair");
  EXPECT_EQ((*flat)[2].label, "table");
  EXPECT_EQ((*flat)[2].path, P("flat/table/deep/3.pcd"));
  // No test/ folders: the test split is empty, which is an error naming the layout.
  const auto no_test = LabeledFiles(P("flat"), Split::kTest);
  EXPECT_TRUE(absl::IsInvalidArgument(no_test.status()));
  EXPECT_THAT(no_test.status().message(), HasSubstr("<label>/test/"));

  Touch("split/chair/train/1.pcd");
  Touch("split/chair/test/2.pcd");
  Touch("split/table/train/3.pcd");
  Touch("split/table/test/4.pcd");
  Touch("split/table/test/5.pcd");
  EXPECT_TRUE(HasTrainTestSplit(P("split")));
  auto train = LabeledFiles(P("split"), Split::kTrain);
  auto test = LabeledFiles(P("split"), Split::kTest);
  ASSERT_TRUE(train.ok() && test.ok());
  EXPECT_EQ(train->size(), 2u);
  EXPECT_EQ(test->size(), 3u);
  EXPECT_EQ((*test)[2].label, "table");
  EXPECT_EQ(LabeledFiles(P("split"), Split::kAll)->size(), 5u);
}

TEST_F(InputFilesTest, LabeledFilesErrors) {
  EXPECT_TRUE(absl::IsNotFound(LabeledFiles(P("missing"), Split::kAll).status()));
  Touch("file.pcd");
  EXPECT_TRUE(absl::IsInvalidArgument(LabeledFiles(P("file.pcd"), Split::kAll).status()));
  Touch("nolabels/a.pcd");  // files directly in the root: no label folders
  EXPECT_TRUE(absl::IsInvalidArgument(LabeledFiles(P("nolabels"), Split::kAll).status()));
}

}  // namespace
}  // namespace shapeid
