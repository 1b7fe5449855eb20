// The pruned DFSD kernel against reading every point: the same bits at every SIMD level, on
// clouds chosen to strain the pruning (ties, a point on every cell center, flat, a single
// spot, far clusters), fed in chunks, and on ModelNet10 clouds when ../shared/data is there.
#include "core/descriptors/dfsd_kernels.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <random>
#include <string>
#include <vector>

#include "core/descriptors/dfsd_kernels_testing.h"
#include "core/io/point_cloud_reader.h"
#include "core/simd.h"
#include "gtest/gtest.h"

namespace shapeid::dfsd_internal {
namespace {

namespace fs = std::filesystem;

std::vector<float> Minima(const FieldInput& in, SimdLevel level) {
  std::vector<float> out(static_cast<size_t>(in.grid) * in.grid * in.grid);
  NearestSquaredDistances(in, out.data(), level);
  return out;
}

// Every level's pruned minima have the bits of reading every point (scalar).
void ExpectPrunedMatches(const Points& points, int g, const std::string& what) {
  GeometricInput input(g, PaddedStride(points.size()));
  input.Fill(points, /*first_chunk=*/true);
  const std::vector<float> want = Minima(input.Input(false, false), SimdLevel::kScalar);
  for (SimdLevel level : {SimdLevel::kScalar, SimdLevel::kAvx2, SimdLevel::kAvx512}) {
    if (level > DetectedSimdLevel()) continue;
    const std::vector<float> got = Minima(input.Input(true, false), level);
    ASSERT_EQ(0, std::memcmp(want.data(), got.data(), want.size() * sizeof(float)))
        << what << ", grid " << g << ", " << points.size() << " points, " << SimdLevelName(level);
  }
}

Points Shape(const std::string& name, size_t n, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  std::normal_distribution<float> normal(0.0f, 1.0f);
  Points points(n);
  for (size_t p = 0; p < n; ++p) {
    std::array<float, 3>& q = points[p];
    if (name == "cube") {
      q = {u(rng), u(rng), u(rng)};
    } else if (name == "sphere") {
      q = {normal(rng), normal(rng), normal(rng)};
      const float r = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2]) + 1e-12f;
      for (float& c : q) c /= r;
    } else if (name == "plane") {
      q = {u(rng), u(rng), 0.3f};
    } else if (name == "line") {
      const float t = u(rng);
      q = {t, -t, 0.5f * t};
    } else if (name == "spot") {
      q = {0.1f, -0.7f, 0.9f};
    } else if (name == "clusters") {
      const float side = p % 2 == 0 ? -0.95f : 0.95f;
      q = {side + 0.01f * u(rng), side + 0.01f * u(rng), -side + 0.01f * u(rng)};
    } else if (name == "corners") {
      q = {p % 2 == 0 ? -1.0f : 1.0f, (p / 2) % 2 == 0 ? -1.0f : 1.0f, (p / 4) % 2 ? -1.0f : 1.0f};
    }
  }
  return points;
}

TEST(DfsdKernelsTest, PrunedKernelGivesTheBitsOfReadingEveryPoint) {
  for (const std::string shape :
       {"cube", "sphere", "plane", "line", "spot", "clusters", "corners"}) {
    for (int g : {4, 5, 7, 12, 32}) {
      for (size_t n : {size_t{1}, size_t{3}, size_t{16}, size_t{37}, size_t{300}, size_t{2000}}) {
        ExpectPrunedMatches(Shape(shape, n, static_cast<uint32_t>(g * 1000 + n)), g, shape);
      }
    }
  }
}

TEST(DfsdKernelsTest, PrunedKernelWithAPointOnEveryCellCenterAndTies) {
  // Every center is a point (distance 0 there), and each point is repeated: exact ties.
  for (int g : {4, 7, 12}) {
    const std::vector<float> centers = Centers(g);
    Points points;
    for (float x : centers) {
      for (float y : centers) {
        for (float z : centers) {
          points.push_back({x, y, z});
          points.push_back({x, y, z});
        }
      }
    }
    ExpectPrunedMatches(points, g, "centers");
    // Points midway between centers: each cell has several nearest at equal distance.
    Points midway;
    for (size_t i = 0; i + 1 < centers.size(); ++i) {
      const float m = 0.5f * (centers[i] + centers[i + 1]);
      midway.push_back({m, m, m});
      midway.push_back({m, -m, m});
    }
    ExpectPrunedMatches(midway, g, "midway");
  }
}

