#include "core/io/stl_reader.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include "Eigen/Core"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "core/io/io_testing.h"
#include "core/io/point_cloud_reader.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"

namespace shapeid {
namespace {

using ::testing::HasSubstr;

ReadOptions Sampled(size_t n, uint64_t seed = 0) {
  ReadOptions options = Raw();
  options.sample_points = n;
  options.sample_seed = seed;
  return options;
}

// Binary STL is little-endian whatever the host.
template <typename T>
void PutLittle(std::string* out, T value) {
  char b[sizeof(T)];
  std::memcpy(b, &value, sizeof(T));
  if (__BYTE_ORDER__ != __ORDER_LITTLE_ENDIAN__) std::reverse(b, b + sizeof(T));
  out->append(b, sizeof(T));
}

using Triangle = std::array<Eigen::Vector3f, 3>;

// A binary STL of `triangles` whose 80-byte header starts with `header` (SolidWorks starts
// its binary files with "solid").
std::string Binary(const std::vector<Triangle>& triangles, const std::string& header = "binary") {
  std::string f = header;
  f.resize(80, ' ');
  PutLittle<uint32_t>(&f, static_cast<uint32_t>(triangles.size()));
  for (const Triangle& t : triangles) {
    for (int a = 0; a < 3; ++a) PutLittle<float>(&f, std::nanf(""));  // normals are ignored
    for (const Eigen::Vector3f& v : t) {
      for (int a = 0; a < 3; ++a) PutLittle<float>(&f, v[a]);
    }
    PutLittle<uint16_t>(&f, 0x7c1f);  // color, ignored
  }
  return f;
}

std::string Ascii(const std::vector<Triangle>& triangles) {
  std::string f = "solid shape\n";
  for (const Triangle& t : triangles) {
    f += "  facet normal 0 0 0\n    outer loop\n";
    for (const Eigen::Vector3f& v : t) {
      absl::StrAppendFormat(&f, "      vertex %.9g %.9g %.9g\n", v.x(), v.y(), v.z());
    }
    f += "    endloop\n  endfacet\n";
  }
  return f + "endsolid shape\n";
}

// The unit cube as 12 triangles.
std::vector<Triangle> Cube() {
  const Eigen::Vector3f c[8] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0},
                                {0, 0, 1}, {1, 0, 1}, {1, 1, 1}, {0, 1, 1}};
  const int quads[6][4] = {{0, 3, 2, 1}, {4, 5, 6, 7}, {0, 1, 5, 4},
                           {2, 3, 7, 6}, {1, 2, 6, 5}, {0, 4, 7, 3}};
  std::vector<Triangle> triangles;
  for (const auto& q : quads) {
    triangles.push_back({c[q[0]], c[q[1]], c[q[2]]});
    triangles.push_back({c[q[0]], c[q[2]], c[q[3]]});
  }
  return triangles;
}

void ExpectVertices(const PointCloud& cloud, const std::vector<Triangle>& triangles) {
  ASSERT_EQ(cloud.size(), 3 * triangles.size());
  for (size_t t = 0; t < triangles.size(); ++t) {
    for (size_t v = 0; v < 3; ++v) {
      EXPECT_EQ(cloud.point(3 * t + v), triangles[t][v]) << "triangle " << t << " vertex " << v;
    }
  }
}

TEST(StlReaderTest, BinaryVerticesAsStoredEvenWithASolidHeader) {
  const std::vector<Triangle> triangles = {
      {{{0, 0, 0}, {1.5f, 0, 0}, {0, 2.25f, 0}}},
      {{{0, 0, 0}, {1.5f, 0, 0}, {-0.1f, 1e-30f, 123456.789f}}}};
  for (const std::string header : {"binary", "solid part exported by SolidWorks"}) {
    const std::string path = WriteTempFile("two.stl", Binary(triangles, header));
    const absl::StatusOr<ReadResult> r = ReadPointCloud(path, Sampled(0));
    ASSERT_TRUE(r.ok()) << header << ": " << r.status();
    ExpectVertices(r->cloud, triangles);  // shared corners are not merged
  }
}

