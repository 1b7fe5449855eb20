#ifndef SHAPEID_CORE_VIEWS_TEST_SURFACES_H_
#define SHAPEID_CORE_VIEWS_TEST_SURFACES_H_

// Test-only surface samplings for the scan simulator's tests and benchmark: uniform,
// area-weighted and seeded, like the mesh readers' sampling.

#include <cstdint>
#include <random>

#include "Eigen/Core"
#include "core/point_cloud.h"

namespace shapeid::test_surfaces {

// n points uniform on the surface of the box center +- half (all six faces, by area).
inline PointCloud BoxSurface(const Eigen::Vector3f& center, const Eigen::Vector3f& half, size_t n,
                             uint32_t seed) {
  const float face_area[3] = {half.y() * half.z(), half.x() * half.z(), half.x() * half.y()};
  const float total = face_area[0] + face_area[1] + face_area[2];
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  PointCloud cloud;
  cloud.Reserve(n);
  for (size_t i = 0; i < n; ++i) {
    const float pick = 0.5f * (u(rng) + 1.0f) * total;  // which pair of faces, by area
    const int axis = pick < face_area[0] ? 0 : pick < face_area[0] + face_area[1] ? 1 : 2;
    Eigen::Vector3f p(u(rng), u(rng), u(rng));
    p[axis] = u(rng) < 0 ? -1.0f : 1.0f;
    cloud.Add(center + p.cwiseProduct(half));
  }
  return cloud;
}

// n points uniform on the sphere center + radius * S^2.
inline PointCloud SphereSurface(size_t n, uint32_t seed, float radius = 1.0f,
                                const Eigen::Vector3f& center = Eigen::Vector3f::Zero()) {
  std::mt19937 rng(seed);
  std::normal_distribution<float> g;
  PointCloud cloud;
  cloud.Reserve(n);
  while (cloud.size() < n) {
    const Eigen::Vector3f p(g(rng), g(rng), g(rng));
    if (p.norm() > 1e-3f) cloud.Add(center + radius * p.normalized());
  }
  return cloud;
}

// n points uniform on the square [-half, half]^2 in the plane z = 0 (an open surface).
inline PointCloud SquareSurface(float half, size_t n, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-half, half);
  PointCloud cloud;
  cloud.Reserve(n);
  for (size_t i = 0; i < n; ++i) cloud.Add(u(rng), u(rng), 0.0f);
  return cloud;
}

}  // namespace shapeid::test_surfaces

#endif  // SHAPEID_CORE_VIEWS_TEST_SURFACES_H_
