#include "core/io/off_reader.h"

#include <cmath>
#include <string>

#include "absl/strings/str_cat.h"
#include "core/io/io_testing.h"
#include "core/io/point_cloud_reader.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"

namespace shapeid {
namespace {

using ::testing::HasSubstr;

// The unit cube [0, 1]^3: 8 vertices, 6 quads (split into fans by the reader), a comment and a
// color on one face.
constexpr char kCube[] =
    "OFF\n"
    "# unit cube\n"
    "8 6 12\n"
    "0 0 0\n1 0 0\n1 1 0\n0 1 0\n"
    "0 0 1\n1 0 1\n1 1 1\n0 1 1\n"
    "4 0 3 2 1\n4 4 5 6 7\n4 0 1 5 4\n4 2 3 7 6\n4 1 2 6 5\n4 0 4 7 3 255 0 0\n";

ReadOptions Sampled(size_t n, uint64_t seed) {
  ReadOptions options = Raw();
  options.sample_points = n;
  options.sample_seed = seed;
  return options;
}

TEST(OffReaderTest, CubeSampledOnTheSurface) {
  const std::string path = WriteTempFile("cube.off", kCube);
  const absl::StatusOr<ReadResult> r = ReadPointCloud(path, Sampled(3000, 7));
  ASSERT_TRUE(r.ok()) << r.status();
  ASSERT_EQ(r->cloud.size(), 3000u);
  int per_face[6] = {0, 0, 0, 0, 0, 0};
  for (size_t i = 0; i < r->cloud.size(); ++i) {
    const auto p = r->cloud.point(i);
    double distance = 0;  // to the nearest face plane, measured from the center
    for (int a = 0; a < 3; ++a) {
      EXPECT_GE(p[a], -1e-6f);
      EXPECT_LE(p[a], 1 + 1e-6f);
      distance = std::max(distance, std::abs(static_cast<double>(p[a]) - 0.5));
    }
    EXPECT_NEAR(distance, 0.5, 1e-6) << "point " << i << " is not on the surface";
    for (int a = 0; a < 3; ++a) {
      if (std::abs(p[a]) < 1e-6f) ++per_face[2 * a];
      if (std::abs(p[a] - 1) < 1e-6f) ++per_face[2 * a + 1];
    }
  }
  // Area-weighted: each face gets about 500 of the points.
  for (int f = 0; f < 6; ++f) {
    EXPECT_GT(per_face[f], 400) << f;
    EXPECT_LT(per_face[f], 600) << f;
  }
}

TEST(OffReaderTest, SameSeedSamePoints) {
  const absl::StatusOr<ReadResult> a = ParseOff(kCube, "a.off", Sampled(100, 42));
  const absl::StatusOr<ReadResult> b = ParseOff(kCube, "b.off", Sampled(100, 42));
  const absl::StatusOr<ReadResult> c = ParseOff(kCube, "c.off", Sampled(100, 43));
  ASSERT_TRUE(a.ok() && b.ok() && c.ok());
  bool differs = false;
  for (size_t i = 0; i < 100; ++i) {
    EXPECT_EQ(a->cloud.point(i), b->cloud.point(i));
    differs |= a->cloud.point(i) != c->cloud.point(i);
  }
  EXPECT_TRUE(differs);
}

TEST(OffReaderTest, DefaultSampleCountAndRecentering) {
  const absl::StatusOr<ReadResult> r = ParseOff(kCube, "cube.off");
  ASSERT_TRUE(r.ok()) << r.status();
  EXPECT_EQ(r->cloud.size(), ReadOptions().sample_points);
  EXPECT_NEAR(r->offset.x(), 0.5, 1e-3);
}

TEST(OffReaderTest, VerticesWhenSamplingIsOff) {
  const absl::StatusOr<ReadResult> r = ParseOff(kCube, "cube.off", Sampled(0, 0));
  ASSERT_TRUE(r.ok()) << r.status();
  ASSERT_EQ(r->cloud.size(), 8u);
  EXPECT_EQ(r->cloud.point(6), Eigen::Vector3f(1, 1, 1));
}

TEST(OffReaderTest, ModelNetCountsOnTheOffLine) {
  const absl::StatusOr<ReadResult> r =
      ParseOff("OFF3 1 0\n0 0 0\n2 0 0\n0 2 0\n3 0 1 2\n", "m.off", Sampled(50, 1));
  ASSERT_TRUE(r.ok()) << r.status();
  ASSERT_EQ(r->cloud.size(), 50u);
  for (size_t i = 0; i < 50; ++i) {
    const auto p = r->cloud.point(i);
    EXPECT_EQ(p.z(), 0);
    EXPECT_LE(p.x() + p.y(), 2 + 1e-5f);
  }
}

TEST(OffReaderTest, MalformedFilesNameTheLine) {
  const struct {
    const char* contents;
    const char* where;
  } cases[] = {
      {"PLY\n3 1 0\n", "line 1"},
      {"", "line 1"},
      {"OFF\n", "counts line"},
      {"OFF\n3 x 0\n", "line 2"},
      {"OFF\n3\n", "line 2"},
      {"OFF\n3 1 0\n0 0 0\n1 0\n0 1 0\n3 0 1 2\n", "line 4"},
      {"OFF\n3 1 0\n0 0 0\n1 0 zero\n0 1 0\n3 0 1 2\n", "line 4"},
      {"OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n", "line 6"},
      {"OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n2 0 1\n", "line 6"},
      {"OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1\n", "line 6"},
      {"OFF\n3 2 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n", "ends after 1 of 2 faces"},
      {"OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n1 2 3\n", "line 7"},
      {"OFF\n3 0 0\n0 0 0\n1 0 0\n0 1 0\n", "no surface area"},
      {"OFF\n3 1 0\n0 0 0\n1 0 0\nnan 1 0\n3 0 1 2\n", "line 6"},
  };
  for (const auto& c : cases) {
    const std::string path = WriteTempFile("bad.off", c.contents);
    ExpectError(ReadPointCloud(path), absl::StatusCode::kInvalidArgument, path, c.where);
  }
}

// Every prefix and random corruptions: read or rejected, never a crash (run under ASan).
TEST(OffReaderTest, TruncationsAndCorruptionsAreHandled) {
  const std::string file = kCube;
  for (size_t n = 0; n <= file.size(); ++n) {
    const absl::StatusOr<ReadResult> r = ParseOff(file.substr(0, n), "prefix.off");
    if (!r.ok()) {
      EXPECT_THAT(std::string(r.status().message()), HasSubstr("prefix.off"));
    }
  }
  const char replacements[] = "0123456789 \n.-e#x\xff";
  uint64_t state = 1;
  ExpectCorruptionsNameTheFile(file, "corrupt.off",
                               absl::string_view(replacements, sizeof replacements - 1), &state,
                               [](const std::string& contents) {
                                 return ParseOff(contents, "corrupt.off", Sampled(16, 3));
                               });
}

}  // namespace
}  // namespace shapeid
