#include "server/cloud_assembler.h"

#include <cstring>
#include <string>
#include <vector>

#include "gmock/gmock.h"
#include "gtest/gtest.h"

namespace shapeid {
namespace {

using ::testing::HasSubstr;

std::string Bytes(const std::vector<float>& xyz) {
  std::string bytes(xyz.size() * 4, '\0');
  std::memcpy(bytes.data(), xyz.data(), bytes.size());
  return bytes;
}

TEST(CloudAssemblerTest, JoinsChunksOfAnySizeIncludingEmpty) {
  CloudAssembler assembler(100);
  ASSERT_TRUE(assembler.Start(3).ok());
  ASSERT_TRUE(assembler.Append(Bytes({1, 2, 3})).ok());
  ASSERT_TRUE(assembler.Append("").ok());
  ASSERT_TRUE(assembler.Append(Bytes({4, 5, 6, 7, 8, 9})).ok());
  auto cloud = assembler.Finish();
  ASSERT_TRUE(cloud.ok()) << cloud.status();
  EXPECT_THAT(cloud->xyz(), ::testing::ElementsAre(1, 2, 3, 4, 5, 6, 7, 8, 9));
  EXPECT_FALSE(assembler.started());
}

TEST(CloudAssemblerTest, AnEmptyFirstChunkIsFine) {
  CloudAssembler assembler(10);
  ASSERT_TRUE(assembler.Start(0).ok());
  ASSERT_TRUE(assembler.Append("").ok());  // nothing stored yet: no copy into null storage
  ASSERT_TRUE(assembler.Append(Bytes({1, 2, 3})).ok());
  auto cloud = assembler.Finish();
  ASSERT_TRUE(cloud.ok());
  EXPECT_EQ(cloud->size(), 1u);
}

TEST(CloudAssemblerTest, ReusableForTheNextCloud) {
  CloudAssembler assembler(10);
  ASSERT_TRUE(assembler.Start(0).ok());
  ASSERT_TRUE(assembler.Append(Bytes({1, 1, 1})).ok());
  ASSERT_TRUE(assembler.Finish().ok());
  ASSERT_TRUE(assembler.Start(0).ok());
  ASSERT_TRUE(assembler.Append(Bytes({2, 2, 2, 3, 3, 3})).ok());
  auto cloud = assembler.Finish();
  ASSERT_TRUE(cloud.ok());
  EXPECT_EQ(cloud->size(), 2u);
}

TEST(CloudAssemblerTest, ErrorsSayWhatIsWrongWithNumbers) {
  CloudAssembler assembler(2);
  EXPECT_THAT(assembler.Append(Bytes({1, 2, 3})).message(), HasSubstr("before the header"));

  const absl::Status announced = assembler.Start(5);
  EXPECT_EQ(announced.code(), absl::StatusCode::kResourceExhausted);
  EXPECT_THAT(announced.message(), HasSubstr("announces 5 points, more than the limit of 2"));

  ASSERT_TRUE(assembler.Start(0).ok());
  const absl::Status partial = assembler.Append(std::string(13, '\0'));
  EXPECT_EQ(partial.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(partial.message(), HasSubstr("13 bytes is not a whole number of points"));

  ASSERT_TRUE(assembler.Append(Bytes({1, 2, 3, 4, 5, 6})).ok());
  const absl::Status over = assembler.Append(Bytes({7, 8, 9}));
  EXPECT_EQ(over.code(), absl::StatusCode::kResourceExhausted);
  EXPECT_THAT(over.message(), HasSubstr("more than the limit of 2 points (3 received so far; "
                                        "max_points_per_cloud)"));

  ASSERT_TRUE(assembler.Start(2).ok());
  ASSERT_TRUE(assembler.Append(Bytes({1, 2, 3})).ok());
  const auto short_cloud = assembler.Finish();
  EXPECT_EQ(short_cloud.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(short_cloud.status().message(), HasSubstr("announced 2 points but 1 arrived"));
}

}  // namespace
}  // namespace shapeid
