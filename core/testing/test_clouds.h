#ifndef SHAPEID_CORE_TESTING_TEST_CLOUDS_H_
#define SHAPEID_CORE_TESTING_TEST_CLOUDS_H_

// Test-only clouds, seeded, so every run sees the same points.

#include <cstdint>
#include <random>
#include <vector>

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

// n points on the unit sphere (normalized Gaussian samples).
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

// A sensor-frame-like scene for scene-recognition tests: a 1.2 m square table top at z =
// kTableHeight (1 cm grid, 121 x 121 points, first) with a box, a sphere and a rod (ShapeCloud
// kinds 0-2, seeds 50-52, 3,000 points each, 5 cm per unit) standing 3 cm clear of it, each
// far from the others. `truth`, when given, gets each shape's indices, box first.
inline constexpr float kTableHeight = -0.5f;
inline PointCloud TableWithShapes(std::vector<std::vector<uint32_t>>* truth = nullptr) {
  PointCloud frame;
  for (int x = -60; x <= 60; ++x) {
    for (int y = -60; y <= 60; ++y) frame.Add(0.01f * x, 0.01f * y, kTableHeight);
  }
  const float places[3][3] = {{0.1f, 0.3f, kTableHeight + 0.04f},
                              {-0.3f, -0.1f, kTableHeight + 0.08f},
                              {0.2f, -0.3f, kTableHeight + 0.04f}};
  for (int kind = 0; kind < 3; ++kind) {
    const PointCloud shape = ShapeCloud(kind, static_cast<uint32_t>(50 + kind), 3000);
    if (truth != nullptr) truth->emplace_back();
    for (size_t i = 0; i < shape.size(); ++i) {
      if (truth != nullptr) truth->back().push_back(static_cast<uint32_t>(frame.size()));
      const auto p = shape.point(i);
      frame.Add(0.05f * p.x() + places[kind][0], 0.05f * p.y() + places[kind][1],
                0.05f * p.z() + places[kind][2]);
    }
  }
  return frame;
}

}  // namespace shapeid::testing_clouds

#endif  // SHAPEID_CORE_TESTING_TEST_CLOUDS_H_
