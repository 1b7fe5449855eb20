#include "core/io/scene_files.h"

#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <string>

#include "gmock/gmock.h"
#include "gtest/gtest.h"

namespace shapeid {
namespace {

using ::testing::HasSubstr;

std::string FreshDir(const std::string& name) {
  const std::filesystem::path dir = std::filesystem::path(::testing::TempDir()) / name;
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir.string();
}

SceneFile TwoObjects(const std::string& name) {
  SceneFile scene;
  scene.name = name;
  scene.frame = {{0, 0, 1}, {0.5f, 0, 1}, {0, 0.25f, 2}, {1, 1, 1}};
  scene.frame.Add(std::numeric_limits<float>::quiet_NaN(), 0, 0);
  scene.truth = {0, 1, 1, 2, 0};
  scene.objects = {{"chair", false, "modelnet10/chair/test/chair_0890.pcd"},
                   {"sphere", true, "a, b"}};
  return scene;
}

TEST(SceneFilesTest, WhatIsWrittenReadsBackExactly) {
  const std::string dir = FreshDir("scene_round_trip");
  const SceneFile written = TwoObjects("0007");
  ASSERT_TRUE(WriteSceneFile(dir, written).ok());
  ASSERT_TRUE(WriteSceneFile(dir, TwoObjects("0002")).ok());
  EXPECT_EQ(ListSceneFiles(dir), (std::vector<std::string>{"0002", "0007"}));
  const absl::StatusOr<SceneFile> read = ReadSceneFile(dir, "0007");
  ASSERT_TRUE(read.ok()) << read.status();
  ASSERT_EQ(read->frame.size(), written.frame.size());
  for (size_t i = 0; i + 1 < written.frame.size(); ++i) {
    EXPECT_EQ(read->frame.point(i), written.frame.point(i)) << i;
  }
  EXPECT_TRUE(std::isnan(read->frame.point(4).x()));  // kept, not dropped: ids stay aligned
  EXPECT_EQ(read->truth, written.truth);
  ASSERT_EQ(read->objects.size(), 2u);
  EXPECT_EQ(read->objects[0].label, "chair");
  EXPECT_FALSE(read->objects[0].clutter);
  EXPECT_EQ(read->objects[0].source, "modelnet10/chair/test/chair_0890.pcd");
  EXPECT_TRUE(read->objects[1].clutter);
  EXPECT_EQ(read->objects[1].source, "a, b");  // the last field may hold commas
}

TEST(SceneFilesTest, MalformedSetsAreRefusedNamingTheFile) {
  const std::string dir = FreshDir("scene_malformed");
  SceneFile bad = TwoObjects("0000");
  bad.objects[0].label = "a,b";
  EXPECT_EQ(WriteSceneFile(dir, bad).code(), absl::StatusCode::kInvalidArgument);
  bad = TwoObjects("0000");
  bad.truth.pop_back();
  EXPECT_EQ(WriteSceneFile(dir, bad).code(), absl::StatusCode::kInvalidArgument);
  // A folder that is not there: the writer's NotFound, naming the file.
  const absl::Status missing = WriteSceneFile(dir + "/no_such_folder", TwoObjects("0000"));
  EXPECT_EQ(missing.code(), absl::StatusCode::kNotFound);
  EXPECT_NE(missing.message().find("no_such_folder/0000.pcd"), absl::string_view::npos);

  ASSERT_TRUE(WriteSceneFile(dir, TwoObjects("0000")).ok());
  const std::string base = dir + "/0000";
  std::ofstream(base + ".truth.u16", std::ios::binary) << std::string(9, '\0');
  absl::StatusOr<SceneFile> read = ReadSceneFile(dir, "0000");
  EXPECT_EQ(read.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(read.status().message(), HasSubstr("0000.truth.u16"));
  std::ofstream(base + ".truth.u16", std::ios::binary) << std::string("\0\0\0\0\3\0\0\0\0\0", 10);
  read = ReadSceneFile(dir, "0000");
  EXPECT_THAT(read.status().message(), HasSubstr("has id 3 but there are 2 objects"));
  std::ofstream(base + ".objects.csv") << "object,label,role,source\n1,chair,furniture,x\n";
  read = ReadSceneFile(dir, "0000");
  EXPECT_EQ(read.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(read.status().message(), HasSubstr("0000.objects.csv line 2"));
}

}  // namespace
}  // namespace shapeid