TEST(StlReaderTest, AsciiSeveralSolidsAnyCaseAnyWhitespace) {
  constexpr char kFile[] =
      "  \n\tsolid part one\r\n"
      "FACET NORMAL 0 0 1\r\n\tOUTER\r\nLOOP\r\n"
      "  Vertex 0 0 0\r\n  vertex 1.5 0\r\n 0 vertex 0 2.25 0\r\n"
      "endloop endfacet\r\n"
      "endsolid part one\r\n"
      "solid\n"
      "facet normal -1e-3 nan 1\nouter loop\nvertex -0.1 1e-30 123456.789\n"
      "vertex 1 1 1\nvertex\t2\t2\t2\nendloop\nendfacet\n"
      "endsolid";
  const std::vector<Triangle> triangles = {{{{0, 0, 0}, {1.5f, 0, 0}, {0, 2.25f, 0}}},
                                           {{{-0.1f, 1e-30f, 123456.789f}, {1, 1, 1}, {2, 2, 2}}}};
  const absl::StatusOr<ReadResult> r = ParseStl(kFile, "ascii.stl", Sampled(0));
  ASSERT_TRUE(r.ok()) << r.status();
  ExpectVertices(r->cloud, triangles);
}

TEST(StlReaderTest, CubeSampledOnTheSurfaceAsciiAndBinaryAgree) {
  const absl::StatusOr<ReadResult> binary = ParseStl(Binary(Cube()), "cube.stl", Sampled(3000, 7));
  const absl::StatusOr<ReadResult> ascii = ParseStl(Ascii(Cube()), "cube.stl", Sampled(3000, 7));
  ASSERT_TRUE(binary.ok()) << binary.status();
  ASSERT_TRUE(ascii.ok()) << ascii.status();
  ASSERT_EQ(binary->cloud.size(), 3000u);
  int per_face[6] = {0, 0, 0, 0, 0, 0};
  for (size_t i = 0; i < binary->cloud.size(); ++i) {
    const auto p = binary->cloud.point(i);
    EXPECT_EQ(p, ascii->cloud.point(i)) << i;  // same triangles, same seed
    double distance = 0;
    for (int a = 0; a < 3; ++a) {
      EXPECT_GE(p[a], -1e-6f);
      EXPECT_LE(p[a], 1 + 1e-6f);
      distance = std::max(distance, std::abs(static_cast<double>(p[a]) - 0.5));
      if (std::abs(p[a]) < 1e-6f) ++per_face[2 * a];
      if (std::abs(p[a] - 1) < 1e-6f) ++per_face[2 * a + 1];
    }
    EXPECT_NEAR(distance, 0.5, 1e-6) << "point " << i << " is not on the surface";
  }
  for (int f = 0; f < 6; ++f) {
    EXPECT_GT(per_face[f], 400) << f;
    EXPECT_LT(per_face[f], 600) << f;
  }
}

TEST(StlReaderTest, SameSeedSamePointsAndDefaults) {
  const std::string cube = Binary(Cube());
  const absl::StatusOr<ReadResult> a = ParseStl(cube, "a.stl", Sampled(100, 42));
  const absl::StatusOr<ReadResult> b = ParseStl(cube, "b.stl", Sampled(100, 42));
  const absl::StatusOr<ReadResult> c = ParseStl(cube, "c.stl", Sampled(100, 43));
  ASSERT_TRUE(a.ok() && b.ok() && c.ok());
  bool differs = false;
  for (size_t i = 0; i < 100; ++i) {
    EXPECT_EQ(a->cloud.point(i), b->cloud.point(i));
    differs |= a->cloud.point(i) != c->cloud.point(i);
  }
  EXPECT_TRUE(differs);
  const absl::StatusOr<ReadResult> d = ParseStl(cube, "cube.stl");
  ASSERT_TRUE(d.ok()) << d.status();
  EXPECT_EQ(d->cloud.size(), ReadOptions().sample_points);
  EXPECT_NEAR(d->offset.x(), 0.5, 1e-3);
}