TEST(DfsdKernelsTest, PrunedKernelFedInChunksGivesTheBitsOfOnePass) {
  // 48 points in one pass, and the same points as 32 then 16 with accumulate, as DFSD feeds a
  // cloud of several kernel chunks (the second keeps the first's tail in its padding).
  const int g = 9;
  const Points points = Shape("sphere", 48, 11);
  GeometricInput whole(g, 48);
  whole.Fill(points, true);
  const std::vector<float> want = Minima(whole.Input(false, false), SimdLevel::kScalar);
  for (SimdLevel level : {SimdLevel::kScalar, SimdLevel::kAvx2, SimdLevel::kAvx512}) {
    if (level > DetectedSimdLevel()) continue;
    GeometricInput chunked(g, 32);
    chunked.Fill(Points(points.begin(), points.begin() + 32), true);
    std::vector<float> got(static_cast<size_t>(g) * g * g);
    NearestSquaredDistances(chunked.Input(true, false), got.data(), level);
    chunked.Fill(Points(points.begin() + 32, points.end()), false);
    NearestSquaredDistances(chunked.Input(true, true), got.data(), level);
    EXPECT_EQ(0, std::memcmp(want.data(), got.data(), want.size() * sizeof(float)))
        << SimdLevelName(level);
  }
}

TEST(DfsdKernelsTest, SpatialOrderGroupsNearbyPoints) {
  // Points on a 16^3 lattice in scrambled order: after ordering, each block of kPointLanes
  // spans far less of the cube than a block of the scrambled order does.
  Points lattice;
  for (int x = 0; x < 16; ++x) {
    for (int y = 0; y < 16; ++y) {
      for (int z = 0; z < 16; ++z) {
        lattice.push_back({(x + 0.5f) / 8 - 1, (y + 0.5f) / 8 - 1, (z + 0.5f) / 8 - 1});
      }
    }
  }
  std::shuffle(lattice.begin(), lattice.end(), std::mt19937(4));
  const size_t n = lattice.size();
  std::vector<double> coords(3 * n);
  for (size_t p = 0; p < n; ++p) {
    for (int a = 0; a < 3; ++a) coords[a * n + p] = lattice[p][a];
  }
  const double* coord[3] = {coords.data(), coords.data() + n, coords.data() + 2 * n};
  const double half[3] = {1, 1, 1};
  std::vector<uint32_t> order;
  SpatialOrder(coord, n, half, &order);
  std::vector<uint32_t> sorted = order;
  std::sort(sorted.begin(), sorted.end());
  for (size_t p = 0; p < n; ++p) ASSERT_EQ(sorted[p], p) << "not a permutation";
  const auto mean_block_span = [&](const std::vector<uint32_t>& ids) {
    double total = 0;
    for (size_t b = 0; b < n; b += kPointLanes) {
      for (int a = 0; a < 3; ++a) {
        float lo = 2, hi = -2;
        for (size_t p = b; p < b + kPointLanes; ++p) {
          lo = std::min(lo, lattice[ids[p]][a]);
          hi = std::max(hi, lattice[ids[p]][a]);
        }
        total += hi - lo;
      }
    }
    return total / (3.0 * n / kPointLanes);
  };
  std::vector<uint32_t> identity(n);
  for (size_t p = 0; p < n; ++p) identity[p] = static_cast<uint32_t>(p);
  EXPECT_LT(mean_block_span(order), 0.3);     // within about one bucket
  EXPECT_GT(mean_block_span(identity), 1.5);  // most of the cube's width of 2
}

TEST(DfsdKernelsTest, PrunedKernelOnModelNet10Clouds) {
  const fs::path root = fs::path(SHAPEID_SOURCE_DIR) / ".." / "shared" / "data" / "modelnet10";
  if (!fs::is_directory(root)) GTEST_SKIP() << "ModelNet10 not found at " << root << "; skipping";
  std::vector<fs::path> classes;
  for (const auto& entry : fs::directory_iterator(root)) {
    if (entry.is_directory()) classes.push_back(entry.path());
  }
  std::sort(classes.begin(), classes.end());
  ASSERT_FALSE(classes.empty());
  int clouds = 0;
  for (const fs::path& cls : classes) {
    std::vector<fs::path> files;
    for (const auto& entry : fs::directory_iterator(cls / "test")) files.push_back(entry.path());
    std::sort(files.begin(), files.end());
    for (size_t f = 0; f < files.size() && f < 3; ++f) {
      absl::StatusOr<ReadResult> read = ReadPointCloud(files[f].string());
      ASSERT_TRUE(read.ok()) << read.status();
      const Points points = BoxNormalized(read->cloud);
      for (int g : {8, 12, 16}) ExpectPrunedMatches(points, g, files[f].string());
      ++clouds;
    }
  }
  EXPECT_EQ(clouds, 3 * static_cast<int>(classes.size()));
}

}  // namespace
}  // namespace shapeid::dfsd_internal
