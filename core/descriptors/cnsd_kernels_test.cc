#include "core/descriptors/cnsd_kernels.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include "gtest/gtest.h"

namespace shapeid {
namespace {

namespace ci = cnsd_internal;

std::vector<SimdLevel> AvailableLevels() {
  std::vector<SimdLevel> levels = {SimdLevel::kScalar};
  if (DetectedSimdLevel() >= SimdLevel::kAvx2) levels.push_back(SimdLevel::kAvx2);
  if (DetectedSimdLevel() >= SimdLevel::kAvx512) levels.push_back(SimdLevel::kAvx512);
  return levels;
}

// Every pair, the same float expression.
float BruteForceMax(const std::vector<float>& xyz) {
  float best = 0;
  for (size_t i = 0; i < xyz.size() / 3; ++i) {
    for (size_t j = i + 1; j < xyz.size() / 3; ++j) {
      const float dx = xyz[3 * j] - xyz[3 * i];
      const float dy = xyz[3 * j + 1] - xyz[3 * i + 1];
      const float dz = xyz[3 * j + 2] - xyz[3 * i + 2];
      best = std::max(best, (dx * dx + dy * dy) + dz * dz);
    }
  }
  return best;
}

TEST(CnsdKernelsTest, MaxSquaredDistanceMatchesEveryPair) {
  // The kernel measures only the rows of points far enough from the origin to be an end of
  // the farthest pair: clouds where that is every point (a sphere), few points (an elongated
  // cloud), and where the point farthest from the origin is not an end of the farthest pair.
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  std::normal_distribution<float> g;
  std::vector<std::vector<float>> clouds;
  for (size_t n : {2, 3, 17, 100, 1000}) {
    std::vector<float> box, sphere, needle;
    for (size_t i = 0; i < n; ++i) {
      box.insert(box.end(), {u(rng), 0.5f * u(rng), 0.25f * u(rng)});
      const float x = g(rng), y = g(rng), z = g(rng), r = std::sqrt(x * x + y * y + z * z);
      sphere.insert(sphere.end(), {x / r, y / r, z / r});
      needle.insert(needle.end(), {u(rng), 0.01f * u(rng), 0.01f * u(rng)});
    }
    clouds.insert(clouds.end(), {box, sphere, needle});
  }
  // The diameter is x = +-0.8 (1.6); the point farthest from the origin, (0, 0, 0.9), is at
  // most 1.21 from anything.
  clouds.push_back({-0.8f, 0, 0, 0.8f, 0, 0, 0, 0, 0.9f, 0.1f, 0.1f, 0, -0.3f, 0.2f, 0.1f});
  // Ties: many pairs at exactly the largest distance.
  std::vector<float> lattice;
  for (int i = 0; i < 5; ++i) {
    for (int j = 0; j < 5; ++j) {
      for (int k = 0; k < 3; ++k) lattice.insert(lattice.end(), {i * 0.25f, j * 0.25f, k * 0.5f});
    }
  }
  clouds.push_back(lattice);
  clouds.push_back({0.5f, 0.5f, 0.5f, 0.5f, 0.5f, 0.5f, 0.5f, 0.5f, 0.5f});  // coincident

  for (const std::vector<float>& xyz : clouds) {
    const float expected = BruteForceMax(xyz);
    for (SimdLevel level : AvailableLevels()) {
      EXPECT_EQ(ci::MaxSquaredDistance(xyz, level), expected)
          << "n=" << xyz.size() / 3 << " " << SimdLevelName(level);
    }
  }
  EXPECT_EQ(ci::MaxSquaredDistance({1, 2, 3}, SimdLevel::kScalar), 0.0f);  // one point
}

}  // namespace
}  // namespace shapeid
