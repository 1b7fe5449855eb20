// `shapeid scene` against an in-process server on a loopback port: a table frame written as a
// PCD file with missing returns (NaN) among its points; the objects in table, JSON and CSV;
// the frame written back colored (PLY, PCD) and drawn (PNG); errors as one line each.

#include "client/cli/scene_command.h"

#include <zlib.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_split.h"
#include "client/cli/cli_testing.h"
#include "client/client.h"
#include "core/io/pcd_writer.h"
#include "core/io/point_cloud_reader.h"
#include "core/testing/test_clouds.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "server/server.h"

namespace shapeid {
namespace {

namespace fs = std::filesystem;
using cli_testing::Captured;
using cli_testing::PythonOnJsonLines;
using ::testing::HasSubstr;
using testing_clouds::kShapeNames;
using testing_clouds::ShapeCloud;

constexpr size_t kLeadingNans = 5;

class SceneCommandTest : public ::testing::Test {
 protected:
  void SetUp() override {
    ServerOptions server_options;
    server_options.listen = "127.0.0.1:0";
    auto server = ShapeIdServer::Start(server_options);
    ASSERT_TRUE(server.ok()) << server.status();
    server_ = std::move(server).value();
    root_ = cli_testing::ScratchDir("scene_command");
    ClientOptions client_options;
    client_options.target = server_->address();
    auto client = Client::Connect(client_options);
    ASSERT_TRUE(client.ok()) << client.status();
    client_ = *std::move(client);
    for (const char* name : {"shapes", "empty"}) {
      v1::CreateGalleryRequest create;
      create.set_name(name);
      create.set_descriptor_spec("rphsd");
      create.mutable_knn()->set_k(1);
      ASSERT_TRUE(client_->CreateGallery(create).ok());
    }
    std::vector<PointCloud> clouds;
    for (int kind = 0; kind < 3; ++kind) {
      for (uint32_t seed = 1; seed <= 3; ++seed) clouds.push_back(ShapeCloud(kind, seed, 2000));
    }
    std::vector<TrainSample> samples;
    for (size_t i = 0; i < clouds.size(); ++i)
      samples.push_back({kShapeNames[i / 3], 0, &clouds[i]});
    ASSERT_TRUE(client_->Train("shapes", samples).ok());

    // NaN points first (a depth camera's missing returns), then the table with a box, a
    // sphere and a rod (testing_clouds::TableWithShapes).
    const float nan = std::numeric_limits<float>::quiet_NaN();
    for (size_t i = 0; i < kLeadingNans; ++i) frame_.Add(nan, nan, nan);
    std::vector<std::vector<uint32_t>> truth;
    const PointCloud table = testing_clouds::TableWithShapes(&truth);
    table_points_ = truth[0].front();
    for (int kind = 0; kind < 3; ++kind) first_[kind] = kLeadingNans + truth[kind].front();
    for (size_t i = 0; i < table.size(); ++i) frame_.Add(table.point(i));
    ASSERT_TRUE(WritePcd(Path("frame.pcd"), frame_).ok());
  }
  void TearDown() override {
    if (server_) server_->Shutdown(absl::ZeroDuration());
  }

  std::string Path(const std::string& name) const { return (root_ / name).string(); }

  // Runs the command with `options` (gallery "shapes", FRAME frame.pcd unless set).
  int Run(SceneCommandOptions options, OutputFormat format = OutputFormat::kTable) {
    if (options.gallery.empty()) options.gallery = "shapes";
    if (options.frames.empty()) options.frames = {Path("frame.pcd")};
    CliContext context;
    context.out = out_->get();
    context.err = err_->get();
    context.format = format;
    context.progress = ProgressMode::kOff;
    context.client.target = server_->address();
    return RunScene(options, context);
  }

  // Which object (0 box, 1 sphere, 2 rod) point i of the frame belongs to, -1 none.
  int KindOf(size_t i) const {
    for (int kind = 0; kind < 3; ++kind) {
      if (i >= first_[kind] && i < first_[kind] + 3000) return kind;
    }
    return -1;
  }

