#include "core/io/las_reader.h"

#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <string>
#include <tuple>
#include <vector>

#include "absl/strings/str_cat.h"
#include "core/io/io_testing.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"

namespace shapeid {
namespace {

using ::testing::HasSubstr;

constexpr uint16_t kFormatSize[11] = {20, 28, 26, 34, 57, 63, 30, 36, 38, 59, 67};

// What the test writer puts in a LAS file. Records are X, Y, Z then `extra` bytes beyond the
// format's size, all filled with 0xAB so that a reader reading the wrong bytes sees garbage.
struct LasSpec {
  int minor = 2;
  uint8_t format = 0;
  uint16_t extra = 0;
  double scale[3] = {0.01, 0.01, 0.01};
  double offset[3] = {500000, 4000000, 100};
  std::vector<std::array<int32_t, 3>> points;
  size_t vlr_bytes = 0;       // junk between the header and the points
  size_t trailing_bytes = 0;  // junk after the points (EVLRs, waveforms)
  bool legacy_count = true;   // false writes 0 in the 32-bit count (LAS 1.4 style)
};

template <typename T>
void Put(std::string* file, size_t at, T value) {
  std::memcpy(&(*file)[at], &value, sizeof(T));
}

size_t HeaderSize(int minor) { return minor >= 4 ? 375 : minor == 3 ? 235 : 227; }

std::string WriteLas(const LasSpec& spec) {
  const size_t header_size = HeaderSize(spec.minor);
  const uint16_t record_length = kFormatSize[spec.format] + spec.extra;
  std::string file(header_size, '\0');
  std::memcpy(&file[0], "LASF", 4);
  Put<uint8_t>(&file, 24, 1);
  Put<uint8_t>(&file, 25, static_cast<uint8_t>(spec.minor));
  std::memcpy(&file[26], "shapeid test", 12);
  Put<uint16_t>(&file, 94, static_cast<uint16_t>(header_size));
  Put<uint32_t>(&file, 96, static_cast<uint32_t>(header_size + spec.vlr_bytes));
  Put<uint8_t>(&file, 104, spec.format);
  Put<uint16_t>(&file, 105, record_length);
  const uint64_t n = spec.points.size();
  Put<uint32_t>(&file, 107, spec.legacy_count ? static_cast<uint32_t>(n) : 0);
  for (int a = 0; a < 3; ++a) {
    Put<double>(&file, 131 + 8 * a, spec.scale[a]);
    Put<double>(&file, 155 + 8 * a, spec.offset[a]);
  }
  if (spec.minor >= 4) Put<uint64_t>(&file, 247, n);
  file.append(spec.vlr_bytes, '\x5a');
  for (const auto& p : spec.points) {
    for (int32_t v : p) AppendBytes(&file, v);
    file.append(record_length - 12, '\xab');
  }
  file.append(spec.trailing_bytes, '\x5a');
  return file;
}

const std::vector<std::array<int32_t, 3>> kPoints = {
    {12345, -6789, 250}, {-1, 0, 1}, {2000000000, -2000000000, 0}, {77, 88, 99}};

// The coordinate the file means, in double, as LAS defines it.
double Coordinate(const LasSpec& spec, size_t i, int a) {
  return spec.points[i][a] * spec.scale[a] + spec.offset[a];
}

void ExpectRawPoints(const LasSpec& spec, const ReadResult& r) {
  ASSERT_EQ(r.cloud.size(), spec.points.size());
  EXPECT_EQ(r.offset, Eigen::Vector3d::Zero());
  for (size_t i = 0; i < spec.points.size(); ++i) {
    for (int a = 0; a < 3; ++a) {
      EXPECT_EQ(r.cloud.point(i)[a], static_cast<float>(Coordinate(spec, i, a)))
          << "point " << i << " axis " << a;
    }
  }
}

struct VersionFormat {
  int minor;
  uint8_t format;
};

TEST(LasReaderTest, ExactCoordinatesAcrossVersionsAndFormatsWithExtraBytes) {
  const VersionFormat cases[] = {{0, 0}, {2, 1}, {2, 3}, {3, 5}, {4, 6}, {4, 7}, {4, 10}};
  for (const VersionFormat& c : cases) {
    for (uint16_t extra : {0, 5}) {
      LasSpec spec;
      spec.minor = c.minor;
      spec.format = c.format;
      spec.extra = extra;
      spec.points = kPoints;
      SCOPED_TRACE(absl::StrCat("LAS 1.", c.minor, " format ", c.format, " extra ", extra));
      const absl::StatusOr<ReadResult> r = ParseLas(WriteLas(spec), "a.las", Raw());
      ASSERT_TRUE(r.ok()) << r.status();
      ExpectRawPoints(spec, *r);
    }
  }
}

TEST(LasReaderTest, EveryPointFormatInLas14) {
  for (uint8_t format = 0; format <= 10; ++format) {
    LasSpec spec;
    spec.minor = 4;
    spec.format = format;
    spec.points = kPoints;
    SCOPED_TRACE(absl::StrCat("format ", format));
    const absl::StatusOr<ReadResult> r = ParseLas(WriteLas(spec), "f.las", Raw());
    ASSERT_TRUE(r.ok()) << r.status();
    ExpectRawPoints(spec, *r);
  }
}

TEST(LasReaderTest, KnownValuesWithoutRecentering) {
  LasSpec spec;
  spec.points = {{12345, -6789, 250}};
  const absl::StatusOr<ReadResult> r = ParseLas(WriteLas(spec), "k.las", Raw());
  ASSERT_TRUE(r.ok()) << r.status();
  ASSERT_EQ(r->cloud.size(), 1u);
  EXPECT_EQ(r->cloud.point(0).x(), 500123.45f);
  EXPECT_EQ(r->cloud.point(0).y(), 3999932.11f);
  EXPECT_EQ(r->cloud.point(0).z(), 102.5f);
}

TEST(LasReaderTest, GeoreferencedCoordinatesKeepCentimetresAfterRecentering) {
  // Centimetre steps around (500000, 4000000, 100), where a float's spacing is 3 to 25 cm.
  LasSpec spec;
  spec.points = {{1, 2, 3}, {2, 3, 4}, {10001, -20002, 3}, {5003, 7, -999}, {-4321, 12345, 1001}};
  const std::string file = WriteLas(spec);
  const absl::StatusOr<ReadResult> r = ParseLas(file, "geo.las");
  ASSERT_TRUE(r.ok()) << r.status();
  ASSERT_EQ(r->cloud.size(), spec.points.size());
  // The offset is the bounding-box center: x in [499956.79, 500100.01], and so on.
  EXPECT_NEAR(r->offset.x(), (499956.79 + 500100.01) / 2, 1e-9);
  EXPECT_NEAR(r->offset.y(), (3999799.98 + 4000123.45) / 2, 1e-9);
  EXPECT_NEAR(r->offset.z(), (90.01 + 110.01) / 2, 1e-9);
  for (size_t i = 0; i < spec.points.size(); ++i) {
    for (int a = 0; a < 3; ++a) {
      EXPECT_NEAR(r->cloud.point(i)[a] + r->offset[a], Coordinate(spec, i, a), 1e-4)
          << "point " << i << " axis " << a;
    }
  }
  // The first two points are 1 cm apart on each axis, and stay so.
  for (int a = 0; a < 3; ++a) {
    EXPECT_NEAR(r->cloud.point(1)[a] - r->cloud.point(0)[a], 0.01, 1e-5) << "axis " << a;
  }
  // Without recentering, float rounding merges them.
  const absl::StatusOr<ReadResult> raw = ParseLas(file, "geo.las", Raw());
  ASSERT_TRUE(raw.ok()) << raw.status();
  EXPECT_EQ(raw->cloud.point(1).y(), raw->cloud.point(0).y());
}

TEST(LasReaderTest, VlrsBeforeAndEvlrsAfterThePointsAreSkipped) {
  LasSpec spec;
  spec.minor = 4;
  spec.format = 7;
  spec.extra = 3;
  spec.points = kPoints;
  spec.vlr_bytes = 54 + 40;
  spec.trailing_bytes = 60 + 100;
  const absl::StatusOr<ReadResult> r = ParseLas(WriteLas(spec), "v.las", Raw());
  ASSERT_TRUE(r.ok()) << r.status();
  ExpectRawPoints(spec, *r);
}

TEST(LasReaderTest, Las14UsesThe64BitCount) {
  // Format 6 and above: the legacy count must be 0; the 64-bit one counts.
  LasSpec spec;
  spec.minor = 4;
  spec.format = 6;
  spec.points = kPoints;
  spec.legacy_count = false;
  absl::StatusOr<ReadResult> r = ParseLas(WriteLas(spec), "c.las", Raw());
  ASSERT_TRUE(r.ok()) << r.status();
  ExpectRawPoints(spec, *r);

  // Format 6 and above: the 64-bit count wins over a legacy count a writer left set.
  std::string file = WriteLas(spec);
  Put<uint32_t>(&file, 107, 1);
  r = ParseLas(file, "c.las", Raw());
  ASSERT_TRUE(r.ok()) << r.status();
  ExpectRawPoints(spec, *r);

  // A legacy format in LAS 1.4 whose legacy count is 0 (over 2^32 points, or a lazy writer).
  spec.format = 1;
  r = ParseLas(WriteLas(spec), "c.las", Raw());
  ASSERT_TRUE(r.ok()) << r.status();
  ExpectRawPoints(spec, *r);

  // A legacy format with its legacy count set: that count is read.
  file = WriteLas(spec);
  Put<uint32_t>(&file, 107, 2);
  r = ParseLas(file, "c.las", Raw());
  ASSERT_TRUE(r.ok()) << r.status();
  EXPECT_EQ(r->cloud.size(), 2u);
}

TEST(LasReaderTest, NoPointsIsAnEmptyCloud) {
  for (int minor : {0, 4}) {
    LasSpec spec;
    spec.minor = minor;
    const absl::StatusOr<ReadResult> r = ParseLas(WriteLas(spec), "e.las");
    ASSERT_TRUE(r.ok()) << r.status();
    EXPECT_TRUE(r->cloud.empty());
    EXPECT_EQ(r->offset, Eigen::Vector3d::Zero());
  }
}

TEST(LasReaderTest, LazIsRefusedWithTheCommandThatDecompressesIt) {
  LasSpec spec;
  spec.format = 3;
  spec.points = kPoints;
  for (uint8_t bits : {0x80, 0x40, 0xC0}) {
    std::string file = WriteLas(spec);
    Put<uint8_t>(&file, 104, static_cast<uint8_t>(3 | bits));
    const absl::StatusOr<ReadResult> r = ParseLas(file, "in.las", Raw());
    ExpectError(r, absl::StatusCode::kUnimplemented, "in.las", "byte offset 104: ");
    EXPECT_THAT(std::string(r.status().message()), HasSubstr("LAZ"));
    EXPECT_THAT(std::string(r.status().message()), HasSubstr("laszip -i in.laz -o out.las"));
    EXPECT_THAT(std::string(r.status().message()), HasSubstr("pdal translate in.laz out.las"));
  }
}

TEST(LasReaderTest, NotLasSignature) {
  std::string file = WriteLas(LasSpec{});
  file[3] = 'X';
  ExpectError(ParseLas(file, "s.las"), absl::StatusCode::kInvalidArgument, "s.las",
              "byte offset 0: not a LAS file: expected the signature \"LASF\", found \"LASX\"");
  ExpectError(ParseLas("", "s.las"), absl::StatusCode::kInvalidArgument, "s.las", "found \"\"");
  ExpectError(ParseLas("PK\x03\x04 zip", "s.las"), absl::StatusCode::kInvalidArgument, "s.las",
              "found \"PK\\x03\\x04\"");
}

TEST(LasReaderTest, FileShorterThanTheHeader) {
  const std::string file = WriteLas(LasSpec{}).substr(0, 200);
  ExpectError(ParseLas(file, "short.las"), absl::StatusCode::kInvalidArgument, "short.las",
              "byte offset 200: the file ends after 200 bytes, inside the 227-byte LAS header");
}

TEST(LasReaderTest, UnsupportedVersions) {
  for (const auto& [major, minor, text] :
       {std::tuple<uint8_t, uint8_t, const char*>{1, 5, "1.5"}, {2, 0, "2.0"}, {0, 9, "0.9"}}) {
    std::string file = WriteLas(LasSpec{});
    Put<uint8_t>(&file, 24, major);
    Put<uint8_t>(&file, 25, minor);
    ExpectError(ParseLas(file, "ver.las"), absl::StatusCode::kUnimplemented, "ver.las",
                absl::StrCat("byte offset 24: LAS version ", text, " is not supported"));
  }
}

TEST(LasReaderTest, PointFormatAboveTen) {
  std::string file = WriteLas(LasSpec{});
  Put<uint8_t>(&file, 104, 11);
  ExpectError(ParseLas(file, "pf.las"), absl::StatusCode::kUnimplemented, "pf.las",
              "byte offset 104: point data format 11 is not supported");
}

TEST(LasReaderTest, HeaderSizeTooSmallOrBeyondTheFile) {
  std::string file = WriteLas(LasSpec{});
  Put<uint16_t>(&file, 94, 226);
  ExpectError(ParseLas(file, "h.las"), absl::StatusCode::kInvalidArgument, "h.las",
              "byte offset 94: header size 226 is below the 227 bytes of a LAS 1.2 header");

  LasSpec v14;
  v14.minor = 4;
  file = WriteLas(v14);
  Put<uint16_t>(&file, 94, 227);
  ExpectError(ParseLas(file, "h.las"), absl::StatusCode::kInvalidArgument, "h.las",
              "byte offset 94: header size 227 is below the 375 bytes of a LAS 1.4 header");

  // A LAS 1.4 file cut inside its 375-byte header.
  file = WriteLas(v14).substr(0, 300);
  ExpectError(ParseLas(file, "h.las"), absl::StatusCode::kInvalidArgument, "h.las",
              "byte offset 94: header size 375 exceeds the file's 300 bytes");
}

TEST(LasReaderTest, OffsetToPointDataInsideTheHeaderOrBeyondTheFile) {
  LasSpec spec;
  spec.points = kPoints;
  std::string file = WriteLas(spec);
  Put<uint32_t>(&file, 96, 200);
  ExpectError(ParseLas(file, "o.las"), absl::StatusCode::kInvalidArgument, "o.las",
              "byte offset 96: offset to point data 200 lies inside the 227-byte header");
  Put<uint32_t>(&file, 96, 0xFFFFFFFF);
  ExpectError(ParseLas(file, "o.las"), absl::StatusCode::kInvalidArgument, "o.las",
              absl::StrCat("byte offset 96: offset to point data 4294967295 is beyond the end of "
                           "the file (",
                           file.size(), " bytes)"));
}

TEST(LasReaderTest, RecordLengthBelowTheFormatSize) {
  LasSpec spec;
  spec.minor = 4;
  spec.format = 10;
  spec.points = kPoints;
  std::string file = WriteLas(spec);
  Put<uint16_t>(&file, 105, 66);
  ExpectError(ParseLas(file, "r.las"), absl::StatusCode::kInvalidArgument, "r.las",
              "byte offset 105: point record length 66 is below the 67 bytes of point data "
              "format 10");
}

TEST(LasReaderTest, PointDataShorterThanTheCountPromises) {
  LasSpec spec;
  spec.format = 1;
  spec.points = kPoints;
  std::string file = WriteLas(spec);
  ExpectError(ParseLas(file.substr(0, file.size() - 1), "t.las"),
              absl::StatusCode::kInvalidArgument, "t.las",
              "byte offset 227: point data is truncated: expected 112 bytes (4 points of 28 "
              "bytes, count at byte offset 107), found 111");

  // A huge count fails before any allocation.
  Put<uint32_t>(&file, 107, 0xFFFFFFFF);
  ExpectError(ParseLas(file, "t.las"), absl::StatusCode::kInvalidArgument, "t.las",
              "expected 120259084260 bytes (4294967295 points of 28 bytes");

  LasSpec v14;
  v14.minor = 4;
  v14.format = 6;
  v14.legacy_count = false;
  v14.points = kPoints;
  file = WriteLas(v14);
  Put<uint64_t>(&file, 247, 1000000000000ull);
  ExpectError(ParseLas(file, "t.las"), absl::StatusCode::kInvalidArgument, "t.las",
              "byte offset 375: point data is truncated: expected 30000000000000 bytes "
              "(1000000000000 points of 30 bytes, count at byte offset 247), found 120");
  Put<uint64_t>(&file, 247, std::numeric_limits<uint64_t>::max());
  ExpectError(ParseLas(file, "t.las"), absl::StatusCode::kInvalidArgument, "t.las",
              "expected over 2^64 bytes (18446744073709551615 points");
}

TEST(LasReaderTest, ScaleFactorsZeroOrNonFinite) {
  const double kInf = std::numeric_limits<double>::infinity();
  const double kNaN = std::numeric_limits<double>::quiet_NaN();
  const std::string base = WriteLas(LasSpec{});
  std::string file = base;
  Put<double>(&file, 131, 0.0);
  ExpectError(ParseLas(file, "sc.las"), absl::StatusCode::kInvalidArgument, "sc.las",
              "byte offset 131: x scale factor is 0; it must be finite and non-zero");
  file = base;
  Put<double>(&file, 139, kNaN);
  ExpectError(ParseLas(file, "sc.las"), absl::StatusCode::kInvalidArgument, "sc.las",
              "byte offset 139: y scale factor is nan");
  file = base;
  Put<double>(&file, 147, -kInf);
  ExpectError(ParseLas(file, "sc.las"), absl::StatusCode::kInvalidArgument, "sc.las",
              "byte offset 147: z scale factor is -inf");
  // Finite, but 2^31 times it is not.
  file = base;
  Put<double>(&file, 131, 1e300);
  ExpectError(ParseLas(file, "sc.las"), absl::StatusCode::kInvalidArgument, "sc.las",
              "byte offset 131: x scale factor 1e+300 and offset 500000 take coordinates beyond "
              "the range of a double");
}

TEST(LasReaderTest, OffsetsNonFinite) {
  const std::string base = WriteLas(LasSpec{});
  std::string file = base;
  Put<double>(&file, 155, std::numeric_limits<double>::infinity());
  ExpectError(ParseLas(file, "of.las"), absl::StatusCode::kInvalidArgument, "of.las",
              "byte offset 155: x offset is inf; it must be finite");
  file = base;
  Put<double>(&file, 171, std::numeric_limits<double>::quiet_NaN());
  ExpectError(ParseLas(file, "of.las"), absl::StatusCode::kInvalidArgument, "of.las",
              "byte offset 171: z offset is nan");
}

TEST(LasReaderTest, CorruptionsNameTheFile) {
  const absl::string_view kReplacements("\0\x01\x07\x0a\x40\x7f\x80\xc0\xffLASF", 14);
  uint64_t state = 7;
  for (const VersionFormat& c : {VersionFormat{2, 1}, VersionFormat{4, 10}}) {
    LasSpec spec;
    spec.minor = c.minor;
    spec.format = c.format;
    spec.extra = 2;
    spec.points = kPoints;
    spec.vlr_bytes = 10;
    ExpectCorruptionsNameTheFile(
        WriteLas(spec), "corrupt.las", kReplacements, &state,
        [](const std::string& contents) { return ParseLas(contents, "corrupt.las"); });
  }
}

}  // namespace
}  // namespace shapeid
