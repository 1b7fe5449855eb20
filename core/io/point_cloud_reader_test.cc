#include "core/io/point_cloud_reader.h"

#include <sys/stat.h>
#include <unistd.h>

#include <cmath>
#include <string>

#include "core/io/io_testing.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"

namespace shapeid {
namespace {

using ::testing::HasSubstr;

std::string DataDir() { return SHAPEID_SOURCE_DIR "/../shared/data"; }

bool Exists(const std::string& path) { return ::access(path.c_str(), R_OK) == 0; }

TEST(PointCloudReaderTest, ChoosesReaderByExtension) {
  EXPECT_EQ(*CloudFormatForPath("a/b.pcd"), CloudFormat::kPcd);
  EXPECT_EQ(*CloudFormatForPath("B.PCD"), CloudFormat::kPcd);
  EXPECT_EQ(*CloudFormatForPath("x.y/z.xyz"), CloudFormat::kXyz);
  EXPECT_EQ(*CloudFormatForPath("scan.txt"), CloudFormat::kXyz);
  EXPECT_EQ(*CloudFormatForPath("scan.Csv"), CloudFormat::kCsv);
  EXPECT_EQ(*CloudFormatForPath("mesh.ply"), CloudFormat::kPly);
  EXPECT_EQ(*CloudFormatForPath("chair_0001.OFF"), CloudFormat::kOff);
  EXPECT_EQ(*CloudFormatForPath("models/pawn.Obj"), CloudFormat::kObj);
  EXPECT_EQ(*CloudFormatForPath("part.STL"), CloudFormat::kStl);
  EXPECT_EQ(*CloudFormatForPath("cloud.vtk"), CloudFormat::kVtk);
  EXPECT_EQ(*CloudFormatForPath("tile.las"), CloudFormat::kLas);
  EXPECT_EQ(*CloudFormatForPath("a.npy"), CloudFormat::kNpy);
  EXPECT_EQ(*CloudFormatForPath("a.npz"), CloudFormat::kNpz);
  EXPECT_EQ(*CloudFormatForPath("o3d.xyzn"), CloudFormat::kXyz);
  EXPECT_EQ(*CloudFormatForPath("o3d.xyzrgb"), CloudFormat::kXyz);
  EXPECT_EQ(*CloudFormatForPath("leica.pts"), CloudFormat::kPts);
  // A final .gz is looked through; the format is the one before it.
  EXPECT_EQ(*CloudFormatForPath("scan.pcd.gz"), CloudFormat::kPcd);
  EXPECT_EQ(*CloudFormatForPath("scan.XYZ.GZ"), CloudFormat::kXyz);
  for (const char* bad : {"mesh.3ds", "noext", "dir.pcd/file", "trailing.", "a.gz", ".gz"}) {
    const absl::StatusOr<CloudFormat> f = CloudFormatForPath(bad);
    ASSERT_FALSE(f.ok()) << bad;
    EXPECT_EQ(f.status().code(), absl::StatusCode::kInvalidArgument);
    EXPECT_THAT(std::string(f.status().message()), HasSubstr(bad));
    EXPECT_THAT(std::string(f.status().message()), HasSubstr(SupportedExtensions()));
  }
  // LAZ is named, with the way to decompress it.
  const absl::StatusOr<CloudFormat> laz = CloudFormatForPath("tile.LAZ");
  ASSERT_FALSE(laz.ok());
  EXPECT_THAT(std::string(laz.status().message()), HasSubstr("laszip -i in.laz -o out.las"));
}

TEST(PointCloudReaderTest, FormatNamesRoundTrip) {
  const std::vector<std::string>& names = CloudFormatNames();
  for (size_t i = 0; i < names.size(); ++i) {
    EXPECT_EQ(*CloudFormatForName(names[i]), static_cast<CloudFormat>(i)) << names[i];
    EXPECT_EQ(*CloudFormatForPath("f." + names[i]), static_cast<CloudFormat>(i)) << names[i];
  }
  EXPECT_EQ(*CloudFormatForName(".PCD"), CloudFormat::kPcd);
  EXPECT_EQ(*CloudFormatForName("txt"), CloudFormat::kXyz);
  const absl::StatusOr<CloudFormat> bad = CloudFormatForName("e57");
  ASSERT_FALSE(bad.ok());
  EXPECT_THAT(std::string(bad.status().message()), HasSubstr("pcd, ply, off"));
}

TEST(PointCloudReaderTest, AnUnknownExtensionWithoutASignatureIsRefused) {
  const std::string path = WriteTempFile("cloud.e57", "1 2 3\n");
  const absl::StatusOr<ReadResult> r = ReadPointCloud(path);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(std::string(r.status().message()), HasSubstr("\".e57\""));
  EXPECT_THAT(std::string(r.status().message()),
              HasSubstr("nor do its first bytes carry the signature of a format that has one "
                        "(pcd, ply, off, stl, vtk, las, npy, npz)"));
}

// A file named by a tool that knows nothing of extensions (a ROS bag dump, a download) is read
// by its first bytes, gzipped or not; the extension, when it names a format, still decides.
TEST(PointCloudReaderTest, AFileWithoutAKnownExtensionIsReadByItsSignature) {
  const std::string ply_text =
      "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
      "property float z\nend_header\n1 2 3\n4 5 6\n7 8 10\n";
  for (const std::string& name : {std::string("frame_0001"), std::string("scan.dat")}) {
    const absl::StatusOr<ReadResult> r = ReadPointCloud(WriteTempFile(name, ply_text), Raw());
    ASSERT_TRUE(r.ok()) << name << ": " << r.status();
    ASSERT_EQ(r->cloud.size(), 3u);
    EXPECT_EQ(r->cloud.point(2), Eigen::Vector3f(7, 8, 10));
  }
  const absl::StatusOr<ReadResult> pcd = ReadPointCloud(
      WriteTempFile("cloud",
                    "# .PCD v0.7\nVERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\n"
                    "COUNT 1 1 1\nWIDTH 1\nHEIGHT 1\nPOINTS 1\nDATA ascii\n1 2 3\n"),
      Raw());
  ASSERT_TRUE(pcd.ok()) << pcd.status();
  EXPECT_EQ(pcd->cloud.point(0), Eigen::Vector3f(1, 2, 3));
  // A PLY named .xyz is read as text, as its name says, and fails there.
  EXPECT_FALSE(ReadPointCloud(WriteTempFile("mislabeled.xyz", ply_text)).ok());
}

TEST(PointCloudReaderTest, AnInputFormatOverridesTheExtension) {
  const std::string path = WriteTempFile("scan.dat", "1 2 3\n4 5 6\n7 8 10\n");
  ReadOptions options = Raw();
  options.input_format = CloudFormat::kXyz;
  const absl::StatusOr<ReadResult> r = ReadPointCloud(path, options);
  ASSERT_TRUE(r.ok()) << r.status();
  EXPECT_EQ(r->cloud.point(2), Eigen::Vector3f(7, 8, 10));
  // Standard input has no name to choose by: the error says which flag gives the format.
  const absl::StatusOr<ReadResult> stdin_read = ReadPointCloud("-", Raw());
  ASSERT_FALSE(stdin_read.ok());
  EXPECT_THAT(std::string(stdin_read.status().message()), HasSubstr("--input-format"));
}

TEST(PointCloudReaderTest, PtsSkipsCountLinesAndOpen3dTextFormatsReadTheirFirstColumns) {
  const std::string pts = WriteTempFile("s.pts",
                                        "2\n1 2 3 10 255 0 0\n4 5 6 11 0 255 0\n"
                                        "1\n7 8 9 12 0 0 255\n");
  const absl::StatusOr<ReadResult> r = ReadPointCloud(pts, Raw());
  ASSERT_TRUE(r.ok()) << r.status();
  ASSERT_EQ(r->cloud.size(), 3u);
  EXPECT_EQ(r->cloud.point(2), Eigen::Vector3f(7, 8, 9));
  // In .xyz a lone number is still an error (a damaged line, not a count).
  const std::string xyz = WriteTempFile("s.xyz", "1 2 3\n2\n4 5 6\n");
  ExpectError(ReadPointCloud(xyz, Raw()), absl::StatusCode::kInvalidArgument, xyz, "line 2");
  const std::string xyzn = WriteTempFile("n.xyzn", "1 2 3 0 0 1\n4 5 6 0 1 0\n");
  const absl::StatusOr<ReadResult> n = ReadPointCloud(xyzn, Raw());
  ASSERT_TRUE(n.ok()) << n.status();
  EXPECT_EQ(n->cloud.point(1), Eigen::Vector3f(4, 5, 6));
}

// Regular files are mapped, empty ones read: both paths give what the parser gives.
TEST(PointCloudReaderTest, MappedAndEmptyFilesReadLikeContentsInMemory) {
  const std::string text = "1 2 3\n4 5 6.5\n";
  const absl::StatusOr<ReadResult> mapped = ReadPointCloud(WriteTempFile("m.xyz", text), Raw());
  ASSERT_TRUE(mapped.ok()) << mapped.status();
  ASSERT_EQ(mapped->cloud.size(), 2u);
  EXPECT_EQ(mapped->cloud.point(1), Eigen::Vector3f(4, 5, 6.5f));

  const absl::StatusOr<ReadResult> empty = ReadPointCloud(WriteTempFile("e.xyz", ""), Raw());
  ASSERT_TRUE(empty.ok()) << empty.status();
  EXPECT_TRUE(empty->cloud.empty());
  const absl::StatusOr<ReadResult> empty_pcd = ReadPointCloud(WriteTempFile("e.pcd", ""));
  ExpectError(empty_pcd, absl::StatusCode::kInvalidArgument, "e.pcd", "no DATA line");
}

TEST(PointCloudReaderTest, MissingFileAndDirectory) {
  const std::string missing = testing::TempDir() + "shapeid_no_such_file.xyz";
  const absl::StatusOr<ReadResult> r = ReadPointCloud(missing);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), absl::StatusCode::kNotFound);
  EXPECT_THAT(std::string(r.status().message()), HasSubstr(missing));

