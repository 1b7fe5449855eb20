#include "core/io/vtk_reader.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <string>
#include <vector>

#include "Eigen/Core"
#include "Eigen/Geometry"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "core/io/io_testing.h"
#include "core/io/pcd_writer.h"
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

// Legacy VTK binary is big-endian whatever the host.
template <typename T>
void PutBig(std::string* out, T value) {
  char b[sizeof(T)];
  std::memcpy(b, &value, sizeof(T));
  if (__BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__) std::reverse(b, b + sizeof(T));
  out->append(b, sizeof(T));
}

constexpr float kCorners[8][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0},
                                  {0, 0, 1}, {1, 0, 1}, {1, 1, 1}, {0, 1, 1}};
constexpr int kQuads[6][4] = {{0, 3, 2, 1}, {4, 5, 6, 7}, {0, 1, 5, 4},
                              {2, 3, 7, 6}, {1, 2, 6, 5}, {0, 4, 7, 3}};

// The unit cube as VTK 3.0 binary polydata: 8 float points, 6 quads (legacy layout), then cell
// scalars that the reader must not look at.
std::string BinaryCube() {
  std::string f =
      "# vtk DataFile Version 3.0\nunit cube\nBINARY\nDATASET POLYDATA\nPOINTS 8 float\n";
  for (const auto& c : kCorners) {
    for (float v : c) PutBig<float>(&f, v);
  }
  f += "\nPOLYGONS 6 30\n";
  for (const auto& q : kQuads) {
    PutBig<int32_t>(&f, 4);
    for (int i : q) PutBig<int32_t>(&f, i);
  }
  f += "\nCELL_DATA 6\nSCALARS id unsigned_char 1\nLOOKUP_TABLE default\n\x01\x02\x03";
  return f;
}

// The same cube in ascii, VTK 5.1 layout (OFFSETS / CONNECTIVITY).
constexpr char kAsciiCube51[] =
    "# vtk DataFile Version 5.1\n"
    "unit cube\n"
    "ASCII\n"
    "DATASET POLYDATA\n"
    "POINTS 8 double\n"
    "0 0 0 1 0 0 1 1 0\n0 1 0 0 0 1 1 0 1\n1 1 1 0 1 1\n"
    "POLYGONS 7 24\n"
    "OFFSETS vtktypeint64\n"
    "0 4 8 12 16 20 24\n"
    "CONNECTIVITY vtktypeint64\n"
    "0 3 2 1 4 5 6 7 0 1 5 4\n2 3 7 6 1 2 6 5 0 4 7 3\n"
    "POINT_DATA 8\n"
    "NORMALS Normals float\n";

