#include "core/descriptors/cnsd_downsample.h"

#include <algorithm>
#include <cstdint>
#include <random>
#include <set>
#include <tuple>
#include <vector>

#include "core/testing/test_clouds.h"
#include "gtest/gtest.h"

namespace shapeid {
namespace {

namespace ci = cnsd_internal;

using testing_clouds::SphereCloud;
using testing_clouds::UniformCloud;

TEST(CnsdDownsampleTest, VoxelDownsampleKeepsAtMostMaxPointsDeterministically) {
  const PointCloud cloud = SphereCloud(20000, 9);
  for (size_t max_points : {8, 100, 8000}) {
    const PointCloud a = ci::VoxelDownsample(cloud, max_points);
    EXPECT_LE(a.size(), max_points);
    EXPECT_GE(a.size(), max_points == 8 ? 2u : max_points * 3 / 4) << max_points;
    EXPECT_EQ(a.xyz(), ci::VoxelDownsample(cloud, max_points).xyz());
    // Centroids of points on the unit sphere lie inside it.
    for (size_t i = 0; i < a.size(); ++i) EXPECT_LE(a.point(i).norm(), 1.0f + 1e-6f);
  }
  EXPECT_EQ(ci::VoxelDownsample(cloud, 20000).xyz(), cloud.xyz());  // fits: unchanged
}

TEST(CnsdDownsampleTest, RandomDownsampleKeepsExactlyMaxPointsDeterministically) {
  const PointCloud cloud = UniformCloud(20000, 13);
  std::set<std::tuple<float, float, float>> original;
  for (size_t i = 0; i < cloud.size(); ++i) {
    original.emplace(cloud.point(i).x(), cloud.point(i).y(), cloud.point(i).z());
  }
  const PointCloud a = ci::RandomDownsample(cloud, 8000, 42);
  ASSERT_EQ(a.size(), 8000u);
  EXPECT_EQ(a.xyz(), ci::RandomDownsample(cloud, 8000, 42).xyz());
  EXPECT_NE(a.xyz(), ci::RandomDownsample(cloud, 8000, 43).xyz());
  std::set<std::tuple<float, float, float>> kept;
  for (size_t i = 0; i < a.size(); ++i) {
    const auto p = std::make_tuple(a.point(i).x(), a.point(i).y(), a.point(i).z());
    EXPECT_EQ(original.count(p), 1u);
    kept.insert(p);
  }
  EXPECT_EQ(kept.size(), 8000u);  // no point chosen twice
}

TEST(CnsdDownsampleTest, VoxelDownsampleGivesOneCentroidPerCluster) {
  // Nine pairs of points 0.01 apart, 1 apart from one another: the smallest cell size giving
  // at most nine cells is far below 0.99, so no cell spans two pairs, and nine cells means
  // one per pair. Each centroid is the pair's mean summed in double; cells in x order.
  PointCloud cloud;
  for (int k = 0; k < 9; ++k) {
    cloud.Add(float(k), 0, 0);
    cloud.Add(float(k) + 0.01f, 0, 0);
  }
  const PointCloud reduced = ci::VoxelDownsample(cloud, 9);
  ASSERT_EQ(reduced.size(), 9u);
  for (int k = 0; k < 9; ++k) {
    const float mean = static_cast<float>((double(k) + double(float(k) + 0.01f)) / 2);
    EXPECT_EQ(reduced.point(k), Eigen::Vector3f(mean, 0, 0)) << k;
  }
}

TEST(CnsdDownsampleTest, RandomDownsampleSubsetIsFixedBySeed) {
  // Pinned: a gallery described on one machine must match queries described on another, so
  // the subset of a seed may never change (splitmix64, not <random>).
  PointCloud cloud;
  for (int i = 0; i < 20; ++i) cloud.Add(float(i), 0, 0);
  const auto xs = [](const PointCloud& c) {
    std::vector<float> out;
    for (size_t i = 0; i < c.size(); ++i) out.push_back(c.point(i).x());
    return out;
  };
  EXPECT_EQ(xs(ci::RandomDownsample(cloud, 5, 0)), (std::vector<float>{2, 5, 9, 17, 19}));
  EXPECT_EQ(xs(ci::RandomDownsample(cloud, 5, 7)), (std::vector<float>{1, 7, 11, 12, 18}));
}

// The shuffle as it was written over an array of all n places (8 bytes a point): the stored
// places must pick the very same subset.
std::vector<size_t> DenseShuffle(size_t n, size_t max_points, uint64_t seed) {
  const auto split_mix = [](uint64_t& state) {
    uint64_t z = (state += 0x9e3779b97f4a7c15ULL);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return z ^ (z >> 31);
  };
  std::vector<size_t> order(n);
  for (size_t i = 0; i < n; ++i) order[i] = i;
  uint64_t state = seed;
  for (size_t k = 0; k < max_points; ++k) {
    __extension__ using Wide = unsigned __int128;
    const uint64_t bits = split_mix(state);
    const size_t j = k + static_cast<size_t>((static_cast<Wide>(bits) * (n - k)) >> 64);
    std::swap(order[k], order[j]);
  }
  std::sort(order.begin(), order.begin() + static_cast<std::ptrdiff_t>(max_points));
  order.resize(max_points);
  return order;
}

TEST(CnsdDownsampleTest, RandomDownsampleIsTheDenseShuffle) {
  for (size_t n : {9, 20, 1000, 100000}) {
    PointCloud cloud;
    for (size_t i = 0; i < n; ++i) cloud.Add(static_cast<float>(i), 0, 0);
    for (size_t max_points : {size_t{8}, n / 2, n - 1}) {
      for (uint64_t seed : {0, 1, 12345}) {
        const PointCloud got = ci::RandomDownsample(cloud, max_points, seed);
        const std::vector<size_t> want = DenseShuffle(n, max_points, seed);
        ASSERT_EQ(got.size(), want.size());
        for (size_t k = 0; k < want.size(); ++k) {
          ASSERT_EQ(got.point(k).x(), static_cast<float>(want[k])) << n << " " << max_points;
        }
      }
    }
  }
}

}  // namespace
}  // namespace shapeid