  const std::string dir = testing::TempDir() + "shapeid_dir_test.pcd";
  ::mkdir(dir.c_str(), 0700);
  const absl::StatusOr<ReadResult> d = ReadPointCloud(dir);
  ASSERT_FALSE(d.ok());
  EXPECT_EQ(d.status().code(), absl::StatusCode::kInvalidArgument);
  ::rmdir(dir.c_str());
}

TEST(PointCloudReaderTest, RecenteringKeepsCentimetresOfGeoreferencedCoordinates) {
  // DALES-like: ~5e5 m easting, where float32 steps by 3 cm to 6 cm.
  const std::string path =
      WriteTempFile("geo.xyz",
                    "500000.01 4000000.01 100.01\n500000.02 4000000.03 100.02\n"
                    "500000.05 4000000.04 100.05\n");
  const absl::StatusOr<ReadResult> r = ReadPointCloud(path);
  ASSERT_TRUE(r.ok()) << r.status();
  ASSERT_EQ(r->cloud.size(), 3u);
  EXPECT_NEAR(r->offset.x(), 500000.03, 1e-9);
  EXPECT_NEAR(r->offset.y(), 4000000.025, 1e-8);
  EXPECT_NEAR(r->offset.z(), 100.03, 1e-9);
  const double expected[3][3] = {{500000.01, 4000000.01, 100.01},
                                 {500000.02, 4000000.03, 100.02},
                                 {500000.05, 4000000.04, 100.05}};
  for (size_t i = 0; i < 3; ++i) {
    for (int a = 0; a < 3; ++a) {
      // Back to the file's coordinates to well under a millimetre.
      EXPECT_NEAR(r->cloud.point(i)[a] + r->offset[a], expected[i][a], 1e-5) << i << " " << a;
    }
  }
  EXPECT_NEAR(r->cloud.point(1).x() - r->cloud.point(0).x(), 0.01, 1e-5);

  // Without recentering the centimetre is lost: that is why it is the default.
  ReadOptions raw;
  raw.recenter = false;
  const absl::StatusOr<ReadResult> lossy = ReadPointCloud(path, raw);
  ASSERT_TRUE(lossy.ok()) << lossy.status();
  EXPECT_EQ(lossy->offset, Eigen::Vector3d::Zero());
  EXPECT_GT(std::abs((lossy->cloud.point(1).y() - lossy->cloud.point(0).y()) - 0.02), 0.005);
}