// Checks that every point lies on the unit cube's surface, about evenly over the faces.
void ExpectOnUnitCube(const PointCloud& cloud) {
  int per_face[6] = {0, 0, 0, 0, 0, 0};
  for (size_t i = 0; i < cloud.size(); ++i) {
    const auto p = cloud.point(i);
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
  const double expected = static_cast<double>(cloud.size()) / 6;
  for (int f = 0; f < 6; ++f) {
    EXPECT_GT(per_face[f], 0.8 * expected) << f;
    EXPECT_LT(per_face[f], 1.2 * expected) << f;
  }
}

TEST(VtkReaderTest, AsciiCloudAsPclWritesIt) {
  // pcl_pcd2vtk's layout: POINTS + VERTICES, and for an rgb field a COLOR_SCALARS header
  // without its values, which the reader never reaches.
  constexpr char kFile[] =
      "# vtk DataFile Version 3.0\nvtk output\nASCII\nDATASET POLYDATA\nPOINTS 3 float\n"
      "0.5 0.25 3\n-1.5 2 3\n1e-07 1.2346e+05 -5\n\nVERTICES 3 6\n1 0\n1 1\n1 2\n\n"
      "POINT_DATA 3\nCOLOR_SCALARS scalars 3\n\n";
  const std::string path = WriteTempFile("pcl.vtk", kFile);
  // Sampling is asked for, but a cloud has no surface: its points are returned.
  const absl::StatusOr<ReadResult> r = ReadPointCloud(path, Sampled(100));
  ASSERT_TRUE(r.ok()) << r.status();
  ASSERT_EQ(r->cloud.size(), 3u);
  EXPECT_EQ(r->cloud.point(0), Eigen::Vector3f(0.5f, 0.25f, 3));
  EXPECT_EQ(r->cloud.point(1), Eigen::Vector3f(-1.5f, 2, 3));
  EXPECT_EQ(r->cloud.point(2), Eigen::Vector3f(1e-07f, 1.2346e+05f, -5));
}

TEST(VtkReaderTest, ValuesSpanLinesKeywordsAnyCaseCrlf) {
  constexpr char kFile[] =
      "# vtk DataFile Version 2.0\r\ntitle with spaces\r\nascii\r\ndataset polydata\r\n"
      "points 4 double\r\n0.1 0.2\r\n0.3 -4\r\n\r\n5 6 7.25 8 9 1e30 -0.0 2\r\n"
      "lines 1 3 2 0 3\r\n";
  const absl::StatusOr<ReadResult> r = ParseVtk(kFile, "crlf.vtk", Sampled(0));
  ASSERT_TRUE(r.ok()) << r.status();
  ASSERT_EQ(r->cloud.size(), 4u);
  EXPECT_EQ(r->cloud.point(0), Eigen::Vector3f(0.1f, 0.2f, 0.3f));
  EXPECT_EQ(r->cloud.point(1), Eigen::Vector3f(-4, 5, 6));
  EXPECT_EQ(r->cloud.point(2), Eigen::Vector3f(7.25f, 8, 9));
  EXPECT_EQ(r->cloud.point(3), Eigen::Vector3f(1e30f, 0, 2));
  // A double that no float holds: refused, naming the line of its point.
  std::string too_large = kFile;
  too_large.replace(too_large.find("1e30"), 4, "1e300");
  ExpectError(ParseVtk(too_large, "crlf.vtk", Sampled(0)), absl::StatusCode::kInvalidArgument,
              "crlf.vtk", "line 9");
}

template <typename T>
std::string Three(T a, T b, T c) {
  std::string s;
  PutBig(&s, a);
  PutBig(&s, b);
  PutBig(&s, c);
  return s;
}

TEST(VtkReaderTest, BinaryPointsOfEveryNumericType) {
  const auto file = [](const char* type, const std::string& values) {
    return absl::StrCat("# vtk DataFile Version 3.0\nt\nBINARY\nDATASET POLYDATA\nPOINTS 1 ", type,
                        "\n", values, "\n");
  };
  const struct {
    const char* type;
    std::string values;
    Eigen::Vector3f expected;
  } cases[] = {
      {"char", Three<int8_t>(-3, 7, 100), {-3, 7, 100}},
      {"signed_char", Three<int8_t>(-128, 0, 127), {-128, 0, 127}},
      {"unsigned_char", Three<uint8_t>(255, 7, 100), {255, 7, 100}},
      {"short", Three<int16_t>(-300, 7, 32767), {-300, 7, 32767}},
      {"unsigned_short", Three<uint16_t>(65535, 7, 100), {65535, 7, 100}},
      {"int", Three<int32_t>(-70000, 7, 100), {-70000, 7, 100}},
      {"unsigned_int", Three<uint32_t>(4000000000u, 7, 100), {4e9f, 7, 100}},
      {"long", Three<int64_t>(-5, 7, 100), {-5, 7, 100}},
      {"unsigned_long", Three<uint64_t>(5, 7, 100), {5, 7, 100}},
      {"vtktypeint64", Three<int64_t>(-5, 7, 100), {-5, 7, 100}},
      {"vtktypeuint64", Three<uint64_t>(5, 7, 100), {5, 7, 100}},
      {"vtkIdType", Three<int32_t>(-5, 7, 100), {-5, 7, 100}},
      {"float", Three<float>(-0.1f, 1e-30f, 3.5f), {-0.1f, 1e-30f, 3.5f}},
      {"double", Three<double>(-0.1, 1e-30, 3.5), {-0.1f, 1e-30f, 3.5f}},
  };
  for (const auto& c : cases) {
    const absl::StatusOr<ReadResult> r = ParseVtk(file(c.type, c.values), "types.vtk", Raw());
    ASSERT_TRUE(r.ok()) << c.type << ": " << r.status();
    ASSERT_EQ(r->cloud.size(), 1u) << c.type;
    EXPECT_EQ(r->cloud.point(0), c.expected) << c.type;
  }
}

TEST(VtkReaderTest, BinaryLegacyCubeSampledOnTheSurface) {
  const std::string path = WriteTempFile("cube.vtk", BinaryCube());
  const absl::StatusOr<ReadResult> r = ReadPointCloud(path, Sampled(3000, 7));
  ASSERT_TRUE(r.ok()) << r.status();
  ASSERT_EQ(r->cloud.size(), 3000u);
  ExpectOnUnitCube(r->cloud);

  const absl::StatusOr<ReadResult> vertices = ReadPointCloud(path, Sampled(0));
  ASSERT_TRUE(vertices.ok()) << vertices.status();
  ASSERT_EQ(vertices->cloud.size(), 8u);
  for (int i = 0; i < 8; ++i) {
    EXPECT_EQ(vertices->cloud.point(i),
              Eigen::Vector3f(kCorners[i][0], kCorners[i][1], kCorners[i][2]));
  }
}

TEST(VtkReaderTest, AsciiOffsetsLayoutSamplesLikeTheLegacyLayout) {
  const absl::StatusOr<ReadResult> ascii = ParseVtk(kAsciiCube51, "cube51.vtk", Sampled(600, 3));
  const absl::StatusOr<ReadResult> binary = ParseVtk(BinaryCube(), "cube.vtk", Sampled(600, 3));
  ASSERT_TRUE(ascii.ok()) << ascii.status();
  ASSERT_TRUE(binary.ok()) << binary.status();
  ExpectOnUnitCube(ascii->cloud);
  // The same triangles in the same order and the same seed: the same points.
  ASSERT_EQ(ascii->cloud.size(), binary->cloud.size());
  for (size_t i = 0; i < ascii->cloud.size(); ++i) {
    EXPECT_EQ(ascii->cloud.point(i), binary->cloud.point(i)) << i;
  }
}

TEST(VtkReaderTest, BinaryOffsetsLayoutWithInt32AndInt64Arrays) {
  for (const bool wide : {false, true}) {
    std::string f = "# vtk DataFile Version 5.1\nvtk output\nBINARY\nDATASET POLYDATA\n";
    f += "POINTS 4 float\n";
    const float square[4][3] = {{0, 0, 0}, {2, 0, 0}, {2, 2, 0}, {0, 2, 0}};
    for (const auto& p : square) {
      for (float v : p) PutBig<float>(&f, v);
    }
    const auto put = [&f, wide](int64_t v) {
      if (wide) {
        PutBig<int64_t>(&f, v);
      } else {
        PutBig<int32_t>(&f, static_cast<int32_t>(v));
      }
    };
    f += absl::StrCat("\nPOLYGONS 2 4\nOFFSETS ", wide ? "vtktypeint64" : "int", "\n");
    put(0);
    put(4);
    f += absl::StrCat("\nCONNECTIVITY ", wide ? "vtktypeint64" : "int", "\n");
    for (int i : {0, 1, 2, 3}) put(i);
    f += "\n";
    const absl::StatusOr<ReadResult> r = ParseVtk(f, "square.vtk", Sampled(400, 5));
    ASSERT_TRUE(r.ok()) << r.status();
    ASSERT_EQ(r->cloud.size(), 400u);
    int below_diagonal = 0;
    for (size_t i = 0; i < r->cloud.size(); ++i) {
      const auto p = r->cloud.point(i);
      EXPECT_EQ(p.z(), 0);
      EXPECT_GE(p.x(), 0);
      EXPECT_LE(p.x(), 2);
      EXPECT_GE(p.y(), 0);
      EXPECT_LE(p.y(), 2);
      below_diagonal += p.y() < p.x();
    }
    EXPECT_GT(below_diagonal, 150);  // both triangles of the fan
    EXPECT_LT(below_diagonal, 250);
  }
}

TEST(VtkReaderTest, TriangleStripsAreSplitIntoTriangles) {
  // The strip 0 1 2 3 over the unit square: triangles (0, 1, 2) and (1, 2, 3).
  constexpr char kFile[] =
      "# vtk DataFile Version 4.2\nstrip\nASCII\nDATASET POLYDATA\nPOINTS 5 float\n"
      "0 0 0 1 0 0 0 1 0 1 1 0 7 7 7\nTRIANGLE_STRIPS 1 5\n4 0 1 2 3\n";
  const absl::StatusOr<ReadResult> r = ParseVtk(kFile, "strip.vtk", Sampled(1000, 9));
  ASSERT_TRUE(r.ok()) << r.status();
  ASSERT_EQ(r->cloud.size(), 1000u);
  int upper = 0;
  for (size_t i = 0; i < r->cloud.size(); ++i) {
    const auto p = r->cloud.point(i);
    EXPECT_EQ(p.z(), 0);
    EXPECT_TRUE(p.x() >= 0 && p.x() <= 1 && p.y() >= 0 && p.y() <= 1) << p.transpose();
    upper += p.x() + p.y() > 1;
  }
  EXPECT_GT(upper, 400);
  EXPECT_LT(upper, 600);
  // Unsampled: the five points, the unused one included.
  const absl::StatusOr<ReadResult> points = ParseVtk(kFile, "strip.vtk", Sampled(0));
  ASSERT_TRUE(points.ok());
  ASSERT_EQ(points->cloud.size(), 5u);
  EXPECT_EQ(points->cloud.point(4), Eigen::Vector3f(7, 7, 7));
}

TEST(VtkReaderTest, FieldDataAndMetadataAreSkipped) {
  constexpr char kAscii[] =
      "# vtk DataFile Version 5.1\nfields\nASCII\nDATASET POLYDATA\n"
      "FIELD FieldData 4\nTimeValue 1 1 double\n1.5\nNULL_ARRAY\n"
      "flags 2 3 bit\n0 1 1 0 1 0\nids 1 2 int\n4 5\n"
      "METADATA\nINFORMATION 1\nNAME L2_NORM_RANGE LOCATION vtkDataArray\nDATA 2 0 1\n\n"
      "POINTS 2 float\n1 2 3 4 5 6\n\nMETADATA\nCOMPONENT_NAMES\neast\nnorth\nup\n\n\n\n"
      "VERTICES 3 2\nOFFSETS vtktypeint64\n0 1 2\nCONNECTIVITY vtktypeint64\n0 1\n";
  const absl::StatusOr<ReadResult> ascii = ParseVtk(kAscii, "fields.vtk", Raw());
  ASSERT_TRUE(ascii.ok()) << ascii.status();
  ASSERT_EQ(ascii->cloud.size(), 2u);
  EXPECT_EQ(ascii->cloud.point(1), Eigen::Vector3f(4, 5, 6));

  std::string binary =
      "# vtk DataFile Version 4.2\nfields\nBINARY\nDATASET POLYDATA\nFIELD FieldData 2\n"
      "TimeValue 1 1 double\n";
  PutBig<double>(&binary, 1.5);
  binary += "\nmask 1 9 bit\n\xff\x80\nPOINTS 1 float\n";
  for (float v : {-1.0f, 0.5f, 2.0f}) PutBig<float>(&binary, v);
  binary += "\nMETADATA\nCOMPONENT_NAMES\nx\ny\nz\n\nVERTICES 1 2\n";
  PutBig<int32_t>(&binary, 1);
  PutBig<int32_t>(&binary, 0);
  binary += "\n";
  const absl::StatusOr<ReadResult> r = ParseVtk(binary, "fields.vtk", Raw());
  ASSERT_TRUE(r.ok()) << r.status();
  ASSERT_EQ(r->cloud.size(), 1u);
  EXPECT_EQ(r->cloud.point(0), Eigen::Vector3f(-1, 0.5f, 2));
}

TEST(VtkReaderTest, GridsGiveTheirPoints) {
  constexpr char kUnstructured[] =
      "# vtk DataFile Version 4.2\ngrid\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS 3 float\n"
      "0 0 0 1 0 0 0 1 0\nCELLS 1 4\n3 0 1 2\nCELL_TYPES 1\n5\n";
  constexpr char kStructured[] =
      "# vtk DataFile Version 4.2\ngrid\nASCII\nDATASET STRUCTURED_GRID\nDIMENSIONS 2 1 1\n"
      "POINTS 2 float\n0 0 0 1 2 3\n";
  // Sampling asks for a surface, but a grid's cells are not read: its points are the cloud.
  const absl::StatusOr<ReadResult> u = ParseVtk(kUnstructured, "u.vtk", Sampled(50));
  ASSERT_TRUE(u.ok()) << u.status();
  ASSERT_EQ(u->cloud.size(), 3u);
  EXPECT_EQ(u->cloud.point(2), Eigen::Vector3f(0, 1, 0));
  const absl::StatusOr<ReadResult> s = ParseVtk(kStructured, "s.vtk", Sampled(50));
  ASSERT_TRUE(s.ok()) << s.status();
  ASSERT_EQ(s->cloud.size(), 2u);
  EXPECT_EQ(s->cloud.point(1), Eigen::Vector3f(1, 2, 3));
}

TEST(VtkReaderTest, DatasetsWithoutPointsAreUnimplemented) {
  const std::string head = "# vtk DataFile Version 3.0\nt\nASCII\n";
  const struct {
    std::string contents;
    const char* message;
  } cases[] = {
      {head + "DATASET STRUCTURED_POINTS\nDIMENSIONS 2 2 2\n", "line 4: DATASET STRUCTURED_POINTS"},
      {head + "DATASET RECTILINEAR_GRID\n", "line 4: DATASET RECTILINEAR_GRID has no POINTS"},
      {head + "DATASET TABLE\n", "line 4: DATASET TABLE is not read"},
      {head + "FIELD f 1\na 1 1 float\n1\n", "line 4: the file holds only FIELD data"},
      {head + "DATASET POLYDATA\nFIELD f 1\nnames 1 1 string\nabc\n",
       "line 6: FIELD array \"names\" of type string is not read"},
  };
  for (const auto& c : cases) {
    const std::string path = WriteTempFile("grid.vtk", c.contents);
    ExpectError(ReadPointCloud(path), absl::StatusCode::kUnimplemented, path, c.message);
  }
}

TEST(VtkReaderTest, SameSeedSamePointsAndDefaults) {
  const std::string cube = BinaryCube();
  const absl::StatusOr<ReadResult> a = ParseVtk(cube, "a.vtk", Sampled(100, 42));
  const absl::StatusOr<ReadResult> b = ParseVtk(cube, "b.vtk", Sampled(100, 42));
  const absl::StatusOr<ReadResult> c = ParseVtk(cube, "c.vtk", Sampled(100, 43));
  ASSERT_TRUE(a.ok() && b.ok() && c.ok());
  bool differs = false;
  for (size_t i = 0; i < 100; ++i) {
    EXPECT_EQ(a->cloud.point(i), b->cloud.point(i));
    differs |= a->cloud.point(i) != c->cloud.point(i);
  }
  EXPECT_TRUE(differs);
  const absl::StatusOr<ReadResult> d = ParseVtk(cube, "cube.vtk");
  ASSERT_TRUE(d.ok()) << d.status();
  EXPECT_EQ(d->cloud.size(), ReadOptions().sample_points);
  EXPECT_NEAR(d->offset.x(), 0.5, 1e-3);
}

TEST(VtkReaderTest, MalformedAsciiFilesNameTheLine) {
  const std::string head = "# vtk DataFile Version 4.2\nt\nASCII\nDATASET POLYDATA\n";
  const std::string points = head + "POINTS 3 float\n0 0 0 1 0 0 0 1 0\n";  // 5 lines
  const struct {
    std::string contents;
    const char* where;
  } cases[] = {
      {"", "line 1: a legacy VTK file starts with"},
      {"# vtk DataFile\n", "line 1: a legacy VTK file starts with"},
      {"# vtk DataFile Version 3.0\n", "line 2: the file ends before its title"},
      {"# vtk DataFile Version 3.0\ntitle\n", "line 3: expected ASCII or BINARY, found \"\""},
      {"# vtk DataFile Version 3.0\ntitle\nTEXT\n", "line 3: expected ASCII or BINARY"},
      {"# vtk DataFile Version 3.0\ntitle\nASCII\n", "the file ends before its DATASET line"},
      {"# vtk DataFile Version 3.0\nt\nASCII\nPOINTS 1 float\n", "line 4: expected \"DATASET"},
      {"# vtk DataFile Version 3.0\nt\nASCII\nDATASET MESH\n", "line 4: unknown DATASET type"},
      {head, "line 4: the dataset has no POINTS section"},
      {head + "POINT_DATA 3\n", "line 5: the dataset has no POINTS section"},
      {head + "POINTS x float\n", "line 5: expected \"POINTS <count> <type>\", found \"x\""},
      {head + "POINTS -1 float\n", "line 5: expected \"POINTS <count> <type>\""},
      {head + "POINTS 1 float3\n0 0 0\n", "line 5: unknown POINTS data type \"float3\""},
      {head + "POINTS 1 bit\n0 0 0\n", "line 5: unknown POINTS data type \"bit\""},
      {head + "POINTS 2 float\n0 0 0 1 1\n", "line 6: the file ends inside POINTS"},
      {head + "POINTS 5 float\n0 0 0\n", "line 5: POINTS announces 15 values but only 7 bytes"},
      {head + "POINTS 1 float\n0 zero 0\n", "line 6: POINTS value \"zero\" is not a number"},
      {points + "POINTS 1 float\n0 0 0\n", "line 7: a second POINTS section"},
      {head + "POLYGONS 1 4\n3 0 1 2\nPOINTS 3 float\n0 0 0 1 0 0 0 1 0\n",
       "line 5: POLYGONS before POINTS"},
      {points + "POLYGONS 1\n", "line 7: expected \"POLYGONS <cells> <size>\", found \"\""},
      {points + "POLYGONS 2 1\n3 0 1 2\n", "line 7: POLYGONS announces 2 cells in 1 values"},
      {points + "POLYGONS 1 4\n3 0 1 3\n", "line 8: POLYGONS point index 3 is not in [0, 3)"},
      {points + "POLYGONS 1 4\n3 0 -1 2\n", "line 8: POLYGONS point index -1 is not in [0, 3)"},
      {points + "POLYGONS 1 4\n3 0 1.5 2\n", "line 8: POLYGONS value \"1.5\" is not an integer"},
      {points + "POLYGONS 1 4\n5 0 1 2 0 1\n", "line 8: POLYGONS cell 0 has 5 points but 3 of"},
      {points + "POLYGONS 1 5\n3 0 1 2 0\n", "line 8: POLYGONS announces 5 values but its 1"},
      {points + "POLYGONS 2 8\n3 0 1 2          \n", "line 8: the file ends inside POLYGONS"},
      {points + "POLYGONS 1 900\n3 0 1 2\n", "line 7: POLYGONS announces 900 values but only"},
      {points + "LINES 2 3\n1 0\n1 1\n", "line 9: LINES cell 1 has 1 points but 0 of the 3"},
      {points + "POLYGONS 2 3\nOFFSETS int\n0 4\nCONNECTIVITY int\n0 1 2\n",
       "line 9: OFFSETS value 1 is 4; offsets rise from 0 to POLYGONS's connectivity size 3"},
      {points + "POLYGONS 2 3\nOFFSETS int\n1 3\nCONNECTIVITY int\n0 1 2\n",
       "line 9: OFFSETS value 0 is 1"},
      {points + "POLYGONS 3 3\nOFFSETS int\n0 2 1\nCONNECTIVITY int\n0 1 2\n",
       "line 9: OFFSETS value 2 is 1"},
      {points + "POLYGONS 2 3\nOFFSETS int\n0 2\nCONNECTIVITY int\n0 1 2\n",
       "line 9: the last of the 2 OFFSETS is 2 but POLYGONS announces 3"},
      {points + "POLYGONS 2 3\nOFFSETS float\n0 3\nCONNECTIVITY int\n0 1 2\n",
       "line 8: unknown OFFSETS data type \"float\"; expected an integer type"},
      {points + "POLYGONS 2 3\nOFFSETS int\n0 3\nCONNECTIONS int\n0 1 2\n",
       "line 10: expected CONNECTIVITY after OFFSETS, found \"CONNECTIONS\""},
      {points + "POLYGONS 2 3\nOFFSETS int\n0 3\nCONNECTIVITY int\n0 1 7\n",
       "line 11: POLYGONS point index 7 is not in [0, 3)"},
      {points + "POLYGONS 2 3\nOFFSETS int\n0 3\nCONNECTIVITY int\n0 1\n",
       "line 11: the file ends inside POLYGONS"},
      {points + "NORMALS n float\n", "line 7: unknown POLYDATA keyword \"NORMALS\""},
      {points + "FIELD f 2\na 1 1 float\n1\n", "line 9: the file ends after 1 of the FIELD's 2"},
      {points + "FIELD f 1\na 1 2 float\n1\n", "line 9: the file ends inside FIELD array \"a\""},
      {points + "FIELD f 1\na 1 1 complex\n1\n", "line 8: unknown data type \"complex\" for"},
      {points + "FIELD f 1\na 4294967296 4294967296 float\n",
       "line 8: FIELD array \"a\" announces"},
      {points + "FIELD f x\n", "line 7: expected \"FIELD <name> <arrays>\""},
      {head + "POINTS 3 float\n0 0 0 1 0 0 0 1 0\nPOLYGONS 1 3\n2 0 1\n", "no surface area"},
      {head + "POINTS 3 float\n0 0 0 1 0 0 0 nan 0\nPOLYGONS 1 4\n3 0 1 2\n",
       "line 8: the face has a non-finite vertex"},
      {"# vtk DataFile Version 4.2\ng\nASCII\nDATASET UNSTRUCTURED_GRID\nCELLS 0 0\n",
       "line 5: expected POINTS, found \"CELLS\""},
      {"# vtk DataFile Version 4.2\ng\nASCII\nDATASET STRUCTURED_GRID\nDIMENSIONS 2 x 1\n",
       "line 5: expected \"DIMENSIONS nx ny nz\", found \"x\""},
  };
  for (const auto& c : cases) {
    const std::string path = WriteTempFile("bad.vtk", c.contents);
    ExpectError(ReadPointCloud(path, Sampled(10)), absl::StatusCode::kInvalidArgument, path,
                c.where);
  }
}

TEST(VtkReaderTest, MalformedBinaryFilesNameTheByteOffset) {
  const std::string head = "# vtk DataFile Version 4.2\nt\nBINARY\nDATASET POLYDATA\n";
  const std::string points_line = head + "POINTS 3 float\n";
  std::string points = points_line;
  for (float v : {0.f, 0.f, 0.f, 1.f, 0.f, 0.f, 0.f, 1.f, 0.f}) PutBig<float>(&points, v);
  points += "\n";
  const std::string polygons_line = points + "POLYGONS 1 4\n";
  std::string bad_index = polygons_line;
  for (int32_t v : {3, 0, 1, 9}) PutBig<int32_t>(&bad_index, v);
  std::string negative_count = polygons_line;
  for (int32_t v : {-3, 0, 1, 2}) PutBig<int32_t>(&negative_count, v);
  const std::string offsets_line = points + "POLYGONS 2 3\nOFFSETS vtktypeuint64\n";
  std::string offsets_huge = offsets_line;
  PutBig<uint64_t>(&offsets_huge, 0);
  PutBig<uint64_t>(&offsets_huge, ~uint64_t{0});
  const std::string offsets_int_line = points + "POLYGONS 2 3\nOFFSETS int\n";
  const std::string field_line = points + "FIELD f 1\nbits 1 17 bit\n";
  const std::string huge_line = head + "POINTS 1000000000000 double\n";
  const auto at = [](const std::string& prefix, uint64_t plus, const char* message) {
    return absl::StrCat("byte offset ", prefix.size() + plus, ": ", message);
  };
  const struct {
    std::string contents;
    std::string where;
  } cases[] = {
      {points_line + std::string(35, 'x'),
       at(points_line, 0, "POINTS announces 9 float values (36 bytes) but only 35 bytes follow")},
      {huge_line, at(huge_line, 0,
                     "POINTS announces 3000000000000 double values (24000000000000 bytes) but "
                     "only 0 bytes follow")},
      {head + "POINTS 6148914691236517205 double\n", "(over 2^64 bytes)"},
      {polygons_line + std::string(15, 'x'),
       at(polygons_line, 0, "POLYGONS announces 4 int values (16 bytes) but only 15")},
      {bad_index, at(polygons_line, 12, "POLYGONS point index 9 is not in [0, 3)")},
      {negative_count, at(polygons_line, 0, "POLYGONS cell 0 has -3 points")},
      {offsets_huge, at(offsets_line, 8, "OFFSETS value 18446744073709551615 is too large")},
      {offsets_int_line + std::string(7, 'x'),
       at(offsets_int_line, 0, "OFFSETS announces 2 int values (8 bytes) but only 7")},
      {field_line + "\x01\x02",
       at(field_line, 0, "FIELD array \"bits\" needs 3 bytes but only 2 bytes follow")},
  };
  for (const auto& c : cases) {
    const std::string path = WriteTempFile("bad.vtk", c.contents);
    ExpectError(ReadPointCloud(path, Sampled(10)), absl::StatusCode::kInvalidArgument, path,
                c.where);
  }
}

TEST(VtkReaderTest, HugeCountsFailFast) {
  const std::string head = "# vtk DataFile Version 4.2\nt\nASCII\nDATASET POLYDATA\n";
  const std::string points = head + "POINTS 3 float\n0 0 0 1 0 0 0 1 0\n";
  const std::string cases[] = {
      head + "POINTS 1000000000000 float\n0 0 0\n",
      head + "POINTS 18446744073709551615 float\n",
      points + "POLYGONS 1000000000000 1000000000000\n3 0 1 2\n",
      points + "POLYGONS 1000000000000 3\nOFFSETS int\n0\n",
      points + "POLYGONS 2 1000000000000\nOFFSETS int\n0 1000000000000\nCONNECTIVITY int\n0\n",
      points + "FIELD f 1000000000000\nNULL_ARRAY\n",
      points + "FIELD f 1\na 1000000 1000000 double\n1\n",
  };
  const auto start = std::chrono::steady_clock::now();
  for (const std::string& c : cases) {
    const absl::StatusOr<ReadResult> r = ParseVtk(c, "huge.vtk", Sampled(10));
    EXPECT_FALSE(r.ok()) << c;
    EXPECT_THAT(std::string(r.status().message()), HasSubstr("huge.vtk: line "));
  }
  EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(5));
}

