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

}  // namespace shapeid::testing_clouds

#endif  // SHAPEID_CORE_TESTING_TEST_CLOUDS_H_