TEST(PointCloudReaderTest, ParsePointCloudFromMemory) {
  const absl::StatusOr<ReadResult> r =
      ParsePointCloud("x;y;z\n1;2;3\n", CloudFormat::kCsv, "upload");
  ASSERT_TRUE(r.ok()) << r.status();
  EXPECT_EQ(r->cloud.size(), 1u);
  const absl::StatusOr<ReadResult> bad = ParsePointCloud("1 2\n", CloudFormat::kXyz, "upload");
  ASSERT_FALSE(bad.ok());
  EXPECT_THAT(std::string(bad.status().message()), HasSubstr("upload: line 1"));
}

TEST(PointCloudReaderTest, RealModelNet10File) {
  const std::string path = DataDir() + "/modelnet10/chair/train/chair_0001.pcd";
  if (!Exists(path)) GTEST_SKIP() << "no ModelNet10 data at " << path;
  const absl::StatusOr<ReadResult> r = ReadPointCloud(path);
  ASSERT_TRUE(r.ok()) << r.status();
  EXPECT_EQ(r->cloud.size(), 1024u);
  EXPECT_EQ(r->dropped_non_finite, 0u);
  EXPECT_TRUE(ValidateCloud(r->cloud).ok());
  for (float v : r->cloud.xyz()) ASSERT_TRUE(std::isfinite(v));
}

TEST(PointCloudReaderTest, RealDalesFile) {
  const std::string path = DataDir() + "/dales-objects/car/100.xyz";
  if (!Exists(path)) GTEST_SKIP() << "no DALES data at " << path;
  const absl::StatusOr<ReadResult> r = ReadPointCloud(path);
  ASSERT_TRUE(r.ok()) << r.status();
  EXPECT_GE(r->cloud.size(), 100u);
  EXPECT_TRUE(ValidateCloud(r->cloud).ok());
}

}  // namespace
}  // namespace shapeid
