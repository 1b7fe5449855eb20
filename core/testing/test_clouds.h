#ifndef SHAPEID_CORE_TESTING_TEST_CLOUDS_H_
#define SHAPEID_CORE_TESTING_TEST_CLOUDS_H_

// Test-only clouds, seeded, so every run sees the same points.

#include <cstdint>
#include <random>

#include "core/point_cloud.h"

namespace shapeid::testing_clouds {

// n points uniform in the box [-1, 1] x [-2, 2] x [-0.5, 0.5] (three different extents).
inline PointCloud UniformCloud(size_t n, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  PointCloud cloud;
  for (size_t i = 0; i < n; ++i) cloud.Add(u(rng), 2 * u(rng), 0.5f * u(rng));
  return cloud;
}

// n points on the unit sphere (normalised Gaussian samples).
inline PointCloud SphereCloud(size_t n, uint32_t seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<float> g;
  PointCloud cloud;
  while (cloud.size() < n) {
    const Eigen::Vector3f p(g(rng), g(rng), g(rng));
    if (p.norm() > 1e-3f) cloud.Add(p.normalized());
  }
  return cloud;
}

// Three shapes any descriptor tells apart, for tests that train and classify: kind 0 a flat
// 4 x 3 x 0.2 box, 1 a sphere shell (1 % radial noise), 2 a thin rod 6 long. `kShapeNames`
// gives their labels.
inline constexpr const char* kShapeNames[] = {"box", "sphere", "rod"};
inline PointCloud ShapeCloud(int kind, uint32_t seed, size_t n) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  std::normal_distribution<float> g;
  PointCloud cloud;
  cloud.Reserve(n);
  for (size_t i = 0; i < n; ++i) {
    if (kind == 0) {
      cloud.Add(2 * u(rng), 1.5f * u(rng), 0.1f * u(rng));
    } else if (kind == 1) {
      const Eigen::Vector3f p(g(rng), g(rng), g(rng));
      cloud.Add(p.normalized() * (1.0f + 0.01f * u(rng)));
    } else {
      cloud.Add(3 * u(rng), 0.05f * u(rng), 0.05f * u(rng));
    }
  }
  return cloud;
}

}  // namespace shapeid::testing_clouds

#endif  // SHAPEID_CORE_TESTING_TEST_CLOUDS_H_
