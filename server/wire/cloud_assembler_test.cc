#include "server/wire/cloud_assembler.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "gmock/gmock.h"
#include "gtest/gtest.h"

namespace shapeid {
namespace {

using ::testing::HasSubstr;

std::string Bytes(const std::vector<float>& xyz) {
  std::string bytes(xyz.size() * 4, '\0');
  std::memcpy(bytes.data(), xyz.data(), bytes.size());
  return bytes;
}

TEST(CloudAssemblerTest, JoinsChunksOfAnySizeIncludingEmpty) {
  CloudAssembler assembler(100);
  ASSERT_TRUE(assembler.Start(3).ok());
  ASSERT_TRUE(assembler.Append(Bytes({1, 2, 3})).ok());
  ASSERT_TRUE(assembler.Append("").ok());
  ASSERT_TRUE(assembler.Append(Bytes({4, 5, 6, 7, 8, 9})).ok());
  auto cloud = assembler.Finish();
  ASSERT_TRUE(cloud.ok()) << cloud.status();
  EXPECT_THAT(cloud->xyz(), ::testing::ElementsAre(1, 2, 3, 4, 5, 6, 7, 8, 9));
  EXPECT_FALSE(assembler.started());
}

TEST(CloudAssemblerTest, AnEmptyFirstChunkIsFine) {
  CloudAssembler assembler(10);
  ASSERT_TRUE(assembler.Start(0).ok());
  ASSERT_TRUE(assembler.Append("").ok());  // nothing stored yet: no copy into null storage
  ASSERT_TRUE(assembler.Append(Bytes({1, 2, 3})).ok());
  auto cloud = assembler.Finish();
  ASSERT_TRUE(cloud.ok());
  EXPECT_EQ(cloud->size(), 1u);
}

TEST(CloudAssemblerTest, ReusableForTheNextCloud) {
  CloudAssembler assembler(10);
  ASSERT_TRUE(assembler.Start(0).ok());
  ASSERT_TRUE(assembler.Append(Bytes({1, 1, 1})).ok());
  ASSERT_TRUE(assembler.Finish().ok());
  ASSERT_TRUE(assembler.Start(0).ok());
  ASSERT_TRUE(assembler.Append(Bytes({2, 2, 2, 3, 3, 3})).ok());
  auto cloud = assembler.Finish();
  ASSERT_TRUE(cloud.ok());
  EXPECT_EQ(cloud->size(), 2u);
}

TEST(CloudAssemblerTest, ErrorsSayWhatIsWrongWithNumbers) {
  CloudAssembler assembler(2);
  EXPECT_THAT(assembler.Append(Bytes({1, 2, 3})).message(), HasSubstr("before the header"));

  const absl::Status announced = assembler.Start(5);
  EXPECT_EQ(announced.code(), absl::StatusCode::kResourceExhausted);
  EXPECT_THAT(announced.message(), HasSubstr("announces 5 points, more than the limit of 2"));

  ASSERT_TRUE(assembler.Start(0).ok());
  const absl::Status partial = assembler.Append(std::string(13, '\0'));
  EXPECT_EQ(partial.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(partial.message(), HasSubstr("13 bytes is not a whole number of points"));

  ASSERT_TRUE(assembler.Append(Bytes({1, 2, 3, 4, 5, 6})).ok());
  const absl::Status over = assembler.Append(Bytes({7, 8, 9}));
  EXPECT_EQ(over.code(), absl::StatusCode::kResourceExhausted);
  EXPECT_THAT(over.message(), HasSubstr("more than the limit of 2 points (3 received so far; "
                                        "max_points_per_cloud)"));

  ASSERT_TRUE(assembler.Start(2).ok());
  ASSERT_TRUE(assembler.Append(Bytes({1, 2, 3})).ok());
  const auto short_cloud = assembler.Finish();
  EXPECT_EQ(short_cloud.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(short_cloud.status().message(), HasSubstr("announced 2 points but 1 arrived"));
}

// A sensor's bytes for `xyz` (packed float32 x y z): each point `layout.point_step` bytes with
// x, y, z at the layout's offsets and types, in its byte order, other bytes 0xAB (intensity,
// padding), rows padded to row_step.
std::string SensorBytes(const std::vector<float>& xyz, const PointLayout& layout) {
  std::string out;
  const size_t points = xyz.size() / 3;
  for (size_t i = 0; i < points; ++i) {
    std::string point(layout.point_step, '\xAB');
    for (int a = 0; a < 3; ++a) {
      char bytes[8];
      size_t size = 4;
      if (layout.xyz[a].type == PointLayout::Type::kFloat64) {
        const double v = xyz[3 * i + a];
        std::memcpy(bytes, &v, 8);
        size = 8;
      } else {
        std::memcpy(bytes, &xyz[3 * i + a], 4);
      }
      if (layout.big_endian) std::reverse(bytes, bytes + size);
      std::memcpy(point.data() + layout.xyz[a].offset, bytes, size);
    }
    out += point;
    if (layout.width != 0 && (i + 1) % layout.width == 0) {
      out.append(layout.row_step - layout.width * layout.point_step, '\xCD');
    }
  }
  return out;
}

// Assembles `bytes` in `format`, sent in chunks of `chunk` bytes.
absl::StatusOr<PointCloud> Assemble(const std::string& bytes, const WireCloudFormat& format,
                                    size_t chunk, size_t max_points = 1000) {
  CloudAssembler assembler(max_points);
  if (absl::Status s = assembler.Start(0, format); !s.ok()) return s;
  for (size_t at = 0; at < bytes.size(); at += chunk) {
    if (absl::Status s = assembler.Append(absl::string_view(bytes).substr(at, chunk)); !s.ok()) {
      return s;
    }
  }
  return assembler.Finish();
}

const std::vector<float> kSixPoints = {1.5f,  -2.25f, 3,  4, 5,    6.125f, -7,   8,     9e-3f,
                                       10.5f, 11,     12, 0, -0.f, 1e6f,   0.1f, 2e-7f, -3};

TEST(CloudAssemblerTest, SensorLayoutsDecodeToTheFloat32PointsTheyCarry) {
  using Type = PointLayout::Type;
  std::vector<std::pair<std::string, PointLayout>> layouts;
  PointLayout intensity;  // PointCloud2 of x y z intensity
  intensity.point_step = 16;
  layouts.push_back({"x y z intensity", intensity});
  PointLayout padded = intensity;  // PCL's PointXYZ: 16 bytes, as an organized 3 x 2 cloud
  padded.width = 3;
  padded.row_step = 3 * 16 + 5;
  layouts.push_back({"organized, padded rows", padded});
  PointLayout doubles;  // float64, big-endian, z first, gaps
  doubles.point_step = 40;
  doubles.xyz = {{{16, Type::kFloat64}, {28, Type::kFloat64}, {0, Type::kFloat64}}};
  doubles.big_endian = true;
  layouts.push_back({"float64 big-endian shuffled", doubles});
  PointLayout mixed;
  mixed.point_step = 21;
  mixed.xyz = {{{1, Type::kFloat64}, {9, Type::kFloat32}, {13, Type::kFloat64}}};
  layouts.push_back({"mixed types, odd step", mixed});
  for (const auto& [name, layout] : layouts) {
    const std::string bytes = SensorBytes(kSixPoints, layout);
    for (const size_t chunk : {size_t{1}, size_t{7}, size_t{16}, bytes.size()}) {
      const auto cloud = Assemble(bytes, {layout, {}}, chunk);
      ASSERT_TRUE(cloud.ok()) << name << ", chunks of " << chunk << ": " << cloud.status();
      EXPECT_EQ(cloud->xyz(), kSixPoints) << name << ", chunks of " << chunk;
    }
  }
}

TEST(CloudAssemblerTest, NonFinitePointsAreDroppedOnlyWhenAsked) {
  std::vector<float> xyz = kSixPoints;
  xyz[4] = NAN;                                      // point 1
  xyz[15] = std::numeric_limits<float>::infinity();  // point 5
  PointLayout layout;
  layout.point_step = 16;
  const std::string bytes = SensorBytes(xyz, layout);
  const auto kept = Assemble(bytes, {layout, {}}, 10);
  ASSERT_TRUE(kept.ok());
  EXPECT_EQ(kept->size(), 6u);  // refused later, by the descriptor's validation
  layout.drop_nonfinite = true;
  const auto dropped = Assemble(bytes, {layout, {}}, 10);
  ASSERT_TRUE(dropped.ok());
  EXPECT_THAT(dropped->xyz(),
              ::testing::ElementsAre(1.5f, -2.25f, 3, -7, 8, 9e-3f, 10.5f, 11, 12, 0, -0.f, 1e6f));
  // In the default packed layout too; the announced count is of the points sent.
  CloudAssembler assembler(100);
  PointLayout packed;
  packed.drop_nonfinite = true;
  ASSERT_TRUE(assembler.Start(6, {packed, {}}).ok());
  ASSERT_TRUE(assembler.Append(Bytes(xyz)).ok());
  const auto packed_cloud = assembler.Finish();
  ASSERT_TRUE(packed_cloud.ok()) << packed_cloud.status();
  EXPECT_EQ(packed_cloud->xyz(), dropped->xyz());
  EXPECT_EQ(assembler.points_received(), 6u);
}

TEST(CloudAssemblerTest, TheFrameMovesEveryPoint) {
  WireCloudFormat format;
  // A quarter turn about z, then up by 10.
  format.frame = *RigidTransformFromRows(std::vector<double>{0, -1, 0, 0, 1, 0, 0, 0, 0, 0, 1, 10});
  const auto cloud = Assemble(Bytes({1, 2, 3, 4, 5, 6}), format, 12);
  ASSERT_TRUE(cloud.ok());
  EXPECT_THAT(cloud->xyz(), ::testing::ElementsAre(-2, 1, 13, -5, 4, 16));
}

TEST(CloudAssemblerTest, LayoutsThatDoNotHoldTogetherAreRefused) {
  using Type = PointLayout::Type;
  const auto refused = [](PointLayout layout) { return CloudAssembler(10).Start(0, {layout, {}}); };
  PointLayout past_end;
  past_end.point_step = 16;
  past_end.xyz[2] = {12, Type::kFloat64};
  EXPECT_THAT(refused(past_end).message(),
              HasSubstr("z at offset 12 (8 bytes) ends past point_step 16"));
  PointLayout overlap;
  overlap.point_step = 16;
  overlap.xyz[1] = {2, Type::kFloat32};
  EXPECT_THAT(refused(overlap).message(), HasSubstr("x and y overlap (offsets 0 and 2)"));
  PointLayout short_row;
  short_row.width = 4;
  short_row.row_step = 40;
  EXPECT_THAT(refused(short_row).message(),
              HasSubstr("row_step 40 is less than width 4 x point_step 12"));
  PointLayout half_row;
  half_row.width = 4;
  EXPECT_THAT(refused(half_row).message(), HasSubstr("go together"));
  PointLayout zero;
  zero.point_step = 0;
  EXPECT_THAT(refused(zero).message(), HasSubstr("point_step 0 is outside [1, 65536]"));
  PointLayout huge;  // a cut point is buffered: its size is bounded
  huge.point_step = 4'000'000'000u;
  EXPECT_THAT(refused(huge).message(), HasSubstr("point_step 4000000000 is outside"));
}

TEST(CloudAssemblerTest, ADeclaredLayoutMustEndOnAPointAndCountsSentPointsAgainstTheLimit) {
  PointLayout layout;
  layout.point_step = 16;
  const std::string bytes = SensorBytes(kSixPoints, layout);
  const auto cut = Assemble(bytes.substr(0, 40), {layout, {}}, 40);
  EXPECT_EQ(cut.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(cut.status().message(), HasSubstr("ended inside a point: 8 of its 16 bytes"));
  layout.drop_nonfinite = true;
  std::vector<float> nan_points(3 * 6, NAN);
  const auto over = Assemble(SensorBytes(nan_points, layout), {layout, {}}, 1000, 5);
  EXPECT_EQ(over.status().code(), absl::StatusCode::kResourceExhausted);
  EXPECT_THAT(over.status().message(), HasSubstr("more than the limit of 5 points"));
}

TEST(CloudAssemblerTest, AnOrganisedCloudIsWholeRows) {
  PointLayout padded;  // 3 points a row, 5 bytes of padding
  padded.point_step = 16;
  padded.width = 3;
  padded.row_step = 3 * 16 + 5;
  const std::string bytes = SensorBytes(kSixPoints, padded);
  ASSERT_EQ(bytes.size(), 2u * 53);
  EXPECT_TRUE(Assemble(bytes, {padded, {}}, 7).ok());
  // The last row's padding missing; a row's points missing.
  const auto no_padding = Assemble(bytes.substr(0, 53 + 48), {padded, {}}, 7);
  EXPECT_EQ(no_padding.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(no_padding.status().message(),
            "the points ended inside a row: 48 of its 53 bytes (row_step) arrived; an organized "
            "cloud (width 3) is whole rows, padding included");
  EXPECT_THAT(Assemble(bytes.substr(0, 53 + 32), {padded, {}}, 7).status().message(),
              HasSubstr("ended inside a row: 32 of its 53 bytes"));
  PointLayout unpadded = padded;  // rows without padding
  unpadded.row_step = 3 * 16;
  const std::string rows = SensorBytes(kSixPoints, unpadded);
  EXPECT_TRUE(Assemble(rows, {unpadded, {}}, 16).ok());
  EXPECT_THAT(Assemble(rows.substr(0, 5 * 16), {unpadded, {}}, 16).status().message(),
              HasSubstr("ended inside a row: 32 of its 48 bytes"));
  // Announced points that are not whole rows: refused before any arrives.
  const absl::Status announced = CloudAssembler(100).Start(5, {padded, {}});
  EXPECT_EQ(announced.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(announced.message(),
            "the cloud announces 5 points, not whole rows of width 3 (an organized cloud is "
            "height x width points)");
}

TEST(CloudAssemblerTest, AFloat64CoordinateFloat32LosesIsRefused) {
  using Type = PointLayout::Type;
  PointLayout doubles;
  doubles.point_step = 24;
  doubles.xyz = {{{0, Type::kFloat64}, {8, Type::kFloat64}, {16, Type::kFloat64}}};
  const auto decoded = [&](const std::vector<double>& xyz, bool drop) {
    PointLayout layout = doubles;
    layout.drop_nonfinite = drop;
    std::string bytes(xyz.size() * 8, '\0');
    std::memcpy(bytes.data(), xyz.data(), bytes.size());
    return Assemble(bytes, {layout, {}}, 10);
  };
  const double max = std::numeric_limits<float>::max(), min = std::numeric_limits<float>::min();
  std::vector<double> xyz = {1, 2, 3, 4, 5, 6, -max, min, 0, 7, 8, 9, 10, 11, 12, 13, 14, 15};
  EXPECT_TRUE(decoded(xyz, false).ok());     // float32's extremes and 0 are float32 values
  xyz[6] = std::nextafter(-max, -INFINITY);  // beyond float32's largest, but rounds to it
  xyz[7] = std::nextafter(min, 0.0);         // below its smallest normal, but rounds to it
  EXPECT_TRUE(decoded(xyz, false).ok());
  xyz[7] = 1e-39;  // a float32 denormal: not kept whole
  EXPECT_THAT(decoded(xyz, false).status().message(),
              HasSubstr("point 2: y = 1e-39 (FLOAT64) is not 0 but below float32's smallest"));
  xyz[6] = -max;
  xyz[7] = min;
  xyz[10] = 1e39;                          // point 3's y: infinite in float32
  for (const bool drop : {false, true}) {  // not dropped as if it were infinite
    const auto huge = decoded(xyz, drop);
    EXPECT_EQ(huge.status().code(), absl::StatusCode::kInvalidArgument);
    EXPECT_EQ(huge.status().message(),
              "point 3: y = 1e+39 (FLOAT64) does not fit in a float32 (|value| <= 3.40282e+38); "
              "subtract an offset first (every descriptor is translation invariant)");
  }
  xyz[10] = 8;
  xyz[5] = -1e-300;  // point 1's z: 0 in float32
  EXPECT_EQ(decoded(xyz, false).status().message(),
            "point 1: z = -1e-300 (FLOAT64) is not 0 but below float32's smallest normal "
            "(1.17549e-38): float32 data declared FLOAT64 reads like this; is the datatype "
            "right?");
  // NaN and infinities are not lost: they are non-finite points, dropped when asked.
  xyz[5] = std::numeric_limits<double>::infinity();
  xyz[1] = NAN;
  const auto dropped = decoded(xyz, true);
  ASSERT_TRUE(dropped.ok()) << dropped.status();
  EXPECT_EQ(dropped->size(), 4u);
}

TEST(CloudAssemblerTest, MisDeclaredLayoutsAreRefusedDroppingOrNot) {
  // 48 points of a room in metres, big-endian bytes declared little-endian.
  std::vector<float> room;
  for (int i = 0; i < 48 * 3; ++i) room.push_back(0.37f * static_cast<float>(i % 17) - 2.9f);
  PointLayout big_endian;
  big_endian.point_step = 16;
  big_endian.big_endian = true;
  const std::string bytes = SensorBytes(room, big_endian);
  EXPECT_TRUE(Assemble(bytes, {big_endian, {}}, 100).ok());
  PointLayout declared = big_endian;
  declared.big_endian = false;
  for (const bool drop : {false, true}) {
    declared.drop_nonfinite = drop;
    const auto swapped = Assemble(bytes, {declared, {}}, 100);
    EXPECT_EQ(swapped.status().code(), absl::StatusCode::kInvalidArgument);
    EXPECT_THAT(swapped.status().message(),
                HasSubstr("point layout: the points look byte-swapped: "));
  }
  // The default layout's bytes are taken as they are: a cloud of float32 denormals or of
  // values near float32's largest is valid there, and so is the same layout declared.
  for (const float scale : {1e-40f, 1e38f}) {
    std::vector<float> scaled;
    for (float v : room) scaled.push_back(v * scale);
    PointLayout packed;
    EXPECT_TRUE(Assemble(Bytes(scaled), {packed, {}}, 120).ok()) << scale;
    packed.drop_nonfinite = true;
    EXPECT_TRUE(Assemble(Bytes(scaled), {packed, {}}, 120).ok()) << scale;
  }
}

}  // namespace
}  // namespace shapeid