// Every prefix and random corruptions: read or rejected, never a crash (run under ASan).
TEST(VtkReaderTest, TruncationsAndCorruptionsAreHandled) {
  uint64_t state = 1;
  const char replacements[] = "0123456789 \n.-eE\xff\x00\x7f\x80OFFSETS";
  for (const std::string& file : {std::string(kAsciiCube51), BinaryCube()}) {
    for (const size_t samples : {size_t{0}, size_t{16}}) {
      ExpectPrefixesNameTheFile(file, "prefix.vtk: ", [&](const std::string& contents) {
        return ParseVtk(contents, "prefix.vtk", Sampled(samples));
      });
    }
    ExpectCorruptionsNameTheFile(file, "corrupt.vtk",
                                 absl::string_view(replacements, sizeof replacements - 1), &state,
                                 [](const std::string& contents) {
                                   return ParseVtk(contents, "corrupt.vtk", Sampled(16, 3));
                                 });
  }
}

// The checked-in fuzz seeds read; each bad-input file is refused for its one defect.
TEST(VtkReaderTest, CheckedInFiles) {
  const std::string root = SHAPEID_SOURCE_DIR "/tests/";
  const struct {
    const char* file;
    size_t points;  // read with sample_points 0
  } seeds[] = {{"vtk_ascii_cloud_pcl.vtk", 4},
               {"vtk_binary_legacy_cube_polygons.vtk", 8},
               {"vtk_ascii51_strips_field_metadata.vtk", 5},
               {"vtk_binary51_triangle_and_quad.vtk", 4}};
  for (const auto& seed : seeds) {
    const std::string path = root + "fuzz_seeds/testdata/" + seed.file;
    const absl::StatusOr<ReadResult> vertices = ReadPointCloud(path, Sampled(0));
    ASSERT_TRUE(vertices.ok()) << vertices.status();
    EXPECT_EQ(vertices->cloud.size(), seed.points) << seed.file;
    EXPECT_TRUE(ReadPointCloud(path, Sampled(64)).ok()) << seed.file;
  }
  const struct {
    const char* file;
    absl::StatusCode code;
    const char* message;
  } bad[] = {
      {"vtk_points_count_huge.vtk", absl::StatusCode::kInvalidArgument,
       "line 5: POINTS announces 3000000000000 values but only 7 bytes follow"},
      {"vtk_polygon_index_out_of_range.vtk", absl::StatusCode::kInvalidArgument,
       "line 8: POLYGONS point index 3 is not in [0, 3)"},
      {"vtk_binary_points_truncated.vtk", absl::StatusCode::kInvalidArgument,
       "byte offset 70: POINTS announces 9 float values (36 bytes) but only 28 bytes follow"},
      {"vtk_no_points_section.vtk", absl::StatusCode::kInvalidArgument,
       "line 5: the dataset has no POINTS section"},
      {"vtk_unknown_point_type.vtk", absl::StatusCode::kInvalidArgument,
       "line 5: unknown POINTS data type \"float16\""},
      {"vtk_offsets_not_rising.vtk", absl::StatusCode::kInvalidArgument,
       "line 9: OFFSETS value 2 is 2"},
      {"vtk_structured_points.vtk", absl::StatusCode::kUnimplemented,
       "line 4: DATASET STRUCTURED_POINTS has no POINTS"},
  };
  for (const auto& b : bad) {
    const std::string path = root + "bad_input/testdata/" + b.file;
    ExpectError(ReadPointCloud(path, Sampled(10)), b.code, path, b.message);
  }
}