TEST(StlReaderTest, NeitherAsciiNorBinaryGivesTheExpectedSize) {
  std::string five = Binary(Cube());  // announces 12 triangles, holds 2 and a half
  five.resize(84 + 125);
  std::string solid_binary = Binary(Cube(), "solid from SolidWorks");
  solid_binary.resize(solid_binary.size() - 1);
  std::string huge = Binary({});
  huge.replace(80, 4, "\xff\xff\xff\xff");
  huge += "partial";
  const struct {
    std::string contents;
    const char* message;
  } cases[] = {
      {"",
       "byte offset 0: neither ascii STL (which starts with \"solid\") nor binary STL (84 "
       "bytes or more); the file has 0 bytes"},
      {"ply\nformat ascii 1.0\n", "byte offset 0: neither ascii STL"},
      {five,
       "byte offset 80: neither ascii STL (which starts with \"solid\") nor binary STL: its header "
       "announces 12 triangles, which need 84 + 50 * 12 = 684 bytes, but the file has 209 bytes"},
      {solid_binary,
       "byte offset 80: starts with \"solid\" but holds NUL bytes, so it is not ascii STL; as "
       "binary STL, its header announces 12 triangles, which need 84 + 50 * 12 = 684 bytes, but "
       "the file has 683 bytes"},
      {huge, "which need 84 + 50 * 4294967295 = 214748364834 bytes, but the file has 91 bytes"},
  };
  for (const auto& c : cases) {
    const std::string path = WriteTempFile("neither.stl", c.contents);
    ExpectError(ReadPointCloud(path, Sampled(10)), absl::StatusCode::kInvalidArgument, path,
                c.message);
  }
}

TEST(StlReaderTest, BinaryWithABogusCountOrTrailingBytesReadsItsRecords) {
  // Exporters write a count of 0, or pad the file: the records are read as VTK's reader does.
  std::string zero_count = Binary(Cube());
  zero_count.replace(80, 4, std::string(4, '\0'));
  std::string padded = Binary(Cube()) + std::string(17, '\0');
  for (const std::string& file : {zero_count, padded}) {
    const absl::StatusOr<ReadResult> r = ParseStl(file, "lenient.stl", Sampled(0));
    ASSERT_TRUE(r.ok()) << r.status();
    EXPECT_EQ(r->cloud.size(), 3 * Cube().size());
  }
}

TEST(StlReaderTest, EmptyMeshes) {
  // A valid file of no triangles: no vertices; nothing to sample.
  for (const std::string& file : {Binary({}), std::string("solid empty\nendsolid empty\n")}) {
    const absl::StatusOr<ReadResult> vertices = ParseStl(file, "empty.stl", Sampled(0));
    ASSERT_TRUE(vertices.ok()) << vertices.status();
    EXPECT_EQ(vertices->cloud.size(), 0u);
    ExpectError(ParseStl(file, "empty.stl", Sampled(10)), absl::StatusCode::kInvalidArgument,
                "empty.stl", "no surface area");
  }
}

