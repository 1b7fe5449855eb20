#include "core/io/pcd_reader.h"

#include <lzf.h>

#include <cmath>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "absl/strings/str_cat.h"
#include "core/io/io_testing.h"
#include "core/io/point_cloud_reader.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"

namespace shapeid {
namespace {

using ::testing::HasSubstr;

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();

std::string XyzHeader(int points, absl::string_view data) {
  return absl::StrCat("# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\n",
                      "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\n", "WIDTH ", points,
                      "\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\n", "POINTS ", points, "\nDATA ", data,
                      "\n");
}

std::string XyzBinary(std::initializer_list<float> xyz) {
  std::string file = XyzHeader(static_cast<int>(xyz.size() / 3), "binary");
  for (float v : xyz) AppendBytes(&file, v);
  return file;
}

void ExpectPoint(const PointCloud& cloud, size_t i, float x, float y, float z) {
  ASSERT_LT(i, cloud.size());
  EXPECT_EQ(cloud.point(i).x(), x) << "point " << i;
  EXPECT_EQ(cloud.point(i).y(), y) << "point " << i;
  EXPECT_EQ(cloud.point(i).z(), z) << "point " << i;
}

TEST(PcdReaderTest, AsciiWithExtraFieldsAndPadding) {
  const std::string path = WriteTempFile("a.pcd",
                                         "VERSION .7\n"
                                         "FIELDS normal_x x y _ z rgb\n"
                                         "SIZE 4 4 4 1 4 4\n"
                                         "TYPE F F F U F U\n"
                                         "COUNT 1 1 1 3 1 1\n"
                                         "WIDTH 2\nHEIGHT 1\nPOINTS 2\n"
                                         "DATA ascii\n"
                                         "0.5 1 2 0 0 0 3 4278190080\n"
                                         "-0.5 -1.25 2.5e1 7 7 7 nan 16711680\n");
  absl::StatusOr<ReadResult> r = ReadPointCloud(path, Raw());
  ASSERT_TRUE(r.ok()) << r.status();
  ASSERT_EQ(r->cloud.size(), 2u);
  ExpectPoint(r->cloud, 0, 1, 2, 3);
  EXPECT_EQ(r->cloud.point(1).x(), -1.25f);
  EXPECT_EQ(r->cloud.point(1).y(), 25.0f);
  EXPECT_TRUE(std::isnan(r->cloud.point(1).z()));
}

TEST(PcdReaderTest, BinaryWithExtraFieldsAndPadding) {
  // Coordinates behind fields of odd sizes, so their offsets are not multiples of 4.
  std::string file =
      "VERSION 0.7\nFIELDS intensity x _ y normal_x normal_y normal_z z label\n"
      "SIZE 2 4 1 4 4 4 4 4 8\nTYPE U F I F F F F F I\nCOUNT 1 1 3 1 1 1 1 1 2\n"
      "WIDTH 3\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS 3\nDATA binary\n";
  for (int i = 0; i < 3; ++i) {
    AppendBytes<uint16_t>(&file, 7);
    AppendBytes<float>(&file, 1.5f * i);
    file.append(3, '\xff');
    AppendBytes<float>(&file, -2.0f * i);
    for (int k = 0; k < 3; ++k) AppendBytes<float>(&file, kNaN);
    AppendBytes<float>(&file, 100.0f + i);
    AppendBytes<int64_t>(&file, -1);
    AppendBytes<int64_t>(&file, -1);
  }
  const std::string path = WriteTempFile("b.pcd", file);
  absl::StatusOr<ReadResult> r = ReadPointCloud(path, Raw());
  ASSERT_TRUE(r.ok()) << r.status();
  ASSERT_EQ(r->cloud.size(), 3u);
  for (int i = 0; i < 3; ++i) ExpectPoint(r->cloud, i, 1.5f * i, -2.0f * i, 100.0f + i);
}

TEST(PcdReaderTest, DoubleCoordinatesBinaryAndAscii) {
  std::string header =
      "FIELDS x y z\nSIZE 8 8 8\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 2\nHEIGHT 1\nPOINTS 2\n";
  std::string binary = header + "DATA binary\n";
  for (double v : {0.1, 0.2, 0.3, 1e10, -1e-10, 3.0}) AppendBytes(&binary, v);
  const std::string ascii = header + "DATA ascii\n0.1 0.2 0.3\n1e10 -1e-10 3\n";
  for (const std::string& file : {binary, ascii}) {
    const std::string path = WriteTempFile("d.pcd", file);
    absl::StatusOr<ReadResult> r = ReadPointCloud(path, Raw());
    ASSERT_TRUE(r.ok()) << r.status();
    ASSERT_EQ(r->cloud.size(), 2u);
    ExpectPoint(r->cloud, 0, 0.1f, 0.2f, 0.3f);
    ExpectPoint(r->cloud, 1, 1e10f, -1e-10f, 3.0f);
  }
}

TEST(PcdReaderTest, CommentsBlankLinesAndCrlf) {
  const std::string path =
      WriteTempFile("c.pcd",
                    "# written on Windows\r\n\r\nVERSION 0.7\r\nFIELDS x y z # trailing comment\r\n"
                    "SIZE 4 4 4\r\nTYPE F F F\r\nCOUNT 1 1 1\r\nWIDTH 1\r\nHEIGHT 1\r\nPOINTS 1\r\n"
                    "DATA ascii\r\n1 2 3\r\n\r\n");
  absl::StatusOr<ReadResult> r = ReadPointCloud(path, Raw());
  ASSERT_TRUE(r.ok()) << r.status();
  ASSERT_EQ(r->cloud.size(), 1u);
  ExpectPoint(r->cloud, 0, 1, 2, 3);
}

TEST(PcdReaderTest, OrganisedCloudKeepsNaNPointsByDefault) {
  std::string file =
      "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\n"
      "WIDTH 3\nHEIGHT 2\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS 6\nDATA binary\n";
  const float xyz[] = {0, 0, 0, kNaN, kNaN, kNaN, 1, 0, 0, 0, 1, 0, 0, 0, 1, kNaN, kNaN, kNaN};
  for (float v : xyz) AppendBytes(&file, v);
  const std::string path = WriteTempFile("o.pcd", file);

  absl::StatusOr<ReadResult> kept = ReadPointCloud(path, Raw());
  ASSERT_TRUE(kept.ok()) << kept.status();
  EXPECT_EQ(kept->cloud.size(), 6u);
  EXPECT_EQ(kept->dropped_non_finite, 0u);
  EXPECT_TRUE(std::isnan(kept->cloud.point(1).x()));
  // The descriptor then reports the NaN instead of describing a part of the cloud.
  EXPECT_EQ(ValidateCloud(kept->cloud).status().code(), absl::StatusCode::kInvalidArgument);

  ReadOptions drop = Raw();
  drop.drop_non_finite = true;
  absl::StatusOr<ReadResult> dropped = ReadPointCloud(path, drop);
  ASSERT_TRUE(dropped.ok()) << dropped.status();
  EXPECT_EQ(dropped->dropped_non_finite, 2u);
  ASSERT_EQ(dropped->cloud.size(), 4u);
  ExpectPoint(dropped->cloud, 0, 0, 0, 0);
  ExpectPoint(dropped->cloud, 1, 1, 0, 0);
  ExpectPoint(dropped->cloud, 2, 0, 1, 0);
  ExpectPoint(dropped->cloud, 3, 0, 0, 1);
  EXPECT_TRUE(ValidateCloud(dropped->cloud).ok());
  // Both report what they found, so that no caller scans the cloud again: the first NaN point
  // is the second record, 12 bytes after the data starts.
  const size_t data = file.find("DATA binary\n") + 12;
  for (const ReadResult* r : {&*kept, &*dropped}) {
    EXPECT_EQ(r->non_finite_points, 2u);
    EXPECT_EQ(r->first_non_finite, 1u);
    EXPECT_EQ(r->first_non_finite_location, absl::StrCat("byte offset ", data + 12));
  }
}

TEST(PcdReaderTest, DoubleCoordinatesThatDoNotFitAFloatNameTheirByteOffset) {
  std::string file =
      "VERSION 0.7\nFIELDS x y z\nSIZE 8 8 8\nTYPE F F F\nCOUNT 1 1 1\n"
      "WIDTH 2\nHEIGHT 1\nPOINTS 2\nDATA binary\n";
  const size_t data = file.size();
  for (double v : {0.0, 0.0, 0.0, 1e300, 0.0, 0.0}) AppendBytes(&file, v);
  const absl::StatusOr<ReadResult> r = ParsePcd(file, "far.pcd", Raw());
  ExpectError(r, absl::StatusCode::kInvalidArgument, "far.pcd",
              absl::StrCat("byte offset ", data + 24, ": x = 1e+300 does not fit in a float"));
}

TEST(PcdReaderTest, NoPointsIsAnEmptyCloud) {
  const std::string path = WriteTempFile("e.pcd", XyzHeader(0, "binary"));
  absl::StatusOr<ReadResult> r = ReadPointCloud(path);
  ASSERT_TRUE(r.ok()) << r.status();
  EXPECT_TRUE(r->cloud.empty());
}

TEST(PcdReaderTest, OlderHeaderWithoutCountHeightAndPoints) {
  const std::string path =
      WriteTempFile("v6.pcd", "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 1\nDATA ascii\n1 2 3\n");
  absl::StatusOr<ReadResult> r = ReadPointCloud(path, Raw());
  ASSERT_TRUE(r.ok()) << r.status();
  ExpectPoint(r->cloud, 0, 1, 2, 3);
}

// --- Malformed files: every error names the file and where.

TEST(PcdReaderTest, UnknownHeaderKeyword) {
  const std::string path = WriteTempFile(
      "k.pcd", "VERSION 0.7\nFIELDS x y z\nSIZES 4 4 4\nTYPE F F F\nWIDTH 1\nDATA ascii\n1 2 3\n");
  ExpectError(ReadPointCloud(path), absl::StatusCode::kInvalidArgument, path, "line 3");
}

TEST(PcdReaderTest, NotAPcdFile) {
  std::string junk =
      "\x7f"
      "ELF\x02\x01\x01";
  junk.append(200, '\0');
  const std::string path = WriteTempFile("junk.pcd", junk);
  ExpectError(ReadPointCloud(path), absl::StatusCode::kInvalidArgument, path, "line 1");
  const std::string empty = WriteTempFile("empty.pcd", "");
  ExpectError(ReadPointCloud(empty), absl::StatusCode::kInvalidArgument, empty, "no DATA line");
}

TEST(PcdReaderTest, SizeCountDoesNotMatchFields) {
  const std::string path =
      WriteTempFile("s.pcd", "FIELDS x y z\nSIZE 4 4\nTYPE F F F\nWIDTH 1\nDATA ascii\n1 2 3\n");
  ExpectError(ReadPointCloud(path), absl::StatusCode::kInvalidArgument, path, "line 2");
}

TEST(PcdReaderTest, BadSizeAndType) {
  const std::string size3 =
      WriteTempFile("s3.pcd", "FIELDS x y z\nSIZE 4 4 3\nTYPE F F F\nWIDTH 1\nDATA ascii\n1 2 3\n");
  ExpectError(ReadPointCloud(size3), absl::StatusCode::kInvalidArgument, size3, "line 2");
  const std::string type_q =
      WriteTempFile("tq.pcd", "FIELDS x y z\nSIZE 4 4 4\nTYPE F F Q\nWIDTH 1\nDATA ascii\n1 2 3\n");
  ExpectError(ReadPointCloud(type_q), absl::StatusCode::kInvalidArgument, type_q, "line 3");
  const std::string f2 =
      WriteTempFile("f2.pcd", "FIELDS x y z\nSIZE 4 4 2\nTYPE F F F\nWIDTH 1\nDATA ascii\n1 2 3\n");
  ExpectError(ReadPointCloud(f2), absl::StatusCode::kInvalidArgument, f2, "line 3");
}

TEST(PcdReaderTest, MissingXField) {
  const std::string path =
      WriteTempFile("nx.pcd",
                    "VERSION 0.7\nFIELDS y z rgb\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\n"
                    "WIDTH 1\nHEIGHT 1\nPOINTS 1\nDATA ascii\n1 2 3\n");
  ExpectError(ReadPointCloud(path), absl::StatusCode::kInvalidArgument, path, "line 2");
  EXPECT_THAT(std::string(ReadPointCloud(path).status().message()), HasSubstr("\"x\""));
}

TEST(PcdReaderTest, IntegerCoordinatesAreUnimplemented) {
  const std::string path =
      WriteTempFile("ix.pcd", "FIELDS x y z\nSIZE 4 4 4\nTYPE I F F\nWIDTH 1\nDATA ascii\n1 2 3\n");
  ExpectError(ReadPointCloud(path), absl::StatusCode::kUnimplemented, path, "line 3");
}

TEST(PcdReaderTest, TruncatedBinaryData) {
  std::string file = XyzBinary({1, 2, 3, 4, 5, 6, 7, 8, 9});
  const size_t data_start = file.size() - 36;
  file.resize(file.size() - 16);
  const std::string path = WriteTempFile("t.pcd", file);
  const absl::StatusOr<ReadResult> r = ReadPointCloud(path);
  ExpectError(r, absl::StatusCode::kInvalidArgument, path,
              absl::StrCat("byte offset ", data_start));
  EXPECT_THAT(std::string(r.status().message()), HasSubstr("expected 36 bytes"));
  EXPECT_THAT(std::string(r.status().message()), HasSubstr("found 20"));
}

TEST(PcdReaderTest, PointsDoesNotMatchWidthTimesHeight) {
  const std::string path =
      WriteTempFile("p.pcd",
                    "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\n"
                    "WIDTH 2\nHEIGHT 2\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS 3\nDATA ascii\n"
                    "1 2 3\n4 5 6\n7 8 9\n");
  ExpectError(ReadPointCloud(path), absl::StatusCode::kInvalidArgument, path, "line 9");
}

TEST(PcdReaderTest, NonNumericAsciiValue) {
  const std::string path =
      WriteTempFile("n.pcd", XyzHeader(3, "ascii") + "1 2 3\n4 five 6\n7 8 9\n");
  // The header is 11 lines; the bad point is the second data line.
  ExpectError(ReadPointCloud(path), absl::StatusCode::kInvalidArgument, path, "line 13");
}

TEST(PcdReaderTest, WrongNumberOfAsciiValues) {
  const std::string path = WriteTempFile("w.pcd", XyzHeader(2, "ascii") + "1 2 3\n4 5\n");
  ExpectError(ReadPointCloud(path), absl::StatusCode::kInvalidArgument, path, "line 13");
}

TEST(PcdReaderTest, AsciiPointCountDiffersFromHeader) {
  const std::string few = WriteTempFile("few.pcd", XyzHeader(3, "ascii") + "1 2 3\n4 5 6\n");
  ExpectError(ReadPointCloud(few), absl::StatusCode::kInvalidArgument, few, "ends after 2 points");
  const std::string many = WriteTempFile("many.pcd", XyzHeader(1, "ascii") + "1 2 3\n4 5 6\n");
  ExpectError(ReadPointCloud(many), absl::StatusCode::kInvalidArgument, many, "line 13");
}

TEST(PcdReaderTest, HugePointCountDoesNotAllocate) {
  const std::string path =
      WriteTempFile("huge.pcd",
                    "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 4000000000000000000\n"
                    "DATA ascii\n1 2 3\n");
  ExpectError(ReadPointCloud(path), absl::StatusCode::kInvalidArgument, path,
              "ends after 1 points");
  const std::string binary =
      WriteTempFile("hugeb.pcd",
                    "FIELDS x y z\nSIZE 8 8 8\nTYPE F F F\nWIDTH 4000000000000000000\n"
                    "DATA binary\n");
  ExpectError(ReadPointCloud(binary), absl::StatusCode::kInvalidArgument, binary, "truncated");
}

TEST(PcdReaderTest, UnknownDataKind) {
  const std::string path = WriteTempFile("u.pcd", XyzHeader(1, "binary_packed") + "123456789012");
  ExpectError(ReadPointCloud(path), absl::StatusCode::kInvalidArgument, path, "line 11");
}

// A binary_compressed file as PCL writes it: fields intensity (U2), x, _ (3 padding bytes),
// y (F8), z, each stored for all points before the next (SoA), then LZF-compressed.
std::string CompressedFile(const std::vector<float>& xyz) {
  const size_t n = xyz.size() / 3;
  std::string soa;
  for (size_t i = 0; i < n; ++i) AppendBytes<uint16_t>(&soa, 7);
  for (size_t i = 0; i < n; ++i) AppendBytes<float>(&soa, xyz[3 * i]);
  soa.append(3 * n, '\x5a');
  for (size_t i = 0; i < n; ++i) AppendBytes<double>(&soa, xyz[3 * i + 1]);
  for (size_t i = 0; i < n; ++i) AppendBytes<float>(&soa, xyz[3 * i + 2]);
  std::string block(soa.size() + 64, '\0');
  const unsigned int size = lzf_compress(soa.data(), static_cast<unsigned int>(soa.size()),
                                         block.data(), static_cast<unsigned int>(block.size()));
  EXPECT_GT(size, 0u);
  block.resize(size);
  std::string file = absl::StrCat(
      "VERSION 0.7\nFIELDS intensity x _ y z\nSIZE 2 4 1 8 4\nTYPE U F U F F\n"
      "COUNT 1 1 3 1 1\nWIDTH ",
      n, "\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS ", n, "\nDATA binary_compressed\n");
  AppendBytes<uint32_t>(&file, size);
  AppendBytes<uint32_t>(&file, static_cast<uint32_t>(soa.size()));
  return file + block;
}

std::vector<float> RepetitiveXyz(size_t n) {
  std::vector<float> xyz;
  for (size_t i = 0; i < n; ++i) {
    xyz.push_back(static_cast<float>(i % 10));
    xyz.push_back(-0.5f * static_cast<float>(i % 3));
    xyz.push_back(1000.25f);
  }
  return xyz;
}

TEST(PcdReaderTest, BinaryCompressedWithExtraFieldsAndPadding) {
  const std::vector<float> xyz = RepetitiveXyz(500);
  const std::string file = CompressedFile(xyz);
  const std::string path = WriteTempFile("bc.pcd", file);
  absl::StatusOr<ReadResult> r = ReadPointCloud(path, Raw());
  ASSERT_TRUE(r.ok()) << r.status();
  ASSERT_EQ(r->cloud.size(), 500u);
  for (size_t i = 0; i < 500; i += 37) {
    ExpectPoint(r->cloud, i, xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2]);
  }
  EXPECT_LT(file.size(), 500u * 23);  // it really is compressed
}

TEST(PcdReaderTest, BinaryCompressedEmptyCloud) {
  std::string file = XyzHeader(0, "binary_compressed");
  const absl::StatusOr<ReadResult> bare = ParsePcd(file, "e.pcd");
  ASSERT_TRUE(bare.ok()) << bare.status();
  AppendBytes<uint32_t>(&file, 0);
  AppendBytes<uint32_t>(&file, 0);
  const absl::StatusOr<ReadResult> sized = ParsePcd(file, "e.pcd");
  ASSERT_TRUE(sized.ok()) << sized.status();
  EXPECT_EQ(sized->cloud.size(), 0u);
}

TEST(PcdReaderTest, BinaryCompressedErrorsNameTheByteOffset) {
  const std::string file = CompressedFile(RepetitiveXyz(50));
  const size_t data = file.find("binary_compressed\n") + 18;
  // Truncated block.
  const std::string cut = WriteTempFile("cut.pcd", file.substr(0, file.size() - 3));
  ExpectError(ReadPointCloud(cut), absl::StatusCode::kInvalidArgument, cut,
              absl::StrCat("byte offset ", data + 8, ": compressed data is truncated"));
  // Sizes cut short.
  const std::string sizes = WriteTempFile("sizes.pcd", file.substr(0, data + 5));
  ExpectError(ReadPointCloud(sizes), absl::StatusCode::kInvalidArgument, sizes,
              absl::StrCat("byte offset ", data));
  // Uncompressed size disagrees with the header.
  std::string wrong = file;
  wrong[data + 4] = static_cast<char>(wrong[data + 4] + 1);
  const std::string wrong_path = WriteTempFile("wrong.pcd", wrong);
  ExpectError(ReadPointCloud(wrong_path), absl::StatusCode::kInvalidArgument, wrong_path,
              absl::StrCat("byte offset ", data + 4, ": uncompressed size"));
  // Corrupt LZF block: a back reference before the start of the output.
  std::string corrupt = file;
  corrupt[data + 8] = '\xe0';
  corrupt[data + 9] = '\xff';
  const std::string corrupt_path = WriteTempFile("corrupt.pcd", corrupt);
  ExpectError(ReadPointCloud(corrupt_path), absl::StatusCode::kInvalidArgument, corrupt_path,
              absl::StrCat("byte offset ", data + 8, ": the LZF block is corrupt"));
  // A size LZF cannot reach is refused before allocating it.
  std::string forged = XyzHeader(400000000, "binary_compressed");
  AppendBytes<uint32_t>(&forged, 4);
  AppendBytes<uint32_t>(&forged, 4800000000u % (1ull << 32));
  forged += "abcd";
  EXPECT_FALSE(ParsePcd(forged, "forged.pcd").ok());
}

TEST(PcdReaderTest, DuplicateKeywordAndMissingWidth) {
  const std::string dup = WriteTempFile(
      "dup.pcd",
      "FIELDS x y z\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 1\nDATA ascii\n1 2 3\n");
  ExpectError(ReadPointCloud(dup), absl::StatusCode::kInvalidArgument, dup, "line 2");
  const std::string nowidth =
      WriteTempFile("nw.pcd", "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nDATA ascii\n1 2 3\n");
  ExpectError(ReadPointCloud(nowidth), absl::StatusCode::kInvalidArgument, nowidth, "WIDTH");
}

// Every prefix of a valid file is either read or rejected; none crashes or reads past the end
// (run under ASan).
TEST(PcdReaderTest, EveryTruncationIsHandled) {
  std::string binary = XyzBinary({1, 2, 3, 4, 5, 6});
  std::string ascii = XyzHeader(2, "ascii") + "1 2 3\n4 5 6\n";
  std::string compressed = CompressedFile({1, 2, 3, 4, 5, 6});
  for (const std::string& file : {binary, ascii, compressed}) {
    for (size_t n = 0; n <= file.size(); ++n) {
      // Parse from a heap copy of exactly n bytes, so ASan sees any overrun.
      const std::string prefix = file.substr(0, n);
      const absl::StatusOr<ReadResult> r = ParsePcd(prefix, "prefix.pcd");
      if (r.ok()) {
        EXPECT_EQ(r->cloud.size(), 2u);
      } else {
        EXPECT_THAT(std::string(r.status().message()), HasSubstr("prefix.pcd"));
      }
    }
  }
}

// Random byte corruptions of valid files: read or rejected, never a crash (run under ASan).
TEST(PcdReaderTest, RandomCorruptionsAreHandled) {
  const std::string files[] = {
      XyzBinary({1, 2, 3, 4, 5, 6, 7, 8, 9}),
      XyzHeader(3, "ascii") + "1 2 3\n4 5 6\n7 8 9\n",
      CompressedFile(RepetitiveXyz(40)),
  };
  const char replacements[] = "0123456789 \n.-eFIUxyz#\xff";
  std::mt19937 rng(12345);
  for (const std::string& file : files) {
    for (int trial = 0; trial < 3000; ++trial) {
      std::string corrupt = file;
      const int edits = 1 + static_cast<int>(rng() % 4);
      for (int e = 0; e < edits; ++e) {
        corrupt[rng() % corrupt.size()] = replacements[rng() % (sizeof replacements - 1)];
      }
      const absl::StatusOr<ReadResult> r = ParsePcd(corrupt, "corrupt.pcd");
      if (!r.ok()) {
        EXPECT_THAT(std::string(r.status().message()), HasSubstr("corrupt.pcd"));
      }
    }
  }
}

}  // namespace
}  // namespace shapeid
