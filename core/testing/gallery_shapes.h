#ifndef SHAPEID_CORE_TESTING_GALLERY_SHAPES_H_
#define SHAPEID_CORE_TESTING_GALLERY_SHAPES_H_

// Test-only: seeded clouds of three clearly different shapes, small enough to describe in
// microseconds.

#include <cstdint>
#include <limits>
#include <random>

#include "core/point_cloud.h"
#include "core/testing/test_clouds.h"

namespace shapeid::gallery_testing {

inline constexpr size_t kPoints = 256;

// Solid box [-1, 1] x [-2, 2] x [-0.5, 0.5].
inline PointCloud Box(uint32_t seed) { return testing_clouds::UniformCloud(kPoints, seed); }

// Unit sphere surface.
inline PointCloud Sphere(uint32_t seed) { return testing_clouds::SphereCloud(kPoints, seed); }

// A thin rod along x: length 2, radius ~0.02.
inline PointCloud Line(uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  PointCloud cloud;
  for (size_t i = 0; i < kPoints; ++i) cloud.Add(u(rng), 0.02f * u(rng), 0.02f * u(rng));
  return cloud;
}

// A box with one NaN coordinate at point `bad_point`.
inline PointCloud BoxWithNaN(uint32_t seed, size_t bad_point) {
  PointCloud cloud = Box(seed);
  cloud.data()[3 * bad_point + 1] = std::numeric_limits<float>::quiet_NaN();
  return cloud;
}

}  // namespace shapeid::gallery_testing

#endif  // SHAPEID_CORE_TESTING_GALLERY_SHAPES_H_
