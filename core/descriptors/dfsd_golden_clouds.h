#ifndef SHAPEID_CORE_DESCRIPTORS_DFSD_GOLDEN_CLOUDS_H_
#define SHAPEID_CORE_DESCRIPTORS_DFSD_GOLDEN_CLOUDS_H_

// Test-only clouds for dfsd_golden_test: ordinary shapes and the degenerate ones where a
// frame is hard to choose (flat, straight, symmetric, duplicated, lattice-exact, signed
// zeros). Made with integer arithmetic and float operations only (no <random> distributions,
// whose output the standard leaves to the library), so every build makes the same points.

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "core/point_cloud.h"

namespace shapeid::dfsd_golden {

class Rng {
 public:
  explicit Rng(uint64_t seed) : state_(seed) {}
  uint64_t Next() {
    uint64_t z = (state_ += 0x9e3779b97f4a7c15ULL);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return z ^ (z >> 31);
  }
  // Uniform in [-1, 1), a multiple of 2^-23: exact in float.
  float Symmetric() {
    return static_cast<float>(static_cast<int64_t>(Next() >> 40) - (1 << 23)) * 0x1p-23f;
  }

 private:
  uint64_t state_;
};

// A fixed matrix close to a rotation, so shapes are not aligned with the input axes.
inline void Rotate(float* p) {
  static const float r[3][3] = {
      {0.7923f, -0.4479f, 0.4144f}, {0.5052f, 0.8617f, -0.0479f}, {-0.3357f, 0.2381f, 0.9114f}};
  const float x = p[0], y = p[1], z = p[2];
  for (int a = 0; a < 3; ++a) p[a] = r[a][0] * x + r[a][1] * y + r[a][2] * z;
}

// `shape` is one of Shapes(); n points (lattice shapes round n to their own count).
inline PointCloud MakeCloud(const std::string& shape, size_t n, uint64_t seed = 7) {
  Rng rng(seed * 1000003 + n);
  PointCloud cloud;
  cloud.Reserve(n);
  const auto add = [&cloud](float x, float y, float z, bool rotate) {
    float p[3] = {x, y, z};
    if (rotate) Rotate(p);
    cloud.Add(p[0], p[1], p[2]);
  };
  if (shape == "surface" || shape == "surface_rotated" || shape == "offset" || shape == "tiny") {
    // Half on a 2 x 1 x 0.6 box surface, half on an ellipsoid resting on it.
    const bool rotate = shape == "surface_rotated";
    const float scale = shape == "tiny" ? 1e-20f : 1.0f;
    const float shift = shape == "offset" ? 1e5f : 0.0f;
    for (size_t i = 0; i < n; ++i) {
      float p[3];
      if (i % 2 == 0) {
        const float extent[3] = {2.0f, 1.0f, 0.6f};
        for (int a = 0; a < 3; ++a) p[a] = extent[a] * rng.Symmetric();
        const int face = static_cast<int>(rng.Next() % 3);
        p[face] = rng.Next() % 2 ? extent[face] : -extent[face];
      } else {
        float x = rng.Symmetric(), y = rng.Symmetric(), z = rng.Symmetric();
        const float r = std::sqrt(x * x + y * y + z * z) + 1e-6f;
        p[0] = 1.2f * x / r;
        p[1] = 0.8f * y / r;
        p[2] = 0.6f + 0.9f * z / r;
      }
      add(p[0] * scale + shift, p[1] * scale + shift, p[2] * scale - shift, rotate);
    }
  } else if (shape == "uniform") {
    for (size_t i = 0; i < n; ++i)
      add(rng.Symmetric(), 2 * rng.Symmetric(), 0.5f * rng.Symmetric(), false);
  } else if (shape == "sphere") {
    while (cloud.size() < n) {
      const float x = rng.Symmetric(), y = rng.Symmetric(), z = rng.Symmetric();
      const float r = std::sqrt(x * x + y * y + z * z);
      if (r > 0.1f && r <= 1.0f) add(x / r, y / r, z / r, false);
    }
  } else if (shape == "flat" || shape == "flat_rotated") {
    for (size_t i = 0; i < n; ++i)
      add(2 * rng.Symmetric(), rng.Symmetric(), 0.0f, shape == "flat_rotated");
  } else if (shape == "flat_grid") {
    // A k x k integer grid at z = 0, with x and y extents equal.
    const size_t k = static_cast<size_t>(std::sqrt(static_cast<double>(n)));
    for (size_t i = 0; i < k; ++i) {
      for (size_t j = 0; j < k; ++j) add(static_cast<float>(i), static_cast<float>(j), 0.0f, false);
    }
  } else if (shape == "straight") {
    for (size_t i = 0; i < n; ++i) add(3 * rng.Symmetric(), 0.0f, 0.0f, false);
  } else if (shape == "straight_noisy") {
    for (size_t i = 0; i < n; ++i) {
      const float t = rng.Symmetric();
      add(t + 1e-4f * rng.Symmetric(), 2 * t + 1e-4f * rng.Symmetric(), 3 * t, false);
    }
  } else if (shape == "symmetric" || shape == "near_symmetric") {
    // Mirror images in all three axes: every skewness is 0 (or, perturbed, nearly 0).
    while (cloud.size() + 8 <= n) {
      const float x = rng.Symmetric(), y = 0.7f * rng.Symmetric(), z = 0.4f * rng.Symmetric();
      for (int s = 0; s < 8; ++s) {
        const float e = shape == "near_symmetric" ? 1e-3f * rng.Symmetric() : 0.0f;
        add((s & 1 ? -x : x) + e, s & 2 ? -y : y, s & 4 ? -z : z, false);
      }
    }
    while (cloud.size() < n) add(0.0f, 0.0f, 0.0f, false);
  } else if (shape == "duplicates") {
    // Every point three times, and a run of copies of one point.
    while (cloud.size() + 3 <= n) {
      const float x = rng.Symmetric(), y = 0.5f * rng.Symmetric(), z = 0.3f * rng.Symmetric();
      for (int c = 0; c < 3; ++c) add(x, y, z, false);
    }
    while (cloud.size() < n) add(0.25f, 0.25f, 0.25f, false);
  } else if (shape == "few_distinct") {
    // Four distinct points, repeated.
    const float corners[4][3] = {{0, 0, 0}, {1, 0, 0}, {0, 2, 0}, {0, 0, 3}};
    for (size_t i = 0; i < n; ++i)
      add(corners[i % 4][0], corners[i % 4][1], corners[i % 4][2], false);
  } else if (shape == "cube_lattice") {
    const size_t k = static_cast<size_t>(std::cbrt(static_cast<double>(n)));
    for (size_t i = 0; i < k; ++i) {
      for (size_t j = 0; j < k; ++j) {
        for (size_t l = 0; l < k; ++l)
          add(static_cast<float>(i), static_cast<float>(j), static_cast<float>(l), false);
      }
    }
  } else if (shape == "cylinder") {
    // The side of an upright cylinder: a circle seen from above.
    for (size_t i = 0; i < n; ++i) {
      const float x = rng.Symmetric(), y = rng.Symmetric();
      const float r = std::sqrt(x * x + y * y) + 1e-6f;
      add(x / r, y / r, 2 * rng.Symmetric(), false);
    }
  } else if (shape == "signed_zeros") {
    // A flat cloud at z = -0 and z = +0, symmetric in x and y, so centered coordinates and
    // projections meet zeros of both signs.
    while (cloud.size() + 4 <= n) {
      const float x = rng.Symmetric(), y = rng.Symmetric();
      add(x, y, -0.0f, false);
      add(-x, -y, 0.0f, false);
      add(-0.0f, y, -0.0f, false);
      add(0.0f, -y, 0.0f, false);
    }
    while (cloud.size() < n) add(0.0f, 0.0f, -0.0f, false);
  } else if (shape == "square_prism") {
    // Equal x and y extents (a square cross-section): the box frame's axis order is a guess.
    for (size_t i = 0; i < n; ++i)
      add(rng.Symmetric(), rng.Symmetric(), 0.3f * rng.Symmetric(), true);
  }
  return cloud;
}

inline std::vector<std::string> Shapes() {
  return {"surface",        "surface_rotated", "offset",         "tiny",
          "uniform",        "sphere",          "flat",           "flat_rotated",
          "flat_grid",      "straight",        "straight_noisy", "symmetric",
          "near_symmetric", "duplicates",      "few_distinct",   "cube_lattice",
          "cylinder",       "signed_zeros",    "square_prism"};
}

}  // namespace shapeid::dfsd_golden

#endif  // SHAPEID_CORE_DESCRIPTORS_DFSD_GOLDEN_CLOUDS_H_
