#include "core/io/colored_cloud_writer.h"

#include <cstring>
#include <string>
#include <vector>

#include "core/io/pcd_reader.h"
#include "core/io/ply_reader.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"

namespace shapeid {
namespace {

using ::testing::HasSubstr;
using ::testing::StartsWith;

PointCloud ThreePoints() {
  PointCloud cloud;
  cloud.Add(1.5f, -2.25f, 3.0f);
  cloud.Add(0.0f, 0.125f, -7.5f);
  cloud.Add(1e-3f, 2e3f, -0.0f);
  return cloud;
}
const std::vector<Rgb> kColors = {{{255, 0, 0}}, {{0, 128, 255}}, {{1, 2, 3}}};

// Each format reads back to the same coordinates with the project's readers (which ignore
// the color), and holds each point's color where the format puts it.
TEST(ColoredCloudWriterTest, PlyReadsBackWithItsColors) {
  const PointCloud cloud = ThreePoints();
  const std::string ply =
      EncodeColoredCloud(cloud, kColors, ColoredCloudFormat::kPly, "a test cloud");
  EXPECT_THAT(ply, StartsWith("ply\nformat binary_little_endian 1.0\ncomment a test cloud\n"
                              "element vertex 3\n"));
  EXPECT_THAT(ply, HasSubstr("property uchar red\nproperty uchar green\nproperty uchar blue\n"
                             "end_header\n"));
  ReadOptions as_written;
  as_written.recenter = false;
  const absl::StatusOr<ReadResult> read = ParsePly(ply, "test.ply", as_written);
  ASSERT_TRUE(read.ok()) << read.status();
  ASSERT_EQ(read->cloud.size(), 3u);
  EXPECT_EQ(0, std::memcmp(read->cloud.data(), cloud.data(), 36));
  const size_t body = ply.size() - 3 * 15;
  for (size_t i = 0; i < 3; ++i) {
    EXPECT_EQ(0, std::memcmp(ply.data() + body + 15 * i + 12, kColors[i].data(), 3)) << i;
  }
}

TEST(ColoredCloudWriterTest, PcdPacksRgbAsPcl) {
  const PointCloud cloud = ThreePoints();
  const std::string pcd = EncodeColoredCloud(cloud, kColors, ColoredCloudFormat::kPcd, "x");
  EXPECT_THAT(pcd, HasSubstr("FIELDS x y z rgb\nSIZE 4 4 4 4\nTYPE F F F U\nCOUNT 1 1 1 1\n"
                             "WIDTH 3\nHEIGHT 1\n"));
  ReadOptions as_written;
  as_written.recenter = false;
  const absl::StatusOr<ReadResult> read = ParsePcd(pcd, "test.pcd", as_written);
  ASSERT_TRUE(read.ok()) << read.status();
  ASSERT_EQ(read->cloud.size(), 3u);
  EXPECT_EQ(0, std::memcmp(read->cloud.data(), cloud.data(), 36));
  const size_t body = pcd.size() - 3 * 16;
  uint32_t packed;
  std::memcpy(&packed, pcd.data() + body + 16 + 12, 4);
  EXPECT_EQ(packed, 0x000080FFu);  // point 1: red 0, green 128, blue 255
}

TEST(ColoredCloudWriterTest, FormatComesFromTheExtension) {
  ColoredCloudFormat format = ColoredCloudFormat::kPcd;
  ASSERT_TRUE(ColoredCloudFormatOf("out/frame.ply", &format).ok());
  EXPECT_EQ(format, ColoredCloudFormat::kPly);
  ASSERT_TRUE(ColoredCloudFormatOf("frame.pcd", &format).ok());
  EXPECT_EQ(format, ColoredCloudFormat::kPcd);
  const absl::Status bad = ColoredCloudFormatOf("frame.xyz", &format);
  EXPECT_EQ(bad.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(bad.message(), HasSubstr("frame.xyz: a colored cloud is written as .ply or .pcd"));
}

}  // namespace
}  // namespace shapeid
