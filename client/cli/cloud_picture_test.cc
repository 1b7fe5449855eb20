#include "client/cli/cloud_picture.h"

#include <zlib.h>

#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <string>

#include "absl/strings/escaping.h"
#include "absl/strings/string_view.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"

namespace shapeid {
namespace {

using ::testing::StartsWith;

// Pixels drawn as points (any depth shade).
int PointPixels(const CloudPicture& picture) {
  int n = 0;
  for (uint8_t p : picture.pixels) n += p >= kPictureNearest ? 1 : 0;
  return n;
}

// The origin and the three unit points: a unit box, scale 90 px per unit in a 96 px view
// (frame, margin, 2 px points), so each corner lands on a known pixel.
PointCloud Corners() { return PointCloud({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}}); }

constexpr uint8_t kFarthest = kPictureNearest + kPictureShades - 1;

TEST(CloudPictureTest, KnownPointsLightTheExpectedPixels) {
  const CloudPicture picture = RenderCloudViews(Corners());
  ASSERT_EQ(picture.width, 3 * 96 + 2 * 6);
  ASSERT_EQ(picture.height, 96);
  ASSERT_EQ(picture.pixels.size(), 300u * 96u);
  // Four 2 x 2 points per view, of which two coincide in each: 3 squares of 4 pixels.
  EXPECT_EQ(PointPixels(picture), 3 * 3 * 4);

  // Front (x right, y up, seen from +z): the origin and (0,0,1) share the bottom-left corner,
  // where the nearer, (0,0,1), shows in the darkest shade.
  EXPECT_EQ(picture.at(2, 92), kPictureNearest);
  EXPECT_EQ(picture.at(3, 93), kPictureNearest);
  EXPECT_EQ(picture.at(92, 92), kFarthest);  // (1,0,0)
  EXPECT_EQ(picture.at(2, 2), kFarthest);    // (0,1,0)
  EXPECT_EQ(picture.at(4, 92), kPictureBackground);
  EXPECT_EQ(picture.at(48, 48), kPictureBackground);
  // Side (-z right, y up, seen from +x), starting at x = 102: (1,0,0) hides the origin.
  EXPECT_EQ(picture.at(102 + 92, 92), kPictureNearest);
  EXPECT_EQ(picture.at(102 + 2, 92), kFarthest);  // (0,0,1)
  EXPECT_EQ(picture.at(102 + 92, 2), kFarthest);  // (0,1,0)
  // Top (x right, -z up, seen from +y), starting at x = 204: (0,1,0) hides the origin.
  EXPECT_EQ(picture.at(204 + 2, 2), kPictureNearest);
  EXPECT_EQ(picture.at(204 + 2, 92), kFarthest);  // (0,0,1)
  EXPECT_EQ(picture.at(204 + 92, 2), kFarthest);  // (1,0,0)

  // Frames around each view, background between them.
  for (int left : {0, 102, 204}) {
    EXPECT_EQ(picture.at(left, 50), kPictureFrame);
    EXPECT_EQ(picture.at(left + 95, 50), kPictureFrame);
    EXPECT_EQ(picture.at(left + 50, 0), kPictureFrame);
    EXPECT_EQ(picture.at(left + 50, 95), kPictureFrame);
  }
  EXPECT_EQ(picture.at(98, 50), kPictureBackground);

  // The shade follows depth: a point halfway deep gets the middle shade.
  PointCloud with_middle = Corners();
  with_middle.Add(0.5f, 0.5f, 0.5f);
  const CloudPicture middle = RenderCloudViews(with_middle);
  EXPECT_EQ(middle.at(47, 47), kPictureNearest + 12);
}

TEST(CloudPictureTest, EmptyDegenerateAndNonFiniteClouds) {
  const CloudPicture empty = RenderCloudViews(PointCloud());
  EXPECT_EQ(empty.width, 300);
  EXPECT_EQ(PointPixels(empty), 0);
  EXPECT_EQ(empty.at(0, 0), kPictureFrame);

  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float inf = std::numeric_limits<float>::infinity();
  EXPECT_EQ(PointPixels(RenderCloudViews(PointCloud({{nan, 0, 0}, {0, inf, 0}}))), 0);
  PointCloud corners_and_nan = Corners();
  corners_and_nan.Add(nan, 5, 5);
  EXPECT_EQ(RenderCloudViews(corners_and_nan).pixels, RenderCloudViews(Corners()).pixels);

  // One repeated point: a single square in the middle of each view.
  const CloudPicture one = RenderCloudViews(PointCloud({{3, 3, 3}, {3, 3, 3}}));
  EXPECT_EQ(PointPixels(one), 3 * 4);
  EXPECT_EQ(one.at(47, 47), kPictureNearest);

  // Tiny sizes are raised, not trusted.
  CloudPictureOptions tiny;
  tiny.view_pixels = 0;
  tiny.gap_pixels = -5;
  tiny.point_pixels = 100;
  const CloudPicture small = RenderCloudViews(Corners(), tiny);
  EXPECT_EQ(small.width, 24);
  EXPECT_EQ(small.height, 8);
  EXPECT_GT(PointPixels(small), 0);
}

uint32_t BigEndian(absl::string_view bytes, size_t at) {
  uint32_t v = 0;
  for (size_t i = 0; i < 4; ++i) v = (v << 8) | static_cast<uint8_t>(bytes[at + i]);
  return v;
}

// Decodes what EncodePng writes (one IDAT, filter 0 rows), checking every chunk's CRC.
struct DecodedPng {
  uint32_t width = 0, height = 0;
  std::string ihdr_rest;  // bit depth, color type, compression, filter, interlace
  std::string palette;
  std::string rows;  // inflated IDAT
  std::vector<std::string> chunk_types;
};
DecodedPng Decode(const std::string& png) {
  DecodedPng out;
  EXPECT_EQ(png.substr(0, 8), std::string("\x89PNG\r\n\x1a\n", 8));
  std::string idat;
  for (size_t at = 8; at + 12 <= png.size();) {
    const uint32_t length = BigEndian(png, at);
    EXPECT_LE(at + 12 + length, png.size());
    if (at + 12 + length > png.size()) break;
    const std::string type = png.substr(at + 4, 4);
    const std::string data = png.substr(at + 8, length);
    const uint32_t crc = static_cast<uint32_t>(
        crc32(0, reinterpret_cast<const Bytef*>(png.data() + at + 4), 4 + length));
    EXPECT_EQ(BigEndian(png, at + 8 + length), crc) << type;
    out.chunk_types.push_back(type);
    if (type == "IHDR") {
      out.width = BigEndian(data, 0);
      out.height = BigEndian(data, 4);
      out.ihdr_rest = data.substr(8);
    } else if (type == "PLTE") {
      out.palette = data;
    } else if (type == "IDAT") {
      idat += data;
    }
    at += 12 + length;
  }
  out.rows.resize(static_cast<size_t>(out.width + 1) * out.height + 1);
  uLongf size = out.rows.size();
  EXPECT_EQ(uncompress(reinterpret_cast<Bytef*>(out.rows.data()), &size,
                       reinterpret_cast<const Bytef*>(idat.data()), idat.size()),
            Z_OK);
  out.rows.resize(size);
  return out;
}

TEST(CloudPictureTest, PngDecodesToThePicture) {
  const CloudPicture picture = RenderCloudViews(Corners());
  const std::string png = EncodePng(picture);
  const DecodedPng decoded = Decode(png);
  EXPECT_EQ(decoded.chunk_types, (std::vector<std::string>{"IHDR", "PLTE", "IDAT", "IEND"}));
  EXPECT_EQ(decoded.width, 300u);
  EXPECT_EQ(decoded.height, 96u);
  EXPECT_EQ(decoded.ihdr_rest, std::string("\x08\x03\x00\x00\x00", 5));
  ASSERT_EQ(decoded.palette.size(), 3u * kPictureColors);
  EXPECT_EQ(decoded.palette.substr(0, 6), "\xFF\xFF\xFF\xD1\xD5\xDB");  // white, frame grey
  ASSERT_EQ(decoded.rows.size(), 301u * 96u);
  for (int y = 0; y < 96; ++y) {
    EXPECT_EQ(decoded.rows[static_cast<size_t>(y) * 301], '\0') << y;  // filter: none
    for (int x = 0; x < 300; ++x) {
      ASSERT_EQ(static_cast<uint8_t>(decoded.rows[static_cast<size_t>(y) * 301 + 1 + x]),
                picture.at(x, y))
          << x << "," << y;
    }
  }

  const std::string uri = PngDataUri(png);
  EXPECT_THAT(uri, StartsWith("data:image/png;base64,iVBORw0KGgo"));
  std::string back;
  ASSERT_TRUE(absl::Base64Unescape(absl::string_view(uri).substr(22), &back));
  EXPECT_EQ(back, png);
}

TEST(CloudPictureTest, AScanSizedCloudMakesASmallPicture) {
  // 2,048 points on a sphere and a box's faces, as a scan would give.
  std::mt19937 rng(7);
  std::normal_distribution<float> normal;
  std::uniform_real_distribution<float> uniform(-1, 1);
  PointCloud cloud;
  for (int i = 0; i < 1024; ++i) {
    float x = normal(rng), y = normal(rng), z = normal(rng);
    const float r = std::sqrt(x * x + y * y + z * z);
    cloud.Add(x / r, y / r + 2.5f, z / r);
    cloud.Add(uniform(rng), uniform(rng) * 0.5f, i % 2 == 0 ? 1.0f : -1.0f);
  }
  const CloudPicture picture = RenderCloudViews(cloud);
  EXPECT_GT(PointPixels(picture), 3000);
  const std::string png = EncodePng(picture);
  EXPECT_LT(png.size(), 8000u) << "a picture should cost a few KB of page";
  EXPECT_EQ(Decode(png).rows.size(), 301u * 96u);
}

}  // namespace
}  // namespace shapeid
