#include "core/io/obj_reader.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
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

// The unit cube [0, 1]^3 as 6 quads, written the way exporters do: a missing material
// library, objects, groups, materials, smoothing, texture coordinates, normals, a line and a
// point element, and every face form (v, v/vt, v//vn, v/vt/vn).
constexpr char kCube[] =
    "# Blender-style unit cube\n"
    "mtllib cube_materials_that_do_not_exist.mtl\n"
    "o Cube\n"
    "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n"
    "v 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\n"
    "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n"
    "vn 0 0 -1\nvn 0 0 1\nvn 0 -1 0\n"
    "g bottom top\n"
    "usemtl Steel\n"
    "s off\n"
    "f 1/1/1 4/4/1 3/3/1 2/2/1\n"
    "f 5/1/2 6/2/2 7/3/2 8/4/2\n"
    "g sides\n"
    "usemtl Paint\n"
    "s 1\n"
    "f 1//3 2//3 6//3 5//3\n"
    "f 3/3 4/4 8/4 7/3\n"
    "  f 2 3 7 6\t\n"
    "f 1 5 8 4\n"
    "l 1 2\n"
    "p 3\n";

// The same cube with relative indices: -1 is the last vertex read so far.
constexpr char kRelativeCube[] =
    "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n"
    "v 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\n"
    "f -8 -5 -6 -7\nf -4 -3 -2 -1\nf -8 -7 -3 -4\n"
    "f -6 -5 -1 -2\nf -7 -6 -2 -3\nf -8 -4 -1 -5\n";

// The same cube as 12 triangles, with CRLF line ends.
constexpr char kTriangleCube[] =
    "v 0 0 0\r\nv 1 0 0\r\nv 1 1 0\r\nv 0 1 0\r\n"
    "v 0 0 1\r\nv 1 0 1\r\nv 1 1 1\r\nv 0 1 1\r\n"
    "f 1 4 3\r\nf 1 3 2\r\nf 5 6 7\r\nf 5 7 8\r\nf 1 2 6\r\nf 1 6 5\r\n"
    "f 3 4 8\r\nf 3 8 7\r\nf 2 3 7\r\nf 2 7 6\r\nf 1 5 8\r\nf 1 8 4\r\n";

ReadOptions Sampled(size_t n, uint64_t seed) {
  ReadOptions options = Raw();
  options.sample_points = n;
  options.sample_seed = seed;
  return options;
}

// Checks that every point lies on the surface of the unit cube and returns how many lie on
// each face (x = 0, x = 1, y = 0, ...).
std::vector<int> CountPerCubeFace(const PointCloud& cloud) {
  std::vector<int> per_face(6, 0);
  for (size_t i = 0; i < cloud.size(); ++i) {
    const auto p = cloud.point(i);
    double distance = 0;  // to the farthest face plane, measured from the center
    for (int a = 0; a < 3; ++a) {
      EXPECT_GE(p[a], -1e-6f) << "point " << i;
      EXPECT_LE(p[a], 1 + 1e-6f) << "point " << i;
      distance = std::max(distance, std::abs(static_cast<double>(p[a]) - 0.5));
    }
    EXPECT_NEAR(distance, 0.5, 1e-6) << "point " << i << " is not on the surface";
    for (int a = 0; a < 3; ++a) {
      if (std::abs(p[a]) < 1e-6f) ++per_face[2 * a];
      if (std::abs(p[a] - 1) < 1e-6f) ++per_face[2 * a + 1];
    }
  }
  return per_face;
}

TEST(ObjReaderTest, CubeSampledOnTheSurfaceAreaWeighted) {
  const std::string path = WriteTempFile("cube.obj", kCube);
  const absl::StatusOr<ReadResult> r = ReadPointCloud(path, Sampled(3000, 7));
  ASSERT_TRUE(r.ok()) << r.status();
  ASSERT_EQ(r->cloud.size(), 3000u);
  const std::vector<int> per_face = CountPerCubeFace(r->cloud);
  for (int f = 0; f < 6; ++f) {  // each face gets about 500 of the points
    EXPECT_GT(per_face[f], 400) << f;
    EXPECT_LT(per_face[f], 600) << f;
  }
}

TEST(ObjReaderTest, TrianglesAndCrlfLineEnds) {
  const absl::StatusOr<ReadResult> r = ParseObj(kTriangleCube, "tri.obj", Sampled(600, 1));
  ASSERT_TRUE(r.ok()) << r.status();
  ASSERT_EQ(r->cloud.size(), 600u);
  for (int n : CountPerCubeFace(r->cloud)) EXPECT_GT(n, 50);
}