TEST(StlReaderTest, NonFiniteVertices) {
  std::vector<Triangle> triangles = Cube();
  triangles[1][2].y() = std::nanf("");
  const std::string binary = Binary(triangles);
  // Sampling needs every face's area: the face is named by its byte offset or line.
  ExpectError(ParseStl(binary, "nan.stl", Sampled(10)), absl::StatusCode::kInvalidArgument,
              "nan.stl", "byte offset 134: the face has a non-finite vertex");
  ExpectError(ParseStl(Ascii(triangles), "nan.stl", Sampled(10)),
              absl::StatusCode::kInvalidArgument, "nan.stl", "line 9: the face has a non-finite");
  // The vertices can be read, and the non-finite one dropped when asked.
  ReadOptions drop = Sampled(0);
  drop.drop_non_finite = true;
  const absl::StatusOr<ReadResult> r = ParseStl(binary, "nan.stl", drop);
  ASSERT_TRUE(r.ok()) << r.status();
  EXPECT_EQ(r->cloud.size(), 35u);
  EXPECT_EQ(r->dropped_non_finite, 1u);
}

TEST(StlReaderTest, MalformedAsciiNamesTheLine) {
  const std::string facet = "facet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\n";
  const std::string good = "solid x\n" + facet + "vertex 0 1 0\nendloop\nendfacet\n";  // 8 lines
  const struct {
    std::string contents;
    const char* where;
  } cases[] = {
      {"solidify\nendsolid\n", "line 1: an ascii STL file starts with \"solid [name]\""},
      {"solid x\n" + facet + "endloop\nendfacet\nendsolid\n",
       "line 6: the facet on line 2 has 2 vertices; STL facets are triangles (3)"},
      {good.substr(0, good.size() - 17) + "vertex 1 1 0\nendloop\n",
       "line 7: the facet on line 2 has a fourth vertex"},
      {"solid x\n" + facet + "vertex 0 zero 0\nendloop\nendfacet\nendsolid\n",
       "line 6: vertex y value \"zero\" is not a number"},
      {"solid x\nfacet normal 0 0 one\n", "line 2: normal z value \"one\" is not a number"},
      {"solid x\nfacet 0 0 1\n", "line 2: expected \"normal\", found \"0\""},
      {"solid x\nfacet normal 0 0 1\nloop\n", "line 3: expected \"outer\", found \"loop\""},
      {good.substr(0, good.size() - 9) + "endsolid x\n",
       "line 8: expected \"endfacet\", found \"endsolid\""},
      {"solid x\nvertex 0 0 0\n", "line 2: expected \"facet\" or \"endsolid\", found \"vertex\""},
      {"solid x\n" + facet + "vertex 0 1 0\nend loop\n",
       "line 7: expected \"vertex\" or \"endloop\", found \"end\""},
      {good, "line 8: the file ends inside a solid, before its \"endsolid\""},
      {good + "endsolid x\nfoo\n",
       "line 10: expected \"solid\" or the end of the file after endsolid, found \"foo\""},
      {"solid x\n" + facet, "line 5: the file ends inside a facet's loop"},
      {"solid x\n" + facet + "vertex 0 0", "line 6: the file ends inside a vertex (x y z)"},
      {"solid x\nfacet normal 0 0 1\n", "line 2: the file ends where \"outer\" was expected"},
  };
  for (const auto& c : cases) {
    const std::string path = WriteTempFile("bad.stl", c.contents);
    ExpectError(ReadPointCloud(path, Sampled(10)), absl::StatusCode::kInvalidArgument, path,
                c.where);
  }
}

// Every prefix and random corruptions: read or rejected, never a crash (run under ASan).
TEST(StlReaderTest, TruncationsAndCorruptionsAreHandled) {
  uint64_t state = 1;
  const char replacements[] = "0123456789 \n.-eEsolid\xff\x00\x7f";
  const std::vector<Triangle> cube = Cube();
  const std::vector<Triangle> two(cube.begin(), cube.begin() + 2);
  for (const std::string& file : {Ascii(two), Binary(two, "solid x")}) {
    for (const size_t samples : {size_t{0}, size_t{16}}) {
      ExpectPrefixesNameTheFile(file, "prefix.stl: ", [&](const std::string& contents) {
        return ParseStl(contents, "prefix.stl", Sampled(samples));
      });
    }
    ExpectCorruptionsNameTheFile(file, "corrupt.stl",
                                 absl::string_view(replacements, sizeof replacements - 1), &state,
                                 [](const std::string& contents) {
                                   return ParseStl(contents, "corrupt.stl", Sampled(16, 3));
                                 });
  }
}

