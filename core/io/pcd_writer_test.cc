#include "core/io/pcd_writer.h"

#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <limits>
#include <string>
#include <vector>

#include "absl/strings/str_cat.h"
#include "core/io/io_testing.h"
#include "core/io/pcd_reader.h"
#include "core/io/point_cloud_reader.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"

namespace shapeid {
namespace {

using ::testing::HasSubstr;
using ::testing::StartsWith;

constexpr PcdEncoding kEncodings[] = {PcdEncoding::kAscii, PcdEncoding::kBinary};

const char* EncodingName(PcdEncoding encoding) {
  return encoding == PcdEncoding::kAscii ? "ascii" : "binary";
}

// Floats that a careless text encoding would not bring back: subnormals, negative zero, values
// needing all 9 significant digits, large georeferenced coordinates, and random bit patterns.
// Not +-FLT_MAX: their 9 digits, 3.40282347e+38, parse to a double just above FLT_MAX, which
// the readers reject as not fitting in a float (although it rounds to FLT_MAX).
PointCloud AwkwardCloud() {
  std::vector<float> xyz = {0.0f,
                            -0.0f,
                            1.0f,
                            0.1f,
                            1.0f / 3.0f,
                            16777217.0f,
                            3.40282e38f,
                            -1.17549421e-38f,
                            500000.03f,
                            4000000.5f,
                            -123.456789f,
                            std::numeric_limits<float>::min(),
                            std::numeric_limits<float>::denorm_min()};
  uint64_t state = 12345;
  while (xyz.size() < 3000) {
    state = state * 6364136223846793005ull + 1442695040888963407ull;
    const uint32_t bits = static_cast<uint32_t>(state >> 32);
    float value;
    std::memcpy(&value, &bits, sizeof value);
    if (std::isfinite(value) && std::abs(value) < std::numeric_limits<float>::max()) {
      xyz.push_back(value);
    }
  }
  return PointCloud(std::move(xyz));
}

uint32_t Bits(float value) {
  uint32_t bits;
  std::memcpy(&bits, &value, sizeof bits);
  return bits;
}

void ExpectBitIdentical(const PointCloud& a, const PointCloud& b) {
  ASSERT_EQ(a.size(), b.size());
  for (size_t i = 0; i < a.xyz().size(); ++i) {
    ASSERT_EQ(Bits(a.xyz()[i]), Bits(b.xyz()[i]))
        << "value " << i << ": " << a.xyz()[i] << " came back as " << b.xyz()[i];
  }
}

TEST(PcdWriterTest, HeaderIsPcdV07) {
  const PointCloud cloud{{1, 2, 3}, {4, 5, 6}};
  EXPECT_EQ(EncodePcd(cloud, PcdEncoding::kAscii),
            "# .PCD v0.7 - Point Cloud Data file format\n"
            "VERSION 0.7\n"
            "FIELDS x y z\n"
            "SIZE 4 4 4\n"
            "TYPE F F F\n"
            "COUNT 1 1 1\n"
            "WIDTH 2\n"
            "HEIGHT 1\n"
            "VIEWPOINT 0 0 0 1 0 0 0\n"
            "POINTS 2\n"
            "DATA ascii\n"
            "1 2 3\n"
            "4 5 6\n");
  const std::string binary = EncodePcd(cloud, PcdEncoding::kBinary);
  const std::string header_end = "POINTS 2\nDATA binary\n";
  const size_t data = binary.find(header_end);
  ASSERT_NE(data, std::string::npos);
  EXPECT_EQ(binary.size() - data - header_end.size(), 6 * sizeof(float));
}

TEST(PcdWriterTest, AsciiValuesAreFormattedLikePrintfNineDigits) {
  const PointCloud cloud = AwkwardCloud();
  const std::string text = EncodePcd(cloud, PcdEncoding::kAscii);
  std::string expected;
  char value[32];
  for (size_t i = 0; i < cloud.xyz().size(); ++i) {
    std::snprintf(value, sizeof value, "%.9g", static_cast<double>(cloud.xyz()[i]));
    absl::StrAppend(&expected, value, i % 3 == 2 ? "\n" : " ");
  }
  const std::string header_end = "DATA ascii\n";
  ASSERT_THAT(text, HasSubstr(header_end));
  EXPECT_EQ(text.substr(text.find(header_end) + header_end.size()), expected);
  EXPECT_THAT(text, HasSubstr("\n0 -0 1\n0.100000001 0.333333343 16777216\n"));
}

TEST(PcdWriterTest, RoundTripsBitIdentical) {
  const PointCloud cloud = AwkwardCloud();
  ASSERT_GT(cloud.size(), 900u);
  for (PcdEncoding encoding : kEncodings) {
    SCOPED_TRACE(EncodingName(encoding));
    const absl::StatusOr<ReadResult> parsed =
        ParsePointCloud(EncodePcd(cloud, encoding), CloudFormat::kPcd, "memory.pcd", Raw());
    ASSERT_TRUE(parsed.ok()) << parsed.status();
    ExpectBitIdentical(cloud, parsed->cloud);

    const std::string path = WriteTempFile(absl::StrCat(EncodingName(encoding), ".pcd"), "");
    ASSERT_TRUE(WritePcd(path, cloud, encoding).ok());
    const absl::StatusOr<ReadResult> read = ReadPointCloud(path, Raw());
    ASSERT_TRUE(read.ok()) << read.status();
    ExpectBitIdentical(cloud, read->cloud);
    EXPECT_NE(::access((path + ".tmp").c_str(), F_OK), 0) << "the temporary file was left behind";
  }
}

TEST(PcdWriterTest, BinaryKeepsFloatExtremes) {
  const float max = std::numeric_limits<float>::max();
  const PointCloud cloud{{max, std::numeric_limits<float>::lowest(), 0}};
  const absl::StatusOr<ReadResult> r =
      ParsePcd(EncodePcd(cloud, PcdEncoding::kBinary), "max.pcd", Raw());
  ASSERT_TRUE(r.ok()) << r.status();
  ExpectBitIdentical(cloud, r->cloud);
}

TEST(PcdWriterTest, NonFiniteValuesAreWrittenAsTheyAre) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float inf = std::numeric_limits<float>::infinity();
  const PointCloud cloud{{nan, 1, 2}, {inf, -inf, 3}};
  for (PcdEncoding encoding : kEncodings) {
    SCOPED_TRACE(EncodingName(encoding));
    const absl::StatusOr<ReadResult> r = ParsePcd(EncodePcd(cloud, encoding), "nan.pcd", Raw());
    ASSERT_TRUE(r.ok()) << r.status();
    ASSERT_EQ(r->cloud.size(), 2u);
    EXPECT_TRUE(std::isnan(r->cloud.point(0).x()));
    EXPECT_EQ(r->cloud.point(1), Eigen::Vector3f(inf, -inf, 3));
  }
}

TEST(PcdWriterTest, EmptyCloud) {
  for (PcdEncoding encoding : kEncodings) {
    SCOPED_TRACE(EncodingName(encoding));
    const std::string bytes = EncodePcd(PointCloud(), encoding);
    EXPECT_THAT(bytes, HasSubstr("\nWIDTH 0\n"));
    EXPECT_THAT(bytes, HasSubstr("\nPOINTS 0\n"));
    const absl::StatusOr<ReadResult> r = ParsePcd(bytes, "empty.pcd", Raw());
    ASSERT_TRUE(r.ok()) << r.status();
    EXPECT_TRUE(r->cloud.empty());

    const std::string path =
        WriteTempFile(absl::StrCat("empty_", EncodingName(encoding), ".pcd"), "");
    ASSERT_TRUE(WritePcd(path, PointCloud(), encoding).ok());
    const absl::StatusOr<std::string> written = ReadFileContents(path);
    ASSERT_TRUE(written.ok()) << written.status();
    EXPECT_EQ(*written, bytes);
  }
}

TEST(PcdWriterTest, ReplacesAnExistingFile) {
  const std::string path = WriteTempFile("replace.pcd", std::string(100000, 'x'));
  const PointCloud cloud{{1, 2, 3}};
  ASSERT_TRUE(WritePcd(path, cloud).ok());
  const absl::StatusOr<std::string> written = ReadFileContents(path);
  ASSERT_TRUE(written.ok()) << written.status();
  EXPECT_EQ(*written, EncodePcd(cloud, PcdEncoding::kBinary));
}

TEST(PcdWriterTest, UnwritablePathsGiveClearErrors) {
  const PointCloud cloud{{1, 2, 3}};
  const std::string missing_dir = testing::TempDir() + "shapeid_no_such_dir/out.pcd";
  const absl::Status no_dir = WritePcd(missing_dir, cloud);
  EXPECT_EQ(no_dir.code(), absl::StatusCode::kNotFound) << no_dir;
  EXPECT_THAT(std::string(no_dir.message()), StartsWith(missing_dir + ": cannot create "));
  EXPECT_THAT(std::string(no_dir.message()), HasSubstr(std::strerror(ENOENT)));

  // A directory where the file should go: creating the .tmp works, the rename does not, and
  // the .tmp is removed again.
  const std::string dir =
      testing::TempDir() + "shapeid_pcd_writer_dir_" + std::to_string(::getpid()) + ".pcd";
  ASSERT_EQ(::mkdir(dir.c_str(), 0700), 0) << std::strerror(errno);
  const absl::Status is_dir = WritePcd(dir, cloud);
  EXPECT_FALSE(is_dir.ok());
  EXPECT_THAT(std::string(is_dir.message()), StartsWith(dir + ": cannot rename "));
  EXPECT_NE(::access((dir + ".tmp").c_str(), F_OK), 0);
  ::rmdir(dir.c_str());

  if (::geteuid() != 0) {  // root writes anywhere
    const std::string read_only =
        testing::TempDir() + "shapeid_pcd_writer_ro_" + std::to_string(::getpid());
    ASSERT_EQ(::mkdir(read_only.c_str(), 0500), 0) << std::strerror(errno);
    const absl::Status denied = WritePcd(read_only + "/out.pcd", cloud);
    EXPECT_EQ(denied.code(), absl::StatusCode::kPermissionDenied) << denied;
    EXPECT_THAT(std::string(denied.message()), HasSubstr(std::strerror(EACCES)));
    ::rmdir(read_only.c_str());
  }
}

}  // namespace
}  // namespace shapeid
