#include "core/io/ply_reader.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <string>

#include "absl/strings/str_cat.h"
#include "core/io/io_testing.h"
#include "core/io/point_cloud_reader.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"

namespace shapeid {
namespace {

using ::testing::HasSubstr;

// The unit square in z = 0 as two triangles, plus an off-plane vertex used by no face; with
// mixed property types, an extra element before and after the faces, and a list in both.
constexpr char kHeaderTail[] =
    "comment made by shapeid tests\n"
    "element vertex 5\n"
    "property double x\nproperty float y\nproperty int16 z\nproperty uchar red\n"
    "element edge 1\n"
    "property list uint8 uint32 ends\n"
    "element face 2\n"
    "property list uchar int vertex_indices\nproperty ushort flags\n"
    "element material 1\n"
    "property float shine\n"
    "end_header\n";

constexpr char kAscii[] =
    "ply\nformat ascii 1.0\n%s"
    "0 0 0 255\n1 0 0 1\n1 1 0 2\n0 1 0 3\n0.5 0.5 9 4\n"
    "2 0 1\n"
    "3 0 1 2 7\n3 0 2 3 7\n"
    "0.25\n";

template <typename T>
void Put(std::string* out, T value, bool big) {
  char b[sizeof(T)];
  std::memcpy(b, &value, sizeof(T));
  if (big) std::reverse(b, b + sizeof(T));
  out->append(b, sizeof(T));
}

std::string AsciiFile() {
  std::string s = kAscii;
  return s.replace(s.find("%s"), 2, kHeaderTail);
}

std::string BinaryFile(bool big) {
  std::string s =
      absl::StrCat("ply\nformat binary_", big ? "big" : "little", "_endian 1.0\n", kHeaderTail);
  const double v[5][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {0.5, 0.5, 9}};
  for (int i = 0; i < 5; ++i) {
    Put<double>(&s, v[i][0], big);
    Put<float>(&s, static_cast<float>(v[i][1]), big);
    Put<int16_t>(&s, static_cast<int16_t>(v[i][2]), big);
    Put<uint8_t>(&s, static_cast<uint8_t>(i), big);
  }
  Put<uint8_t>(&s, 2, big);
  Put<uint32_t>(&s, 0, big);
  Put<uint32_t>(&s, 1, big);
  for (const int32_t t : {1, 2}) {  // faces 0 1 2 and 0 2 3, as in the ascii file
    Put<uint8_t>(&s, 3, big);
    Put<int32_t>(&s, 0, big);
    Put<int32_t>(&s, t, big);
    Put<int32_t>(&s, t + 1, big);
    Put<uint16_t>(&s, 7, big);
  }
  Put<float>(&s, 0.25f, big);
  return s;
}

ReadOptions Faces(size_t n, uint64_t seed = 0) {
  ReadOptions options = Raw();
  options.sample_points = n;
  options.sample_seed = seed;
  return options;
}

TEST(PlyReaderTest, VerticesInEveryEncoding) {
  for (const std::string& file : {AsciiFile(), BinaryFile(false), BinaryFile(true)}) {
    const std::string path = WriteTempFile("v.ply", file);
    const absl::StatusOr<ReadResult> r = ReadPointCloud(path, Faces(0));
    ASSERT_TRUE(r.ok()) << r.status();
    ASSERT_EQ(r->cloud.size(), 5u);
    EXPECT_EQ(r->cloud.point(1), Eigen::Vector3f(1, 0, 0));
    EXPECT_EQ(r->cloud.point(4), Eigen::Vector3f(0.5f, 0.5f, 9));
  }
}

TEST(PlyReaderTest, FacesSampledInEveryEncoding) {
  for (const std::string& file : {AsciiFile(), BinaryFile(false), BinaryFile(true)}) {
    const absl::StatusOr<ReadResult> r = ParsePly(file, "f.ply", Faces(500, 9));
    ASSERT_TRUE(r.ok()) << r.status();
    ASSERT_EQ(r->cloud.size(), 500u);
    for (size_t i = 0; i < r->cloud.size(); ++i) {
      const auto p = r->cloud.point(i);
      EXPECT_EQ(p.z(), 0);  // the off-plane vertex is in no face
      EXPECT_GE(std::min(p.x(), p.y()), 0);
      EXPECT_LE(std::max(p.x(), p.y()), 1);
    }
    // The same seed gives the same points, whatever the encoding.
    const absl::StatusOr<ReadResult> ascii = ParsePly(AsciiFile(), "a.ply", Faces(500, 9));
    ASSERT_TRUE(ascii.ok());
    EXPECT_EQ(ascii->cloud.point(123), r->cloud.point(123));
  }
}

TEST(PlyReaderTest, MeshesAreSampledByDefaultLikeEveryMeshFormat) {
  const absl::StatusOr<ReadResult> r = ParsePly(AsciiFile(), "m.ply", Raw());
  ASSERT_TRUE(r.ok()) << r.status();
  EXPECT_EQ(r->cloud.size(), ReadOptions().sample_points);
}

TEST(PlyReaderTest, ACloudWithoutFacesGivesItsVerticesWhateverTheSampling) {
  const std::string file =
      "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n"
      "property float y\nproperty float z\nend_header\n1 2 3\n";
  for (const size_t n : {size_t{0}, size_t{10}}) {
    const absl::StatusOr<ReadResult> vertices = ParsePly(file, "p.ply", Faces(n));
    ASSERT_TRUE(vertices.ok()) << vertices.status();
    EXPECT_EQ(vertices->cloud.size(), 1u);
  }
  // An empty face element is no mesh either.
  const std::string no_faces =
      "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
      "property float z\nelement face 0\nproperty list uchar int vertex_indices\nend_header\n"
      "1 2 3\n";
  const absl::StatusOr<ReadResult> empty = ParsePly(no_faces, "e.ply", Faces(10));
  ASSERT_TRUE(empty.ok()) << empty.status();
  EXPECT_EQ(empty->cloud.size(), 1u);
}

TEST(PlyReaderTest, MalformedHeaderNamesTheLine) {
  const struct {
    const char* contents;
    const char* where;
  } cases[] = {
      {"pcd\n", "line 1"},
      {"ply\nformat ascii 2.0\nend_header\n", "line 2"},
      {"ply\nformat binary_middle_endian 1.0\nend_header\n", "line 2"},
      {"ply\nformat ascii 1.0\nproperty float x\nend_header\n", "line 3"},
      {"ply\nformat ascii 1.0\nelement vertex many\nend_header\n", "line 3"},
      {"ply\nformat ascii 1.0\nelement vertex 1\nproperty float128 x\nend_header\n", "line 4"},
      {"ply\nformat ascii 1.0\nelement vertex 1\nproperty list float int x\nend_header\n",
       "line 4"},
      {"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
       "end_header\n1 2\n",
       "line 3"},
      {"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nbogus\nend_header\n", "line 5"},
      {"ply\nelement vertex 0\nend_header\n", "line 3"},
  };
  for (const auto& c : cases) {
    const std::string path = WriteTempFile("bad.ply", c.contents);
    ExpectError(ReadPointCloud(path), absl::StatusCode::kInvalidArgument, path, c.where);
  }
  ExpectError(ParsePly("ply\nformat ascii 1.0\n", "h.ply"), absl::StatusCode::kInvalidArgument,
              "h.ply", "no end_header");
}

TEST(PlyReaderTest, MalformedAsciiDataNamesTheLine) {
  std::string file = AsciiFile();
  const size_t header_lines = 16;  // "ply", format and kHeaderTail's 14 lines
  std::string bad = file;
  bad.replace(bad.find("1 1 0 2"), 7, "1 one 0 2");
  ExpectError(ParsePly(bad, "a.ply"), absl::StatusCode::kInvalidArgument, "a.ply",
              absl::StrCat("line ", header_lines + 3));
  bad = file;
  bad.replace(bad.find("3 0 2 3 7"), 9, "3 0 2 5 7");
  ExpectError(ParsePly(bad, "a.ply", Faces(4)), absl::StatusCode::kInvalidArgument, "a.ply",
              absl::StrCat("line ", header_lines + 8));
  ExpectError(ParsePly(file + "1\n", "a.ply"), absl::StatusCode::kInvalidArgument, "a.ply",
              absl::StrCat("line ", header_lines + 10));
  bad = file;
  bad.replace(bad.find("2 0 1\n"), 6, "2 0 1 5\n");
  ExpectError(ParsePly(bad, "a.ply"), absl::StatusCode::kInvalidArgument, "a.ply",
              absl::StrCat("line ", header_lines + 6, ": extra value"));
}

TEST(PlyReaderTest, TruncatedBinaryNamesTheByteOffset) {
  const std::string file = BinaryFile(false);
  const std::string path = WriteTempFile("t.ply", file.substr(0, file.size() - 2));
  ExpectError(ReadPointCloud(path), absl::StatusCode::kInvalidArgument, path,
              absl::StrCat("byte offset ", file.size() - 4, ": the binary data is truncated"));
}

TEST(PlyReaderTest, HugeCountsDoNotAllocate) {
  const std::string file =
      "ply\nformat binary_little_endian 1.0\nelement vertex 4000000000\nproperty float x\n"
      "property float y\nproperty float z\nend_header\n0123456789ab";
  const absl::StatusOr<ReadResult> r = ParsePly(file, "huge.ply");
  ExpectError(r, absl::StatusCode::kInvalidArgument, "huge.ply", "truncated");
}

// Found by the bad-input corpus (tests/bad_input_test.cc): an element without properties has
// zero-byte instances, and a count of 2^64 - 1 of them used to spin the reader for ever.
TEST(PlyReaderTest, AnElementWithoutPropertiesIsSkippedWhateverItsCount) {
  const std::string file =
      "ply\nformat binary_little_endian 1.0\nelement vertex 1\nproperty float x\n"
      "property float y\nproperty float z\nelement nothing 18446744073709551615\nend_header\n" +
      std::string("\0\0\0\0\0\0\x80\x3f\0\0\0\x40", 12);
  ReadOptions keep_coordinates;
  keep_coordinates.recenter = false;
  const absl::StatusOr<ReadResult> r = ParsePly(file, "empty-element.ply", keep_coordinates);
  ASSERT_TRUE(r.ok()) << r.status();
  ASSERT_EQ(r->cloud.size(), 1u);
  EXPECT_EQ(r->cloud.point(0).y(), 1.0f);
  EXPECT_EQ(r->cloud.point(0).z(), 2.0f);
}

// Every prefix and random corruptions: read or rejected, never a crash (run under ASan).
TEST(PlyReaderTest, TruncationsAndCorruptionsAreHandled) {
  const char replacements[] = "0123456789 \n.-e#x\xff\x80";
  uint64_t state = 5;
  for (const std::string& file : {AsciiFile(), BinaryFile(false), BinaryFile(true)}) {
    for (size_t n = 0; n <= file.size(); ++n) {
      const absl::StatusOr<ReadResult> r = ParsePly(file.substr(0, n), "prefix.ply", Faces(8));
      if (!r.ok()) {
        EXPECT_THAT(std::string(r.status().message()), HasSubstr("prefix.ply"));
      }
    }
    ExpectCorruptionsNameTheFile(
        file, "corrupt.ply", absl::string_view(replacements, sizeof replacements - 1), &state,
        [](const std::string& contents) { return ParsePly(contents, "corrupt.ply", Faces(8, 1)); });
  }
}

// A vertex element whose x, y, z are float32 in fixed records is read as columns; one with a
// list property goes through the per-value reader. Both must give the same cloud, bit for bit.
std::string FloatVertexFile(bool big, bool with_list) {
  std::string s = absl::StrCat(
      "ply\nformat binary_", big ? "big" : "little", "_endian 1.0\n",
      "element header_junk 2\nproperty short j\n",
      "element vertex 4\nproperty uchar tag\nproperty float y\nproperty float x\n",
      "property double w\nproperty float z\n", with_list ? "property list uchar int l\n" : "",
      "element face 1\nproperty list uchar int vertex_indices\nend_header\n");
  Put<int16_t>(&s, 7, big);
  Put<int16_t>(&s, 8, big);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float v[4][3] = {{1.5f, -2, 1e30f}, {-0.f, 3, 4}, {nan, 0, 1}, {2, 2.25f, -1e30f}};
  for (const auto& p : v) {
    s += 'T';
    Put<float>(&s, p[1], big);
    Put<float>(&s, p[0], big);
    Put<double>(&s, 0.5, big);
    Put<float>(&s, p[2], big);
    if (with_list) {
      s += '\1';
      Put<int32_t>(&s, 9, big);
    }
  }
  s += '\3';
  for (int32_t i : {0, 1, 3}) Put<int32_t>(&s, i, big);
  return s;
}

TEST(PlyReaderTest, FloatVertexColumnsMatchThePerValueReader) {
  for (const bool big : {false, true}) {
    for (const bool drop : {false, true}) {
      for (const bool recenter : {false, true}) {
        ReadOptions options;
        options.sample_points = 0;
        options.drop_non_finite = drop;
        options.recenter = recenter;
        const absl::StatusOr<ReadResult> columns =
            ParsePly(FloatVertexFile(big, false), "c.ply", options);
        const absl::StatusOr<ReadResult> values =
            ParsePly(FloatVertexFile(big, true), "v.ply", options);
        ASSERT_TRUE(columns.ok()) << columns.status();
        ASSERT_TRUE(values.ok()) << values.status();
        ASSERT_EQ(columns->cloud.size(), drop ? 3u : 4u);
        ASSERT_EQ(values->cloud.size(), columns->cloud.size());
        EXPECT_EQ(std::memcmp(columns->cloud.data(), values->cloud.data(),
                              4 * columns->cloud.xyz().size()),
                  0);
        EXPECT_EQ(columns->offset, values->offset);
        EXPECT_EQ(columns->non_finite_points, 1u);
        EXPECT_EQ(values->non_finite_points, 1u);
        EXPECT_EQ(columns->first_non_finite, 2u);
        // Records of 21 bytes after the 4 bytes of header_junk.
        const size_t header = FloatVertexFile(big, false).find("end_header\n") + 11;
        EXPECT_EQ(columns->first_non_finite_location,
                  absl::StrCat("byte offset ", header + 4 + 42));
        if (!recenter) {
          EXPECT_EQ(columns->cloud.point(0), Eigen::Vector3f(1.5f, -2, 1e30f));
          EXPECT_TRUE(std::signbit(columns->cloud.point(1).x()));
        }
      }
    }
  }
}

TEST(PlyReaderTest, TruncatedFloatVerticesNameTheByteOffset) {
  std::string file = FloatVertexFile(false, false);
  const size_t vertices = file.find("end_header\n") + 11 + 4;
  file.resize(vertices + 30);  // one record and a half
  ReadOptions options;
  options.sample_points = 0;
  ExpectError(ParsePly(file, "t.ply", options), absl::StatusCode::kInvalidArgument, "t.ply",
              "byte offset");
}

}  // namespace
}  // namespace shapeid