TEST(ObjReaderTest, RelativeIndicesGiveTheSameMesh) {
  // Same vertices, same fans, same seed: the same points, bit for bit.
  const absl::StatusOr<ReadResult> absolute = ParseObj(kCube, "abs.obj", Sampled(200, 5));
  const absl::StatusOr<ReadResult> relative = ParseObj(kRelativeCube, "rel.obj", Sampled(200, 5));
  ASSERT_TRUE(absolute.ok()) << absolute.status();
  ASSERT_TRUE(relative.ok()) << relative.status();
  ASSERT_EQ(absolute->cloud.size(), relative->cloud.size());
  for (size_t i = 0; i < absolute->cloud.size(); ++i) {
    EXPECT_EQ(absolute->cloud.point(i), relative->cloud.point(i)) << i;
  }
}

TEST(ObjReaderTest, RelativeIndicesCountFromTheVerticesReadSoFar) {
  // -3 -2 -1 is the triangle in z = 0, not the last three vertices of the file.
  const absl::StatusOr<ReadResult> r =
      ParseObj("v 0 0 0\nv 1 0 0\nv 0 1 0\nf -3 -2 -1\nv 5 5 5\n", "r.obj", Sampled(100, 2));
  ASSERT_TRUE(r.ok()) << r.status();
  ASSERT_EQ(r->cloud.size(), 100u);
  for (size_t i = 0; i < r->cloud.size(); ++i) {
    EXPECT_EQ(r->cloud.point(i).z(), 0) << i;
    EXPECT_LE(r->cloud.point(i).x() + r->cloud.point(i).y(), 1 + 1e-6f) << i;
  }
}

TEST(ObjReaderTest, FacesMayReferToLaterVertices) {
  const absl::StatusOr<ReadResult> r =
      ParseObj("f 1 2 3\nv 0 0 0\nv 1 0 0\nv 0 1 0\n", "fwd.obj", Sampled(10, 0));
  ASSERT_TRUE(r.ok()) << r.status();
  EXPECT_EQ(r->cloud.size(), 10u);
}

TEST(ObjReaderTest, SameSeedSamePoints) {
  const absl::StatusOr<ReadResult> a = ParseObj(kCube, "a.obj", Sampled(100, 42));
  const absl::StatusOr<ReadResult> b = ParseObj(kCube, "b.obj", Sampled(100, 42));
  const absl::StatusOr<ReadResult> c = ParseObj(kCube, "c.obj", Sampled(100, 43));
  ASSERT_TRUE(a.ok() && b.ok() && c.ok());
  bool differs = false;
  for (size_t i = 0; i < 100; ++i) {
    EXPECT_EQ(a->cloud.point(i), b->cloud.point(i));
    differs |= a->cloud.point(i) != c->cloud.point(i);
  }
  EXPECT_TRUE(differs);
}

TEST(ObjReaderTest, DefaultSampleCountAndRecentering) {
  const absl::StatusOr<ReadResult> r = ParseObj(kCube, "cube.obj");
  ASSERT_TRUE(r.ok()) << r.status();
  EXPECT_EQ(r->cloud.size(), ReadOptions().sample_points);
  for (int a = 0; a < 3; ++a) EXPECT_NEAR(r->offset[a], 0.5, 1e-2) << a;
  for (float v : r->cloud.xyz()) {
    EXPECT_GE(v, -0.5f - 1e-6f);
    EXPECT_LE(v, 0.5f + 1e-6f);
  }
}

TEST(ObjReaderTest, VerticesWhenSamplingIsOff) {
  const absl::StatusOr<ReadResult> r = ParseObj(kCube, "cube.obj", Sampled(0, 0));
  ASSERT_TRUE(r.ok()) << r.status();
  ASSERT_EQ(r->cloud.size(), 8u);
  EXPECT_EQ(r->cloud.point(6), Eigen::Vector3f(1, 1, 1));
}

TEST(ObjReaderTest, PointCloudWithoutFacesGivesItsVertices) {
  // Exporters write w or a color after xyz; both are ignored.
  constexpr char kPoints[] = "# scan\nv 1.5 -2 3e2\nv 4 5 6 1.0\nv 7 8 9 0.5 0.25 1\nvn 0 0 1\n";
  const absl::StatusOr<ReadResult> r = ParseObj(kPoints, "scan.obj", Sampled(2048, 0));
  ASSERT_TRUE(r.ok()) << r.status();
  ASSERT_EQ(r->cloud.size(), 3u);
  EXPECT_EQ(r->cloud.point(0), Eigen::Vector3f(1.5f, -2, 300));
  EXPECT_EQ(r->cloud.point(2), Eigen::Vector3f(7, 8, 9));

  const absl::StatusOr<ReadResult> centered = ParseObj(kPoints, "scan.obj");
  ASSERT_TRUE(centered.ok()) << centered.status();
  EXPECT_EQ(centered->offset, Eigen::Vector3d(4.25, 3, 153));
  EXPECT_EQ(centered->cloud.point(0), Eigen::Vector3f(-2.75f, -5, 147));
}