// --- Files written by other tools ------------------------------------------------------------

bool Shell(const std::string& command) { return std::system(command.c_str()) == 0; }

bool HaveVtkPython() { return Shell("/usr/bin/python3 -c 'import vtk' >/dev/null 2>&1"); }

std::vector<Eigen::Vector3d> ReadXyz(const std::string& path) {
  std::vector<Eigen::Vector3d> points;
  std::ifstream in(path);
  double x, y, z;
  while (in >> x >> y >> z) points.emplace_back(x, y, z);
  return points;
}

std::vector<Eigen::Vector3i> ReadTriangles(const std::string& path) {
  std::vector<Eigen::Vector3i> triangles;
  std::ifstream in(path);
  int a, b, c;
  while (in >> a >> b >> c) triangles.emplace_back(a, b, c);
  return triangles;
}

bool OnTriangle(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                const Eigen::Vector3d& c) {
  const Eigen::Vector3d n = (b - a).cross(c - a);
  if (n.norm() == 0) return false;
  if (std::abs(n.normalized().dot(p - a)) > 1e-5) return false;
  // Barycentric coordinates by sub-triangle areas, signed along n.
  const double area = n.squaredNorm();
  const double u = (c - b).cross(p - b).dot(n) / area;
  const double v = (a - c).cross(p - c).dot(n) / area;
  const double w = 1 - u - v;
  return u >= -1e-5 && v >= -1e-5 && w >= -1e-5;
}

