#include "server/wire/point_layout.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "gmock/gmock.h"
#include "gtest/gtest.h"

namespace shapeid {
namespace {

using ::testing::HasSubstr;
using Type = PointLayout::Type;

TEST(PointLayoutTest, RowsPadByLessThanOnePoint) {
  PointLayout layout;
  layout.point_step = 16;
  layout.width = 48;
  layout.row_step = 48 * 16 + 15;
  EXPECT_TRUE(ValidatePointLayout(layout).ok());
  // 32-byte points declared 16 bytes, row_step the data's length: half of each row's bytes
  // would be read as points and the other half skipped.
  layout.row_step = 48 * 32;
  const absl::Status status = ValidatePointLayout(layout);
  EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(status.message(),
            "point layout: row_step 1536 leaves 768 bytes after width 48 x point_step 16, room "
            "for 48 more points; rows pad by less than one point (is point_step right?)");
  // 16-byte points (x y z intensity) declared 12 bytes.
  layout.point_step = 12;
  layout.row_step = 48 * 16;
  EXPECT_THAT(ValidatePointLayout(layout).message(),
              HasSubstr("row_step 768 leaves 192 bytes after width 48 x point_step 12, room for "
                        "16 more points"));
}

// `points` as a sensor's bytes: x y z of `type` at `offsets`, `point_step` bytes a point, in
// the given byte order, the other bytes `fill`.
std::string Records(const std::vector<std::array<double, 3>>& points, uint32_t point_step,
                    const std::array<uint32_t, 3>& offsets, Type type, bool big_endian,
                    char fill = '\xAB') {
  std::string out(points.size() * point_step, fill);
  for (size_t i = 0; i < points.size(); ++i) {
    for (int a = 0; a < 3; ++a) {
      char bytes[8];
      size_t size = 4;
      if (type == Type::kFloat64) {
        std::memcpy(bytes, &points[i][a], 8);
        size = 8;
      } else {
        const float v = static_cast<float>(points[i][a]);
        std::memcpy(bytes, &v, 4);
      }
      if (big_endian) std::reverse(bytes, bytes + size);  // this host is little-endian
      std::memcpy(out.data() + i * point_step + offsets[a], bytes, size);
    }
  }
  return out;
}

PointLayout Declared(uint32_t point_step, const std::array<uint32_t, 3>& offsets, Type type,
                     bool big_endian) {
  PointLayout layout;
  layout.point_step = point_step;
  for (int a = 0; a < 3; ++a) layout.xyz[a] = {offsets[a], type};
  layout.big_endian = big_endian;
  return layout;
}

absl::Status Survey(const std::string& bytes, const PointLayout& layout) {
  LayoutSurvey survey;
  survey.Reset(layout);
  survey.Add(bytes.data(), bytes.size() / layout.point_step);
  return survey.Verdict();
}

// A room scanned in metres: what sensors send.
std::vector<std::array<double, 3>> Scan(size_t n, uint32_t seed = 1) {
  std::mt19937 random(seed);
  std::uniform_real_distribution<double> coordinate(-8, 8);
  std::vector<std::array<double, 3>> points(n);
  for (auto& p : points) p = {coordinate(random), coordinate(random), coordinate(random) / 4};
  return points;
}

const std::array<uint32_t, 3> kFloat32Offsets = {0, 4, 8};   // x y z intensity, 16 bytes
const std::array<uint32_t, 3> kFloat64Offsets = {0, 8, 16};  // x y z intensity, 32 bytes

TEST(LayoutSurveyTest, WhatSensorsSendPasses) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  std::vector<std::array<double, 3>> with_missing = Scan(500);
  for (size_t i = 0; i < with_missing.size(); i += 5) {
    for (int j = 0; j < 4 && i + j < with_missing.size(); ++j)
      with_missing[i + j] = {nan, nan, nan};
  }
  std::vector<std::array<double, 3>> integers(500), zeros(500, {0, 0, 0});
  for (size_t i = 0; i < integers.size(); ++i) integers[i] = {double(i % 7), double(i % 13), 2};
  zeros[3] = {1.5, 2, 3};
  // Degenerate but valid: a cloud a thousand times smaller than a picometre or near float32's
  // largest value reads implausibly as declared, but no better exchanged.
  std::vector<std::array<double, 3>> tiny = Scan(500), huge = Scan(500);
  for (auto& p : tiny) p = {p[0] * 1e-30, p[1] * 1e-30, p[2] * 1e-30};
  for (auto& p : huge) p = {p[0] * 4e37, p[1] * 4e37, p[2] * 4e37};
  for (const bool big_endian : {false, true}) {
    for (const auto& [name, points] :
         std::vector<std::pair<std::string, std::vector<std::array<double, 3>>>>{
             {"scan", Scan(2000)},
             {"4 in 5 points missing", with_missing},
             {"integers", integers},
             {"zeros", zeros},
             {"tiny", tiny},
             {"huge", huge}}) {
      for (const Type type : {Type::kFloat32, Type::kFloat64}) {
        const bool f64 = type == Type::kFloat64;
        const auto offsets = f64 ? kFloat64Offsets : kFloat32Offsets;
        const uint32_t step = f64 ? 32 : 16;
        EXPECT_TRUE(Survey(Records(points, step, offsets, type, big_endian),
                           Declared(step, offsets, type, big_endian))
                        .ok())
            << name << (f64 ? " float64" : " float32") << (big_endian ? " big" : " little");
      }
    }
  }
}

TEST(LayoutSurveyTest, AWrongByteOrderIsNamed) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  std::vector<std::array<double, 3>> with_missing = Scan(48);
  for (size_t i = 0; i < with_missing.size(); i += 3) with_missing[i] = {nan, nan, nan};
  std::vector<std::array<double, 3>> integers(48);
  for (size_t i = 0; i < integers.size(); ++i) integers[i] = {double(i % 7 + 1), 3, -2};
  for (const auto& [name, points] :
       std::vector<std::pair<std::string, std::vector<std::array<double, 3>>>>{
           {"scan", Scan(48)}, {"a third missing", with_missing}, {"integers", integers}}) {
    for (const bool big_endian : {false, true}) {
      const absl::Status f32 =
          Survey(Records(points, 16, kFloat32Offsets, Type::kFloat32, !big_endian),
                 Declared(16, kFloat32Offsets, Type::kFloat32, big_endian));
      EXPECT_EQ(f32.code(), absl::StatusCode::kInvalidArgument) << name;
      EXPECT_THAT(f32.message(), HasSubstr("point layout: the points look byte-swapped: ")) << name;
      EXPECT_THAT(f32.message(), HasSubstr(big_endian ? "(is_bigendian true), 0 read little-endian"
                                                      : "(is_bigendian false), 0 read big-endian"))
          << name;
      const absl::Status f64 =
          Survey(Records(points, 32, kFloat64Offsets, Type::kFloat64, !big_endian),
                 Declared(32, kFloat64Offsets, Type::kFloat64, big_endian));
      EXPECT_THAT(f64.message(), HasSubstr("look byte-swapped")) << name;
    }
  }
  // The counts, for the message's sake: 16 points, all read as denormals or worse.
  std::vector<std::array<double, 3>> round(16, {1, 2, 0.5});
  EXPECT_EQ(Survey(Records(round, 12, kFloat32Offsets, Type::kFloat32, true),
                   Declared(12, kFloat32Offsets, Type::kFloat32, false))
                .message(),
            "point layout: the points look byte-swapped: 48 of 48 coordinates are implausible "
            "(not 0 and outside [2^-40, 2^40]) as declared (is_bigendian false), 0 read "
            "big-endian; is is_bigendian right?");
}