TEST(ObjReaderTest, DropsNonFiniteVerticesWhenAsked) {
  ReadOptions options = Sampled(0, 0);
  options.drop_non_finite = true;
  const absl::StatusOr<ReadResult> r =
      ParseObj("v 0 0 0\nv nan 1 2\nv 1 inf 0\nv 1 1 1\n", "nan.obj", options);
  ASSERT_TRUE(r.ok()) << r.status();
  EXPECT_EQ(r->cloud.size(), 2u);
  EXPECT_EQ(r->dropped_non_finite, 2u);
}

TEST(ObjReaderTest, MalformedFilesNameTheFileAndLine) {
  const struct {
    const char* contents;
    const char* where;
  } cases[] = {
      {"", "empty"},
      {"\x7f"
       "ELF\x02\x01\x01\xff\xfe garbage\n\x01\x02",
       "no vertex"},
      {"# only a comment\n\n", "no vertex"},
      {"v 0 0 0\nv 1 0\nv 0 1 0\nf 1 2 3\n", "line 2"},
      {"v 0 0 0\nv 1 zero 0\nv 0 1 0\n", "line 2"},
      {"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n", "line 4: vertex index 4 is out of range"},
      {"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 0\n", "line 4: face vertex 3 is 0"},
      {"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 x\n", "line 4: face vertex 3 is 0 or not a number"},
      {"v 0 0 0\nv 1 0 0\nv 0 1 0\nf -1 -2 -4\n", "line 4: relative vertex index -4"},
      {"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2\n", "line 4: a face needs 3 or more vertices"},
      // tinyobjloader has no trailing comments: '#' reads as index 0.
      {"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3 # c\n", "line 4: face vertex 4 is 0"},
      {"v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n", "no surface area"},
      {"v 0 0 0\nv 1 0 0\nv nan 1 0\ng g\nf 1 2 3\n", "line 5"},
      {"v 0 0 0\r\n# c\r\nv 1 0 0\r\nv 0 1 0\r\nf 1 2 5\r\n", "line 5"},
      {"v 0 0 0\rv 1 0 0\rv 0 1 0\r\rf 1 2 3 9\r", "line 5"},
      {"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 2 3 4\n", "line 5"},
  };
  for (const auto& c : cases) {
    const std::string path = WriteTempFile("bad.obj", c.contents);
    ExpectError(ReadPointCloud(path), absl::StatusCode::kInvalidArgument, path, c.where);
  }
}

// Every prefix and random corruptions: read or rejected, never a crash (run under ASan).
TEST(ObjReaderTest, TruncationsAndCorruptionsAreHandled) {
  const std::string file = kCube;
  for (size_t n = 0; n <= file.size(); ++n) {
    const absl::StatusOr<ReadResult> r = ParseObj(file.substr(0, n), "prefix.obj");
    if (!r.ok()) {
      EXPECT_THAT(std::string(r.status().message()), HasSubstr("prefix.obj"));
    }
  }
  const char replacements[] = "0123456789 \n\r\t.-/e#vfgox\xff";
  uint64_t state = 1;
  ExpectCorruptionsNameTheFile(file, "corrupt.obj",
                               absl::string_view(replacements, sizeof replacements - 1), &state,
                               [](const std::string& contents) {
                                 return ParseObj(contents, "corrupt.obj", Sampled(16, 3));
                               });
  ExpectCorruptionsNameTheFile(
      file, "corrupt.obj", absl::string_view(replacements, sizeof replacements - 1), &state,
      [](const std::string& contents) { return ParseObj(contents, "corrupt.obj", Sampled(0, 0)); });
}

// Real exporters' files, when a machine has them (Debian's brutalchess package, or the meshes
// extracted from it and minetest-mod-homedecor); CI does not depend on them.
TEST(ObjReaderTest, RealMeshFiles) {
  std::vector<std::string> files;
  for (const char* root :
       {"/usr/share/games/brutalchess/models", "/tmp/meshdl/x/usr/share/games"}) {
    std::error_code error;
    for (auto it = std::filesystem::recursive_directory_iterator(root, error);
         !error && it != std::filesystem::recursive_directory_iterator(); it.increment(error)) {
      if (it->path().extension() == ".obj") files.push_back(it->path().string());
    }
  }
  if (files.empty()) GTEST_SKIP() << "no brutalchess or homedecor OBJ meshes on this machine";
  std::sort(files.begin(), files.end());
  for (const std::string& path : files) {
    const absl::StatusOr<ReadResult> r = ReadPointCloud(path);
    ASSERT_TRUE(r.ok()) << r.status();
    EXPECT_EQ(r->cloud.size(), ReadOptions().sample_points) << path;
    EXPECT_TRUE(ValidateCloud(r->cloud).ok()) << path;
  }
}

}  // namespace
}  // namespace shapeid