// Writes a vtkPolyData of `mode` (cloud: the points of `base`, an .xyz file; sphere: a
// vtkSphereSource mesh of polygons; strips: the same sphere through vtkStripper) with
// vtkPolyDataWriter, ascii and binary, in the legacy 4.2 and the 5.1 layouts, to
// base.{ascii,binary}{42,51}.vtk; then reads each back with VTK's own vtkPolyDataReader and
// dumps its points (%.17g) to FILE.xyz and its triangles (vtkTriangleFilter) to FILE.tri.
constexpr char kVtkScript[] = R"(
import sys, vtk
mode, base = sys.argv[1], sys.argv[2]

def cloud():
    pts = vtk.vtkPoints()
    verts = vtk.vtkCellArray()
    for line in open(base):
        x, y, z = map(float, line.split())
        verts.InsertNextCell(1)
        verts.InsertCellPoint(pts.InsertNextPoint(x, y, z))
    pts.GetData().SetComponentName(0, 'east')  # a METADATA block after POINTS
    pd = vtk.vtkPolyData()
    pd.SetPoints(pts)
    pd.SetVerts(verts)
    time = vtk.vtkDoubleArray()  # a FIELD before POINTS
    time.SetName('TimeValue')
    time.InsertNextValue(1.5)
    pd.GetFieldData().AddArray(time)
    return pd

