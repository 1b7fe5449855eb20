#include "core/io/xyz_reader.h"

#include <cmath>
#include <cstring>
#include <string>

#include "absl/strings/numbers.h"
#include "core/io/io_testing.h"
#include "core/io/point_cloud_reader.h"
#include "core/io/text_lines.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"

namespace shapeid {
namespace {

using ::testing::HasSubstr;

void ExpectPoints(const PointCloud& cloud, std::initializer_list<float> xyz) {
  ASSERT_EQ(cloud.size() * 3, xyz.size());
  size_t i = 0;
  for (float v : xyz) {
    EXPECT_EQ(cloud.xyz()[i], v) << "point " << i / 3 << " coordinate " << i % 3;
    ++i;
  }
}

TEST(XyzReaderTest, SpacesTabsAndCommas) {
  const std::string path =
      WriteTempFile("a.xyz", "1 2 3\n4\t5  6\n7,8,9\n10, 11 ,12\n  13 14 15  \n");
  absl::StatusOr<ReadResult> r = ReadPointCloud(path, Raw());
  ASSERT_TRUE(r.ok()) << r.status();
  ExpectPoints(r->cloud, {1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15});
}

TEST(XyzReaderTest, CommentsBlankLinesExtraColumnsAndCrlf) {
  const std::string path =
      WriteTempFile("b.txt",
                    "# exported by a scanner\r\n\r\n1.5 -2 3e2 255 0 0 label\r\n   \r\n"
                    "# middle comment\r\n4 5 6 # trailing comment\r\n-0.25 +1 .5 1\r\n");
  absl::StatusOr<ReadResult> r = ReadPointCloud(path, Raw());
  ASSERT_TRUE(r.ok()) << r.status();
  ExpectPoints(r->cloud, {1.5f, -2, 300, 4, 5, 6, -0.25f, 1, 0.5f});
}

TEST(XyzReaderTest, CsvWithHeaderLine) {
  const std::string path = WriteTempFile(
      "c.csv", "# comment before the header\nx,y,z,intensity\n1,2,3,0.5\n4,5,6,0.7\n");
  absl::StatusOr<ReadResult> r = ReadPointCloud(path, Raw());
  ASSERT_TRUE(r.ok()) << r.status();
  ExpectPoints(r->cloud, {1, 2, 3, 4, 5, 6});
}

TEST(XyzReaderTest, CsvWithSemicolons) {
  const std::string path = WriteTempFile("s.csv", "\"X\";\"Y\";\"Z\"\n1.5;2;3\n4;5;6.25\n");
  absl::StatusOr<ReadResult> r = ReadPointCloud(path, Raw());
  ASSERT_TRUE(r.ok()) << r.status();
  ExpectPoints(r->cloud, {1.5f, 2, 3, 4, 5, 6.25f});
  // A decimal comma in a semicolon file is an error, not three wrong numbers.
  const std::string comma = WriteTempFile("dc.csv", "1;2;3\n1,5;2;3\n");
  ExpectError(ReadPointCloud(comma, Raw()), absl::StatusCode::kInvalidArgument, comma, "line 2");
}

TEST(XyzReaderTest, HeaderAllowedOnlyFirst) {
  const std::string path = WriteTempFile("h.xyz", "1 2 3\nx y z\n4 5 6\n");
  const absl::StatusOr<ReadResult> r = ReadPointCloud(path, Raw());
  ExpectError(r, absl::StatusCode::kInvalidArgument, path, "line 2");
  EXPECT_THAT(std::string(r.status().message()), HasSubstr("header"));
}

TEST(XyzReaderTest, BadLineInTheMiddle) {
  const std::string path = WriteTempFile("m.xyz", "1 2 3\n4 5 6\n# c\n7 eight 9\n10 11 12\n");
  const absl::StatusOr<ReadResult> r = ReadPointCloud(path, Raw());
  ExpectError(r, absl::StatusCode::kInvalidArgument, path, "line 4");
  EXPECT_THAT(std::string(r.status().message()), HasSubstr("\"eight\""));
}

TEST(XyzReaderTest, TooFewValues) {
  const std::string path = WriteTempFile("f.xyz", "1 2 3\n4 5\n");
  ExpectError(ReadPointCloud(path, Raw()), absl::StatusCode::kInvalidArgument, path, "line 2");
}

TEST(XyzReaderTest, FirstLinePartlyNumericIsAnErrorNotAHeader) {
  const std::string path = WriteTempFile("p.xyz", "1 y 3\n4 5 6\n");
  ExpectError(ReadPointCloud(path, Raw()), absl::StatusCode::kInvalidArgument, path, "line 1");
}

TEST(XyzReaderTest, NonFiniteValues) {
  const std::string path = WriteTempFile("n.xyz", "1 2 3\nnan 0 0\n4 inf 6\n7 8 9\n");
  absl::StatusOr<ReadResult> kept = ReadPointCloud(path);
  ASSERT_TRUE(kept.ok()) << kept.status();
  EXPECT_EQ(kept->cloud.size(), 4u);
  EXPECT_TRUE(std::isnan(kept->cloud.point(1).x()));
  EXPECT_TRUE(std::isinf(kept->cloud.point(2).y()));
  ReadOptions drop;
  drop.drop_non_finite = true;
  absl::StatusOr<ReadResult> dropped = ReadPointCloud(path, drop);
  ASSERT_TRUE(dropped.ok()) << dropped.status();
  EXPECT_EQ(dropped->dropped_non_finite, 2u);
  // Recentered on the finite points only: box (1..7, 2..8, 3..9), center (4, 5, 6).
  EXPECT_EQ(dropped->offset, Eigen::Vector3d(4, 5, 6));
  ExpectPoints(dropped->cloud, {-3, -3, -3, 3, 3, 3});
}

TEST(XyzReaderTest, CoordinateBeyondFloatRangeNamesItsLine) {
  const std::string path = WriteTempFile("big.xyz", "0 0 0\n1 1e39 1\n2 2 2\n");
  ExpectError(ReadPointCloud(path, Raw()), absl::StatusCode::kInvalidArgument, path, "line 2");
  ExpectError(ReadPointCloud(path), absl::StatusCode::kInvalidArgument, path, "line 2");
}

// The text readers' number parser accepts what absl::SimpleAtod accepts, with the same bits.
TEST(XyzReaderTest, NumbersParseAsSimpleAtodParsesThem) {
  for (const char* text : {"0",         "-0",     "+1.5",   "1e5",      "1E-5",
                           ".5",        "5.",     "-.5e+3", "0.1",      "123456789012345678901234",
                           "1e400",     "-1e400", "1e-400", "4.9e-324", "inf",
                           "-Infinity", "nan",    "NaN",    "+-1",      "--1",
                           "0x1p3",     "1.5.5",  "1e",     "e5",       "",
                           " 1",        "1 ",     "1,5",    "abc",      "+",
                           "-",         "."}) {
    double fast = -7, reference = -7;
    const bool ok = ParseDouble(text, &fast);
    EXPECT_EQ(ok, absl::SimpleAtod(text, &reference)) << text;
    if (ok && !std::isnan(reference)) {
      EXPECT_EQ(std::memcmp(&fast, &reference, sizeof fast), 0) << text;
    }
    if (ok && std::isnan(reference)) {
      EXPECT_TRUE(std::isnan(fast)) << text;
    }
  }
}

TEST(XyzReaderTest, EmptyFileIsAnEmptyCloud) {
  const std::string path = WriteTempFile("e.xyz", "# nothing\n\n");
  absl::StatusOr<ReadResult> r = ReadPointCloud(path);
  ASSERT_TRUE(r.ok()) << r.status();
  EXPECT_TRUE(r->cloud.empty());
  EXPECT_EQ(r->offset, Eigen::Vector3d::Zero());
}

TEST(XyzReaderTest, EveryTruncationIsHandled) {
  const std::string file = "x,y,z\n1,2,3\n4 5 6 7\n# end\n";
  for (size_t n = 0; n <= file.size(); ++n) {
    const std::string prefix = file.substr(0, n);
    const absl::StatusOr<ReadResult> r = ParseXyz(prefix, "prefix.csv", TextDialect::kCsv);
    if (!r.ok()) {
      EXPECT_THAT(std::string(r.status().message()), HasSubstr("prefix.csv"));
    }
  }
}

}  // namespace
}  // namespace shapeid
