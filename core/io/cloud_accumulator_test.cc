#include "core/io/cloud_accumulator.h"

#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <string>
#include <vector>

#include "gtest/gtest.h"

namespace shapeid {
namespace {

constexpr float kInf = std::numeric_limits<float>::infinity();
constexpr float kNan = std::numeric_limits<float>::quiet_NaN();

std::vector<uint32_t> Bits(const PointCloud& cloud) {
  std::vector<uint32_t> bits(cloud.xyz().size());
  if (!bits.empty()) std::memcpy(bits.data(), cloud.data(), 4 * bits.size());
  return bits;
}

// Points that exercise the edges: signed zeros, the float range's ends, non-finite values in
// each axis (first and later), and ordinary values.
std::vector<float> EdgePoints() {
  const float big = std::numeric_limits<float>::max();
  return {kNan, 1,    2,                        //
          0.f,  -0.f, 5,                        //
          -0.f, 0.f,  -5,                       //
          big,  -big, 1e-30f, 3.25f, kInf,  0,  //
          -big, big,  7,                        //
          1.5f, 2.5f, -kInf,  1e6f,  3e-7f, -2};
}

// The float32 column path must give what the double accumulator gives, bit for bit: the
// readers switch between them by the file's types.
void ExpectSameAsAccumulator(const std::vector<float>& xyz, const ReadOptions& options) {
  const size_t n = xyz.size() / 3;
  CloudAccumulator accumulator("f", "byte offset");
  for (size_t i = 0; i < n; ++i)
    accumulator.Add(xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2], 100 + 16 * i);
  const absl::StatusOr<ReadResult> expected = std::move(accumulator).Finish(options);
  ASSERT_TRUE(expected.ok()) << expected.status();

  // The same points in 16-byte records (x y z and a pad), once in host order, once swapped.
  for (const bool swapped : {false, true}) {
    std::string records;
    for (size_t i = 0; i < n; ++i) {
      for (int a = 0; a < 4; ++a) {
        uint32_t bits = 0xdeadbeef;
        if (a < 3) std::memcpy(&bits, &xyz[3 * i + a], 4);
        if (swapped) bits = __builtin_bswap32(bits);
        records.append(reinterpret_cast<const char*>(&bits), 4);
      }
    }
    FloatColumns columns;
    for (int a = 0; a < 3; ++a) {
      columns.axis[a] = records.data() + 4 * a;
      columns.stride[a] = 16;
    }
    columns.byte_swapped = swapped;
    columns.where = 100;
    columns.where_step = 16;
    const ReadResult got = ReadFloatColumns(columns, n, "byte offset", options);
    EXPECT_EQ(Bits(got.cloud), Bits(expected->cloud)) << "swapped " << swapped;
    for (int a = 0; a < 3; ++a) {
      EXPECT_EQ(std::memcmp(&got.offset[a], &expected->offset[a], sizeof(double)), 0);
    }
    EXPECT_EQ(got.dropped_non_finite, expected->dropped_non_finite);
    EXPECT_EQ(got.non_finite_points, expected->non_finite_points);
    EXPECT_EQ(got.first_non_finite, expected->first_non_finite);
    EXPECT_EQ(got.first_non_finite_location, expected->first_non_finite_location);
  }
}

TEST(FloatColumnsTest, MatchTheAccumulatorBitForBitUnderEveryOption) {
  for (const bool recenter : {false, true}) {
    for (const bool drop : {false, true}) {
      SCOPED_TRACE(testing::Message() << "recenter " << recenter << " drop " << drop);
      ReadOptions options;
      options.recenter = recenter;
      options.drop_non_finite = drop;
      ExpectSameAsAccumulator(EdgePoints(), options);
      ExpectSameAsAccumulator({}, options);
      ExpectSameAsAccumulator({kNan, kNan, kNan, 1, kInf, 2}, options);  // nothing finite
      ExpectSameAsAccumulator({-0.f, 0.f, -0.f, 0.f, -0.f, 0.f}, options);
      std::vector<float> many;
      uint32_t state = 1;
      for (int i = 0; i < 3000; ++i) {
        state = state * 1664525u + 1013904223u;
        many.push_back(static_cast<float>(state >> 8) * 1e-3f - 5000.f);
      }
      many[3 * 700 + 2] = kNan;
      ExpectSameAsAccumulator(many, options);
    }
  }
}

TEST(CloudAccumulatorTest, CountsNonFinitePointsAndLocatesTheFirst) {
  CloudAccumulator accumulator("f.xyz", "line");
  accumulator.Add(1, 2, 3, 1);
  accumulator.Add(1, kInf, 3, 4);
  accumulator.Add(4, 5, 6, 5);
  accumulator.Add(kNan, 0, 0, 9);
  ReadOptions options;
  options.drop_non_finite = true;
  const absl::StatusOr<ReadResult> read = std::move(accumulator).Finish(options);
  ASSERT_TRUE(read.ok()) << read.status();
  EXPECT_EQ(read->cloud.size(), 2u);
  EXPECT_EQ(read->dropped_non_finite, 2u);
  EXPECT_EQ(read->non_finite_points, 2u);
  EXPECT_EQ(read->first_non_finite, 1u);
  EXPECT_EQ(read->first_non_finite_location, "line 4");
}

TEST(CloudAccumulatorTest, AFiniteCloudHasNoNonFiniteLocation) {
  CloudAccumulator accumulator("f.xyz", "line");
  accumulator.Add(1, 2, 3, 1);
  const absl::StatusOr<ReadResult> read = std::move(accumulator).Finish(ReadOptions());
  ASSERT_TRUE(read.ok());
  EXPECT_EQ(read->non_finite_points, 0u);
  EXPECT_EQ(read->first_non_finite_location, "");
}

TEST(NewCloudBufferTest, HoldsTheFloatsAskedFor) {
  for (const size_t floats : {size_t{0}, size_t{3}, size_t{3} << 20}) {
    std::vector<float> buffer = NewCloudBuffer(floats);
    ASSERT_EQ(buffer.size(), floats);
    if (floats > 0) buffer.back() = 1;  // writable to its end
  }
}

}  // namespace
}  // namespace shapeid