def sphere():
    s = vtk.vtkSphereSource()
    s.SetThetaResolution(8)
    s.SetPhiResolution(6)
    s.SetRadius(2.0)
    s.SetCenter(0.25, -0.5, 1.0)
    s.Update()
    return s.GetOutput()

def strips():
    s = vtk.vtkStripper()
    s.SetInputData(sphere())
    s.Update()
    return s.GetOutput()

def dump(path):
    r = vtk.vtkPolyDataReader()
    r.SetFileName(path)
    r.Update()
    pd = r.GetOutput()
    with open(path + '.xyz', 'w') as f:
        for i in range(pd.GetNumberOfPoints()):
            f.write('%.17g %.17g %.17g\n' % pd.GetPoint(i))
    t = vtk.vtkTriangleFilter()
    t.SetInputData(pd)
    t.PassVertsOff()
    t.PassLinesOff()
    t.Update()
    tri = t.GetOutput()
    ids = vtk.vtkIdList()
    with open(path + '.tri', 'w') as f:
        for c in range(tri.GetNumberOfCells()):
            tri.GetCellPoints(c, ids)
            f.write(' '.join(str(ids.GetId(k)) for k in range(ids.GetNumberOfIds())) + '\n')

data = {'cloud': cloud, 'sphere': sphere, 'strips': strips}[mode]()
for binary in (False, True):
    for version in (42, 51):
        path = '%s.%s%d.vtk' % (base, 'binary' if binary else 'ascii', version)
        w = vtk.vtkPolyDataWriter()
        w.SetInputData(data)
        w.SetFileName(path)
        if binary:
            w.SetFileTypeToBinary()
        if version == 42:
            w.SetFileVersion(42)
        if w.Write() != 1:
            sys.exit('cannot write ' + path)
        dump(path)
)";