// The checked-in fuzz seeds read; each bad-input file is refused for its one defect.
TEST(StlReaderTest, CheckedInFiles) {
  const std::string root = SHAPEID_SOURCE_DIR "/tests/";
  const struct {
    const char* file;
    size_t triangles;
  } seeds[] = {{"stl_binary_solidworks_header_cube.stl", 12},
               {"stl_ascii_two_solids_mixed_case.stl", 2},
               {"stl_binary_tetrahedron.stl", 4}};
  for (const auto& seed : seeds) {
    const std::string path = root + "fuzz_seeds/testdata/" + seed.file;
    const absl::StatusOr<ReadResult> vertices = ReadPointCloud(path, Sampled(0));
    ASSERT_TRUE(vertices.ok()) << vertices.status();
    EXPECT_EQ(vertices->cloud.size(), 3 * seed.triangles) << seed.file;
    EXPECT_TRUE(ReadPointCloud(path, Sampled(64)).ok()) << seed.file;
  }
  const struct {
    const char* file;
    const char* message;
  } bad[] = {
      {"stl_binary_count_huge.stl",
       "byte offset 80: neither ascii STL (which starts with \"solid\") nor binary STL: its "
       "header announces 4294967295 triangles, which need 84 + 50 * 4294967295 = 214748364834 "
       "bytes, but the file has 190 bytes"},
      {"stl_binary_truncated.stl",
       "byte offset 80: starts with \"solid\" but holds NUL bytes, so it is not ascii STL; as "
       "binary STL, its header announces 3 triangles, which need 84 + 50 * 3 = 234 bytes, but "
       "the file has 214 bytes"},
      {"stl_ascii_facet_two_vertices.stl", "line 6: the facet on line 2 has 2 vertices"},
      {"stl_ascii_no_endsolid.stl", "line 8: the file ends inside a solid"},
      {"stl_ascii_vertex_not_a_number.stl", "line 5: vertex y value \"zero\" is not a number"},
      {"stl_neither_ascii_nor_binary.stl", "byte offset 0: neither ascii STL"},
  };
  for (const auto& b : bad) {
    const std::string path = root + "bad_input/testdata/" + b.file;
    ExpectError(ReadPointCloud(path, Sampled(10)), absl::StatusCode::kInvalidArgument, path,
                b.message);
  }
}

// --- Files written by other tools ------------------------------------------------------------

bool Shell(const std::string& command) { return std::system(command.c_str()) == 0; }

// A small mesh whose values every writer keeps exactly (numpy-stl's ascii prints %f).
const Eigen::Vector3f kVertices[] = {
    {0, 0, 0}, {1.5f, 0, 0}, {0, 2.25f, 0}, {0.125f, -0.5f, 3}, {-4.75f, 10.5f, 0.0625f}};
const int kFaces[][3] = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}, {1, 4, 2}};

std::vector<Triangle> KnownTriangles() {
  std::vector<Triangle> triangles;
  for (const auto& f : kFaces)
    triangles.push_back({kVertices[f[0]], kVertices[f[1]], kVertices[f[2]]});
  return triangles;
}

// The known mesh as "v x y z" and "f a b c" lines, for the scripts below.
std::string KnownMeshFile() {
  std::string text;
  for (const auto& v : kVertices)
    absl::StrAppendFormat(&text, "v %.9g %.9g %.9g\n", v.x(), v.y(), v.z());
  for (const auto& f : kFaces) absl::StrAppendFormat(&text, "f %d %d %d\n", f[0], f[1], f[2]);
  return text;
}

