#ifndef SHAPEID_BENCH_BENCH_CLOUDS_H_
#define SHAPEID_BENCH_BENCH_CLOUDS_H_

// Deterministic synthetic clouds for benchmarks: points on the surface of a box joined to an
// ellipsoid (a shape with some structure), in random order as surface samplers emit them.

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <random>
#include <system_error>
#include <vector>

#include "core/io/point_cloud_reader.h"
#include "core/point_cloud.h"

namespace shapeid::bench {

inline PointCloud SurfaceCloud(size_t n, uint32_t seed = 42) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  PointCloud cloud;
  cloud.Reserve(n);
  for (size_t i = 0; i < n; ++i) {
    if (i % 2 == 0) {  // a 2 x 1 x 0.6 box surface, one random face coordinate pinned
      float p[3] = {2.0f * u(rng), u(rng), 0.6f * u(rng)};
      const int face = static_cast<int>((u(rng) + 1.0f) * 1.5f) % 3;
      const float extent[3] = {2.0f, 1.0f, 0.6f};
      p[face] = u(rng) < 0 ? -extent[face] : extent[face];
      cloud.Add(p[0], p[1], p[2]);
    } else {  // an ellipsoid resting on top
      float x = u(rng), y = u(rng), z = u(rng);
      const float r = std::sqrt(x * x + y * y + z * z) + 1e-6f;
      cloud.Add(1.2f * x / r, 0.8f * y / r, 0.6f + 0.9f * z / r);
    }
  }
  return cloud;
}

// The first `per_class` test files of each ModelNet10 class under `root`
// (<class>/test/*.pcd, classes and files in sorted order), as the benchmarks that compare
// per-cloud times read them. Empty where the data is absent; unreadable files are skipped.
inline std::vector<PointCloud> ModelNet10TestClouds(const std::filesystem::path& root,
                                                    size_t per_class) {
  namespace fs = std::filesystem;
  std::vector<PointCloud> clouds;
  std::error_code error;
  std::vector<fs::path> classes;
  for (const auto& entry : fs::directory_iterator(root, error)) classes.push_back(entry.path());
  std::sort(classes.begin(), classes.end());
  for (const fs::path& cls : classes) {
    std::vector<fs::path> files;
    for (const auto& entry : fs::directory_iterator(cls / "test", error))
      files.push_back(entry.path());
    std::sort(files.begin(), files.end());
    for (size_t i = 0; i < files.size() && i < per_class; ++i) {
      auto read = ReadPointCloud(files[i].string());
      if (read.ok()) clouds.push_back(std::move(read->cloud));
    }
  }
  return clouds;
}

}  // namespace shapeid::bench

#endif  // SHAPEID_BENCH_BENCH_CLOUDS_H_