const char* const kVtkVariants[] = {"ascii42", "ascii51", "binary42", "binary51"};

TEST(VtkReaderTest, PythonVtkCloudsReadExactly) {
  if (!HaveVtkPython()) {
    GTEST_SKIP() << "no Python VTK (Debian package python3-vtk9)";
  }
  // Values that VTK's ascii writer (%g, 6 significant digits) keeps exactly.
  const std::vector<Eigen::Vector3f> expected = {
      {0.5f, -1.25f, 3}, {1234.5f, 0.001f, -7}, {123.456f, -0.0625f, 1e-05f}, {-0.3f, 7e8f, 0}};
  std::string xyz;
  for (const auto& p : expected) {
    absl::StrAppendFormat(&xyz, "%.9g %.9g %.9g\n", p.x(), p.y(), p.z());
  }
  const std::string base = WriteTempFile("cloud.xyz", xyz);
  const std::string script = WriteTempFile("write_vtk.py", kVtkScript);
  ASSERT_TRUE(Shell(absl::StrCat("/usr/bin/python3 ", script, " cloud ", base)));
  for (const char* variant : kVtkVariants) {
    const std::string path = absl::StrCat(base, ".", variant, ".vtk");
    const absl::StatusOr<ReadResult> r = ReadPointCloud(path, Sampled(100));
    ASSERT_TRUE(r.ok()) << variant << ": " << r.status();
    const std::vector<Eigen::Vector3d> vtk_read = ReadXyz(path + ".xyz");
    ASSERT_EQ(r->cloud.size(), expected.size()) << variant;
    ASSERT_EQ(vtk_read.size(), expected.size()) << variant;
    for (size_t i = 0; i < expected.size(); ++i) {
      EXPECT_EQ(r->cloud.point(i), expected[i]) << variant << " point " << i;
      EXPECT_EQ(r->cloud.point(i), vtk_read[i].cast<float>()) << variant << " point " << i;
    }
  }
}