constexpr char kReadMesh[] = R"(
import sys
import numpy as np
base = sys.argv[1]
rows = [line.split() for line in open(base)]
v = np.array([[float(x) for x in r[1:]] for r in rows if r[0] == 'v'])
f = np.array([[int(i) for i in r[1:]] for r in rows if r[0] == 'f'], dtype=np.int32)
)";

// Open3D's write_triangle_mesh: binary, and ascii where the installed version writes it
// (0.16 refuses), to base.open3d_{binary,ascii}.stl.
constexpr char kOpen3dScript[] = R"(
import open3d as o3d
m = o3d.geometry.TriangleMesh(o3d.utility.Vector3dVector(v), o3d.utility.Vector3iVector(f))
m.compute_triangle_normals()
if not o3d.io.write_triangle_mesh(base + '.open3d_binary.stl', m):
    sys.exit('open3d cannot write binary STL')
try:
    o3d.io.write_triangle_mesh(base + '.open3d_ascii.stl', m, write_ascii=True)
except RuntimeError as e:
    print('open3d writes no ascii STL:', e)
)";

// numpy-stl: ascii and binary, to base.numpy_stl_{ascii,binary}.stl.
constexpr char kNumpyStlScript[] = R"(
from stl import mesh, Mode
m = mesh.Mesh(np.zeros(len(f), dtype=mesh.Mesh.dtype))
m.vectors[:] = v[f]
m.save(base + '.numpy_stl_ascii.stl', mode=Mode.ASCII)
m.save(base + '.numpy_stl_binary.stl', mode=Mode.BINARY)
)";

void ExpectKnownTriangles(const std::string& path) {
  SCOPED_TRACE(path);
  const absl::StatusOr<ReadResult> r = ReadPointCloud(path, Sampled(0));
  ASSERT_TRUE(r.ok()) << r.status();
  ExpectVertices(r->cloud, KnownTriangles());
  const absl::StatusOr<ReadResult> sampled = ReadPointCloud(path, Sampled(64));
  ASSERT_TRUE(sampled.ok()) << sampled.status();
  EXPECT_EQ(sampled->cloud.size(), 64u);
}

TEST(StlReaderTest, Open3dFilesReadAsWritten) {
  if (!Shell("/usr/bin/python3 -c 'import open3d' >/dev/null 2>&1")) {
    GTEST_SKIP() << "no Open3D for Python (Debian package python3-open3d)";
  }
  const std::string base = WriteTempFile("known_mesh.txt", KnownMeshFile());
  const std::string script = WriteTempFile("open3d_stl.py", absl::StrCat(kReadMesh, kOpen3dScript));
  ASSERT_TRUE(Shell(absl::StrCat("/usr/bin/python3 ", script, " ", base, " >/dev/null 2>&1")));
  ExpectKnownTriangles(base + ".open3d_binary.stl");
  const std::string ascii = base + ".open3d_ascii.stl";
  if (Shell(absl::StrCat("test -s ", ascii))) {
    ExpectKnownTriangles(ascii);
  } else {
    std::printf("this Open3D writes no ascii STL; its binary STL was checked\n");
  }
}

TEST(StlReaderTest, NumpyStlFilesReadAsWritten) {
  if (!Shell("/usr/bin/python3 -c 'import stl.mesh' >/dev/null 2>&1")) {
    GTEST_SKIP() << "no numpy-stl (Debian package python3-stl)";
  }
  const std::string base = WriteTempFile("known_mesh.txt", KnownMeshFile());
  const std::string script =
      WriteTempFile("numpy_stl.py", absl::StrCat(kReadMesh, kNumpyStlScript));
  ASSERT_TRUE(Shell(absl::StrCat("/usr/bin/python3 ", script, " ", base, " >/dev/null 2>&1")));
  ExpectKnownTriangles(base + ".numpy_stl_ascii.stl");
  ExpectKnownTriangles(base + ".numpy_stl_binary.stl");
}

}  // namespace
}  // namespace shapeid