  std::unique_ptr<ShapeIdServer> server_;
  std::unique_ptr<Client> client_;
  fs::path root_;
  PointCloud frame_;
  size_t table_points_ = 0;
  size_t first_[3] = {0, 0, 0};
  // Fresh() replaces them, for the next run's output alone.
  std::unique_ptr<Captured> out_ = std::make_unique<Captured>();
  std::unique_ptr<Captured> err_ = std::make_unique<Captured>();
  void Fresh() {
    out_ = std::make_unique<Captured>();
    err_ = std::make_unique<Captured>();
  }
};

TEST_F(SceneCommandTest, TheTableListsEachObjectThePlaneAndWhereThePointsWent) {
  ASSERT_EQ(Run({}), kExitOk) << err_->contents();
  const std::string out = out_->contents();
  EXPECT_THAT(out, HasSubstr(absl::StrCat(Path("frame.pcd"), ": 3 objects\n")));
  EXPECT_THAT(out, HasSubstr("LABEL"));
  EXPECT_THAT(out, HasSubstr("CENTROID (x y z)"));
  // The sphere's row: its label, full confidence, points, centroid and 10 cm box.
  EXPECT_THAT(out,
              ::testing::ContainsRegex(
                  R"(sphere +100\.0% +3000 +-0\.30[0-9] +-0\.10[0-9] +-0\.42[0-9] +0\.1[0-9]+ )"));
  EXPECT_THAT(out, ::testing::ContainsRegex(
                       R"([0-2] +box +100\.0% +3000 +0\.10[0-9] +0\.30[0-9] +-0\.46[0-9] )"));
  EXPECT_THAT(out,
              HasSubstr("+1.0000 z +0.5000 = 0, " + std::to_string(table_points_) + " points"));
  EXPECT_THAT(out, HasSubstr(absl::StrCat("points: ", frame_.size(), " in the frame, ",
                                          table_points_, " on planes, 9000 in objects, ",
                                          kLeadingNans, " non-finite, 0 outside the region")));
  EXPECT_EQ(err_->contents(), "");
}

TEST_F(SceneCommandTest, JsonAndCsvCarryTheObjectsAndIndicesCountTheMissingPoints) {
  SceneCommandOptions options;
  options.indices = true;
  ASSERT_EQ(Run(options, OutputFormat::kJson), kExitOk) << err_->contents();
  const std::string json = out_->contents();
  EXPECT_EQ(
      PythonOnJsonLines(json, "len(rows), sorted(o[\"label\"] for o in rows[0][\"objects\"])"),
      "1 ['box', 'rod', 'sphere']");
  EXPECT_EQ(PythonOnJsonLines(json,
                              "rows[0][\"non_finite_points\"], rows[0][\"points\"], "
                              "rows[0][\"planes\"][0][\"points\"]"),
            absl::StrCat(kLeadingNans, " ", frame_.size(), " ", table_points_));
  // The sphere's indices are its points' places in the file, NaN points counted.
  EXPECT_EQ(PythonOnJsonLines(json, "[o[\"indices\"] == list(range(" + std::to_string(first_[1]) +
                                        ", " + std::to_string(first_[1] + 3000) +
                                        ")) for o in rows[0][\"objects\"] if o[\"label\"] == "
                                        "\"sphere\"]"),
            "[True]");
  EXPECT_EQ(PythonOnJsonLines(json,
                              "[round(c, 2) for c in [o for o in rows[0][\"objects\"] if "
                              "o[\"label\"] == \"sphere\"][0][\"centroid\"]]"),
            "[-0.3, -0.1, -0.42]");

  Fresh();
  ASSERT_EQ(Run({}, OutputFormat::kCsv), kExitOk) << err_->contents();
  const std::vector<std::string> lines = absl::StrSplit(out_->contents(), "\r\n");
  ASSERT_EQ(lines.size(), 5u);  // header, 3 objects, the empty rest after the last CRLF
  EXPECT_EQ(lines[0],
            "file,object,label,unknown,confidence,points,centroid_x,centroid_y,centroid_z,size_x,"
            "size_y,size_z,nearest_label,nearest_distance,nearest_source,error");
  for (int row = 1; row <= 3; ++row) {
    const std::vector<std::string> fields = absl::StrSplit(lines[row], ',');
    ASSERT_EQ(fields.size(), 16u) << lines[row];
    EXPECT_EQ(fields[0], Path("frame.pcd"));
    EXPECT_EQ(fields[1], std::to_string(row - 1));
    EXPECT_EQ(fields[3], "false");
    EXPECT_EQ(fields[5], "3000");
    EXPECT_EQ(fields[12], fields[2]);  // the nearest sample has the object's label
    EXPECT_EQ(fields[15], "");
  }
  EXPECT_EQ(lines[4], "");
}

// The colored frame reads back with every point in its place (NaN ones too); its colors,
// read from the file's bytes: each object's label color, the table grey, missing points dark.
TEST_F(SceneCommandTest, TheColoredFrameReadsBackWithItsLabelsColors) {
  for (const std::string name : {"colored.ply", "colored.pcd"}) {
    SCOPED_TRACE(name);
    SceneCommandOptions options;
    options.colored = Path(name);
    ASSERT_EQ(Run(options), kExitOk) << err_->contents();
    ReadOptions read;
    read.recenter = false;
    const absl::StatusOr<ReadResult> back = ReadPointCloud(Path(name), read);
    ASSERT_TRUE(back.ok()) << back.status();
    ASSERT_EQ(back->cloud.size(), frame_.size());
    EXPECT_EQ(back->non_finite_points, kLeadingNans);
    EXPECT_EQ(back->cloud.point(first_[1] + 7), frame_.point(first_[1] + 7));

    std::string bytes;
    ASSERT_TRUE(ReadFileContents(Path(name)).ok());
    bytes = *ReadFileContents(Path(name));
    const bool ply = name.back() == 'y';
    const std::string end = ply ? "end_header\n" : "DATA binary\n";
    const size_t data = bytes.find(end) + end.size();
    const size_t step = ply ? 15 : 16;
    ASSERT_EQ(bytes.size(), data + step * frame_.size());
    const auto color = [&](size_t i) {
      std::array<uint8_t, 3> rgb;
      if (ply) {
        std::memcpy(rgb.data(), &bytes[data + step * i + 12], 3);
      } else {
        uint32_t packed;
        std::memcpy(&packed, &bytes[data + step * i + 12], 4);
        rgb = {static_cast<uint8_t>(packed >> 16), static_cast<uint8_t>(packed >> 8),
               static_cast<uint8_t>(packed)};
      }
      return rgb;
    };
    size_t grey = 0;
    for (size_t i = 0; i < frame_.size(); ++i) {
      const int kind = KindOf(i);
      if (i < kLeadingNans) {
        EXPECT_EQ(color(i), kScenePalette[kSceneUnassigned]) << i;
      } else if (kind >= 0) {
        ASSERT_EQ(color(i), kScenePalette[SceneLabelColor(kShapeNames[kind])]) << i;
      } else {
        grey += color(i) == kScenePalette[kScenePlane];
      }
    }
    EXPECT_EQ(grey, table_points_);
    EXPECT_NE(kScenePalette[SceneLabelColor("box")], kScenePalette[SceneLabelColor("sphere")]);
  }
}

TEST_F(SceneCommandTest, ThePictureIsAValidPngOfTheColors) {
  SceneCommandOptions options;
  options.picture = Path("scene.png");
  ASSERT_EQ(Run(options), kExitOk) << err_->contents();
  const absl::StatusOr<std::string> png = ReadFileContents(Path("scene.png"));
  ASSERT_TRUE(png.ok()) << png.status();
  ASSERT_GT(png->size(), 33u);
  EXPECT_EQ(png->substr(0, 8), std::string("\x89PNG\r\n\x1a\n", 8));
  const auto big_endian = [&](size_t at) {
    uint32_t v = 0;
    for (size_t i = 0; i < 4; ++i) v = (v << 8) | static_cast<uint8_t>((*png)[at + i]);
    return v;
  };
  // Chunks, each CRC checked; the pixels' palette indices counted.
  uint32_t width = 0, height = 0;
  std::string idat, types;
  for (size_t at = 8; at + 12 <= png->size();) {
    const uint32_t length = big_endian(at);
    ASSERT_LE(at + 12 + length, png->size());
    const std::string type = png->substr(at + 4, 4);
    EXPECT_EQ(big_endian(at + 8 + length),
              static_cast<uint32_t>(
                  crc32(0, reinterpret_cast<const Bytef*>(png->data() + at + 4), 4 + length)));
    if (type == "IHDR") {
      width = big_endian(at + 8);
      height = big_endian(at + 12);
    }
    if (type == "IDAT") idat += png->substr(at + 8, length);
    types += type + " ";
    at += 12 + length;
  }
  EXPECT_EQ(types, "IHDR PLTE IDAT IEND ");
  EXPECT_EQ(width, 3u * 320 + 2 * 6);
  EXPECT_EQ(height, 320u);
  std::string rows(static_cast<size_t>(width + 1) * height, '\0');
  uLongf size = rows.size();
  ASSERT_EQ(uncompress(reinterpret_cast<Bytef*>(rows.data()), &size,
                       reinterpret_cast<const Bytef*>(idat.data()), idat.size()),
            Z_OK);
  EXPECT_EQ(size, rows.size());
  for (const uint8_t index :
       {kScenePlane, SceneLabelColor("box"), SceneLabelColor("sphere"), SceneLabelColor("rod")}) {
    EXPECT_NE(rows.find(static_cast<char>(index)), std::string::npos) << int{index};
  }
}

TEST_F(SceneCommandTest, TheRegionAndSegmentationFlagsReachTheServer) {
  SceneCommandOptions options;
  options.region = "-0.5,-0.3,-1,-0.1,0.1,0";  // the sphere's corner of the table
  ASSERT_EQ(Run(options), kExitOk) << err_->contents();
  EXPECT_THAT(out_->contents(), HasSubstr(": 1 object\n"));
  EXPECT_THAT(out_->contents(), HasSubstr(" sphere "));
  Fresh();
  options = {};
  options.call.segmentation.set_max_planes(0);  // --planes 0: the table is one huge cluster
  options.call.segmentation.set_max_cluster_points(5000);
  ASSERT_EQ(Run(options), kExitOk) << err_->contents();
  EXPECT_THAT(out_->contents(), HasSubstr(absl::StrCat(table_points_, " in large clusters")));
}

TEST_F(SceneCommandTest, ErrorsAreOneClearLine) {
  const auto line = [&](SceneCommandOptions options, int code) {
    Fresh();
    EXPECT_EQ(Run(std::move(options)), code);
    const std::string text = err_->contents();
    EXPECT_EQ(std::count(text.begin(), text.end(), '\n'), 1) << text;
    return text;
  };
  SceneCommandOptions options;
  options.gallery = "nowhere";
  EXPECT_THAT(line(options, kExitRefused), HasSubstr("nowhere"));
  options.gallery = "empty";
  EXPECT_THAT(line(options, kExitRefused), HasSubstr("no samples"));
  options = {};
  options.region = "0,0,0,1,1";
  EXPECT_THAT(line(options, kExitUsage), HasSubstr("--region: 5 numbers; expected 6"));
  options.region = "0,0,0,1,-1,1";
  EXPECT_THAT(line(options, kExitUsage), HasSubstr("--region: the first corner's y"));
  options = {};
  options.colored = Path("out.txt");
  EXPECT_THAT(line(options, kExitUsage), HasSubstr("must end in .ply or .pcd"));
  options.colored = Path("out.ply");
  options.frames = {Path("frame.pcd"), Path("frame.pcd")};
  EXPECT_THAT(line(options, kExitUsage), HasSubstr("one frame"));
  options = {};
  options.picture = Path("out.jpg");
  EXPECT_THAT(line(options, kExitUsage), HasSubstr("must end in .png"));
  options = {};
  options.frames = {Path("missing.pcd"), Path("frame.pcd")};
  EXPECT_THAT(line(options, kExitSomeInputsFailed), HasSubstr("missing.pcd"));
  EXPECT_THAT(out_->contents(), HasSubstr(": 3 objects"));  // the next frame still answered
  options = {};
  options.call.segmentation.set_min_cluster_points(10);
  options.call.segmentation.set_max_cluster_points(5);
  EXPECT_THAT(line(options, kExitSomeInputsFailed),
              HasSubstr("min_cluster_points is 10 and max_cluster_points 5"));
}

}  // namespace
}  // namespace shapeid