TEST(LayoutSurveyTest, TheOtherFloatWidthIsNamed) {
  for (const char fill : {'\0', '\xAB'}) {
    // float32 x y z at the offsets of float64 ones, the bytes between them padding.
    const absl::Status narrow =
        Survey(Records(Scan(48), 32, kFloat64Offsets, Type::kFloat32, false, fill),
               Declared(32, kFloat64Offsets, Type::kFloat64, false));
    EXPECT_EQ(narrow.code(), absl::StatusCode::kInvalidArgument);
    EXPECT_THAT(narrow.message(),
                HasSubstr("point layout: the points look like FLOAT32 data declared FLOAT64: 144 "
                          "of 144 coordinates are implausible"));
    EXPECT_THAT(narrow.message(), HasSubstr("is the datatype of x, y and z right?"));
  }
  // float64 data declared float32 at the same offsets: their low halves read.
  const absl::Status wide = Survey(Records(Scan(48), 32, kFloat64Offsets, Type::kFloat64, false),
                                   Declared(32, kFloat64Offsets, Type::kFloat32, false));
  EXPECT_THAT(wide.message(),
              HasSubstr("point layout: the points look like FLOAT64 data declared FLOAT32: "));
  // float64 values that were float32 ones: their low halves are nearly all 0.
  std::vector<std::array<double, 3>> widened = Scan(48);
  for (auto& p : widened) {
    for (double& v : p) v = static_cast<float>(v);
  }
  EXPECT_THAT(Survey(Records(widened, 32, kFloat64Offsets, Type::kFloat64, false),
                     Declared(32, kFloat64Offsets, Type::kFloat32, false))
                  .message(),
              HasSubstr("FLOAT64 data declared FLOAT32"));
}

TEST(LayoutSurveyTest, StopsAfterItsSample) {
  // About the first 1,024 points are surveyed (as many as give 3,072 coordinates finite in
  // both readings); what comes after does not change the verdict.
  const PointLayout layout = Declared(16, kFloat32Offsets, Type::kFloat32, false);
  std::string bytes = Records(Scan(1024), 16, kFloat32Offsets, Type::kFloat32, false) +
                      Records(Scan(1024), 16, kFloat32Offsets, Type::kFloat32, true);
  LayoutSurvey survey;
  survey.Reset(layout);
  survey.Add(bytes.data(), 1000);
  EXPECT_FALSE(survey.full());
  survey.Add(bytes.data() + 1000 * 16, 1048);
  EXPECT_TRUE(survey.full());
  EXPECT_TRUE(survey.Verdict().ok());
}

}  // namespace
}  // namespace shapeid