TEST(VtkReaderTest, PythonVtkMeshesReadAsVtkReadsThem) {
  if (!HaveVtkPython()) {
    GTEST_SKIP() << "no Python VTK (Debian package python3-vtk9)";
  }
  const std::string script = WriteTempFile("write_vtk.py", kVtkScript);
  for (const char* mode : {"sphere", "strips"}) {
    const std::string base = WriteTempFile(mode, "");
    ASSERT_TRUE(Shell(absl::StrCat("/usr/bin/python3 ", script, " ", mode, " ", base)));
    for (const char* variant : kVtkVariants) {
      SCOPED_TRACE(absl::StrCat(mode, " ", variant));
      const std::string path = absl::StrCat(base, ".", variant, ".vtk");
      const std::vector<Eigen::Vector3d> points = ReadXyz(path + ".xyz");
      const std::vector<Eigen::Vector3i> triangles = ReadTriangles(path + ".tri");
      ASSERT_EQ(points.size(), 34u);
      ASSERT_EQ(triangles.size(), 64u);

      const absl::StatusOr<ReadResult> vertices = ReadPointCloud(path, Sampled(0));
      ASSERT_TRUE(vertices.ok()) << vertices.status();
      ASSERT_EQ(vertices->cloud.size(), points.size());
      for (size_t i = 0; i < points.size(); ++i) {
        EXPECT_EQ(vertices->cloud.point(i), points[i].cast<float>()) << i;
      }

      // Every sampled point lies on one of VTK's triangles, and every triangle of more than
      // the mean area gets some of them: the cells were read as VTK reads them.
      const absl::StatusOr<ReadResult> sampled = ReadPointCloud(path, Sampled(2000, 11));
      ASSERT_TRUE(sampled.ok()) << sampled.status();
      ASSERT_EQ(sampled->cloud.size(), 2000u);
      std::vector<int> hits(triangles.size(), 0);
      std::vector<double> areas;
      for (const auto& t : triangles) {
        areas.push_back((points[t[1]] - points[t[0]]).cross(points[t[2]] - points[t[0]]).norm());
      }
      for (size_t i = 0; i < sampled->cloud.size(); ++i) {
        const Eigen::Vector3d p = sampled->cloud.point(i).cast<double>();
        size_t k = 0;
        while (k < triangles.size() &&
               !OnTriangle(p, points[triangles[k][0]], points[triangles[k][1]],
                           points[triangles[k][2]])) {
          ++k;
        }
        ASSERT_LT(k, triangles.size()) << "point " << i << " is on no triangle";
        ++hits[k];
      }
      double mean = 0;
      for (double a : areas) mean += a / static_cast<double>(areas.size());
      for (size_t k = 0; k < triangles.size(); ++k) {
        if (areas[k] > mean) {
          EXPECT_GT(hits[k], 0) << "triangle " << k;
        }
      }
    }
  }
}

TEST(VtkReaderTest, PclPcd2VtkCloudsReadExactly) {
  if (!Shell("command -v pcl_pcd2vtk >/dev/null 2>&1")) {
    GTEST_SKIP() << "no pcl_pcd2vtk (Debian package pcl-tools)";
  }
  // pcl_pcd2vtk prints 5 significant digits: values it keeps exactly.
  const PointCloud cloud = {
      {0.5f, -1.25f, 3}, {12.375f, 0.0625f, -100}, {1024, 2048.5f, -0.125f}, {1e-07f, 3, 4}};
  const std::string pcd = WriteTempFile("cloud.pcd", "");
  ASSERT_TRUE(WritePcd(pcd, cloud, PcdEncoding::kBinary).ok());
  const std::string vtk = pcd + ".vtk";
  ASSERT_TRUE(Shell(absl::StrCat("pcl_pcd2vtk ", pcd, " ", vtk, " >/dev/null 2>&1")));
  const absl::StatusOr<ReadResult> r = ReadPointCloud(vtk, Sampled(64));
  ASSERT_TRUE(r.ok()) << r.status();
  ASSERT_EQ(r->cloud.size(), cloud.size());
  for (size_t i = 0; i < cloud.size(); ++i) EXPECT_EQ(r->cloud.point(i), cloud.point(i)) << i;
}

}  // namespace
}  // namespace shapeid
