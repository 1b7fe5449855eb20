#include "core/descriptors/comsd.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/strings/str_cat.h"
#include "core/descriptor.h"
#include "core/descriptor_registry.h"
#include "core/point_cloud.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"

namespace shapeid {
namespace {

using comsd_internal::AllCounts;
using comsd_internal::kDimension;
using comsd_internal::kDirections;
using comsd_internal::kNumDirections;
using comsd_internal::kNumFeatures;
using comsd_internal::PopcountPath;
using ::testing::HasSubstr;

std::unique_ptr<Descriptor> MakeComsd(int grid) {
  auto descriptor = CreateDescriptor(absl::StrCat("comsd:grid=", grid));
  EXPECT_TRUE(descriptor.ok()) << descriptor.status();
  return std::move(descriptor).value();
}

std::vector<float> Describe(const Descriptor& descriptor, const PointCloud& cloud) {
  auto out = descriptor.Compute(cloud);
  EXPECT_TRUE(out.ok()) << out.status();
  return out.ok() ? *out : std::vector<float>();
}

// Points spread over a sphere surface plus a uniform box cloud, so grids of every size get
// both long runs of empty voxels and dense clusters.
PointCloud RandomCloud(size_t n, uint32_t seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<float> normal(0.0f, 1.0f);
  std::uniform_real_distribution<float> uniform(-0.7f, 1.3f);
  PointCloud cloud;
  for (size_t p = 0; p < n; ++p) {
    if (p % 3 == 0) {
      cloud.Add(uniform(rng), 0.5f * uniform(rng), 2.0f * uniform(rng));
    } else {
      Eigen::Vector3f v(normal(rng), normal(rng), normal(rng));
      v.normalize();
      cloud.Add(v.x() * 1.7f + 0.3f, v.y() - 5.0f, v.z() * 0.6f);
    }
  }
  return cloud;
}

// ---------------------------------------------------------------------------------------
// Brute-force reference: unpacked grid, a plain triple loop per direction, the spec's
// formulas written out. Shares nothing with comsd.cc except the direction table.

struct RefGrid {
  int n = 0;
  std::vector<uint8_t> v;
  int At(int i, int j, int k) const { return v[(static_cast<size_t>(i) * n + j) * n + k]; }
};

// Eq. 8.1 per point: {i, j, k}. In float, as the spec's implementation note fixes it; a
// double reference would disagree on points that sit within rounding of a cell boundary.
std::vector<std::array<int, 3>> RefIndices(const PointCloud& cloud, int n) {
  float lo[3], hi[3];
  for (int a = 0; a < 3; ++a) lo[a] = hi[a] = cloud.data()[a];
  for (size_t p = 0; p < cloud.size(); ++p) {
    for (int a = 0; a < 3; ++a) {
      lo[a] = std::min(lo[a], cloud.data()[3 * p + a]);
      hi[a] = std::max(hi[a], cloud.data()[3 * p + a]);
    }
  }
  auto index = [&](float v, int a) {
    const float extent = hi[a] - lo[a];
    if (extent == 0.0f) return 0;
    return static_cast<int>(std::floor((v - lo[a]) / extent * static_cast<float>(n - 1)));
  };
  std::vector<std::array<int, 3>> indices;
  for (size_t p = 0; p < cloud.size(); ++p) {
    const float* q = cloud.data() + 3 * p;
    indices.push_back({index(q[1], 1), index(q[0], 0), index(q[2], 2)});
  }
  return indices;
}

RefGrid RefVoxelize(const PointCloud& cloud, int n) {
  RefGrid grid;
  grid.n = n;
  grid.v.assign(static_cast<size_t>(n) * n * n, 0);
  for (const auto& [i, j, k] : RefIndices(cloud, n)) {
    grid.v[(static_cast<size_t>(i) * n + j) * n + k] = 1;
  }
  return grid;
}

AllCounts RefCount(const RefGrid& grid) {
  const int n = grid.n;
  AllCounts counts;
  for (int d = 0; d < kNumDirections; ++d) {
    const auto dir = kDirections[d];
    for (int i = 0; i < n; ++i) {
      for (int j = 0; j < n; ++j) {
        for (int k = 0; k < n; ++k) {
          const int i2 = i + dir.dy, j2 = j + dir.dx, k2 = k + dir.dz;
          if (i2 < 0 || i2 >= n || j2 < 0 || j2 >= n || k2 < 0 || k2 >= n) continue;
          ++counts[d].counts[grid.At(i, j, k)][grid.At(i2, j2, k2)];
        }
      }
    }
  }
  return counts;
}

std::vector<double> RefFeatures(const AllCounts& counts) {
  std::vector<double> out;
  for (const auto& c : counts) {
    double total = 0;
    for (int r = 0; r < 2; ++r)
      for (int s = 0; s < 2; ++s) total += c.counts[r][s];
    auto P = [&](int r, int s) { return c.counts[r][s] / total; };
    double entropy = 0, energy = 0, contrast = 0, homogeneity = 0, mu = 0;
    for (int r = 0; r < 2; ++r) {
      for (int s = 0; s < 2; ++s) {
        if (P(r, s) > 0) entropy += -P(r, s) * std::log(P(r, s));
        energy += P(r, s) * P(r, s);
        contrast += (r - s) * (r - s) * P(r, s);
        homogeneity += P(r, s) / (1.0 + std::abs(r - s));
        mu += 0.5 * (r * P(r, s) + s * P(r, s));
      }
    }
    double variance = 0, covariance = 0;
    for (int r = 0; r < 2; ++r) {
      for (int s = 0; s < 2; ++s) {
        variance += 0.5 * ((r - mu) * (r - mu) * P(r, s) + (s - mu) * (s - mu) * P(r, s));
        covariance += (r - mu) * (s - mu) * P(r, s);
      }
    }
    const double correlation = variance == 0 ? 0 : covariance / variance;
    for (double f : {entropy, energy, contrast, homogeneity, mu, variance, correlation}) {
      out.push_back(f);
    }
  }
  return out;
}

void ExpectCountsEqual(const AllCounts& expected, const AllCounts& actual,
                       const std::string& context) {
  for (int d = 0; d < kNumDirections; ++d) {
    for (int a = 0; a < 2; ++a) {
      for (int b = 0; b < 2; ++b) {
        EXPECT_EQ(expected[d].counts[a][b], actual[d].counts[a][b])
            << context << " direction " << d << " cell " << a << b;
      }
    }
  }
}

// ---------------------------------------------------------------------------------------

TEST(ComsdTest, KindAndCanonicalSpec) {
  auto descriptor = CreateDescriptor("comsd");
  ASSERT_TRUE(descriptor.ok()) << descriptor.status();
  EXPECT_EQ((*descriptor)->spec().ToString(), "comsd:grid=50");
  EXPECT_EQ((*descriptor)->dimension(), 91u);

  auto padded = CreateDescriptor("comsd:grid=050");
  ASSERT_TRUE(padded.ok()) << padded.status();
  EXPECT_EQ((*padded)->spec().ToString(), "comsd:grid=50");

  for (int grid : {2, 512}) {
    auto edge = CreateDescriptor(absl::StrCat("comsd:grid=", grid));
    ASSERT_TRUE(edge.ok()) << edge.status();
    EXPECT_EQ((*edge)->dimension(), 91u);
  }
  EXPECT_THAT(DescribeRegistry(), HasSubstr("[2, 512]"));
}

TEST(ComsdTest, RejectsInvalidSpecs) {
  struct Case {
    std::string spec;
    std::string message;
  };
  for (const Case& c : std::vector<Case>{
           {"comsd:grid=1", "grid=1 is outside [2, 512]"},
           {"comsd:grid=0", "grid=0 is outside [2, 512]"},
           {"comsd:grid=-5", "outside [2, 512]"},
           {"comsd:grid=10000", "grid=10000 is outside [2, 512]"},
           {"comsd:grid=abc", "grid=abc is not an integer"},
           {"comsd:grid=2.5", "is not an integer"},
           {"comsd:bins=10", "comsd has no parameter \"bins\"; its parameters: grid"},
       }) {
    auto descriptor = CreateDescriptor(c.spec);
    ASSERT_FALSE(descriptor.ok()) << c.spec;
    EXPECT_EQ(descriptor.status().code(), absl::StatusCode::kInvalidArgument) << c.spec;
    EXPECT_THAT(std::string(descriptor.status().message()), HasSubstr(c.message)) << c.spec;
  }
}

TEST(ComsdTest, RejectsInvalidClouds) {
  auto comsd = MakeComsd(8);
  struct Case {
    PointCloud cloud;
    std::string message;
  };
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float inf = std::numeric_limits<float>::infinity();
  std::vector<Case> cases;
  cases.push_back({PointCloud(), "at least 3"});
  cases.push_back({PointCloud({{0, 0, 0}, {1, 1, 1}}), "at least 3"});
  cases.push_back({PointCloud({{0, 0, 0}, {1, nan, 1}, {2, 2, 2}}), "non-finite"});
  cases.push_back({PointCloud({{0, 0, 0}, {1, 1, 1}, {inf, 2, 2}}), "non-finite"});
  cases.push_back({PointCloud({{3, 4, 5}, {3, 4, 5}, {3, 4, 5}, {3, 4, 5}}), "identical"});
  for (const Case& c : cases) {
    std::vector<float> out;
    const absl::Status status = comsd->Compute(c.cloud, &out);
    EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument) << status;
    EXPECT_THAT(std::string(status.message()), HasSubstr(c.message));
  }
}

// N = 2 and four corners of the unit box (coordinates (x, y, z)):
//   (0,0,0) (1,0,0) (0,1,1) (0,0,0)   [the repeat only re-fills a voxel]
// Indices (i from y, j from x, k from z) are the coordinates themselves, so the filled voxels
// V[i,j,k] are V[0,0,0], V[0,1,0], V[1,0,1]; the other five are empty.
// Pairs (V[i,j,k] -> V[i+dy, j+dx, k+dz]) per direction, as counts [[C00, C01], [C10, C11]]:
//   d1  ( 1, 0,0): 000->010 1-1, 001->011 0-0, 100->110 0-0, 101->111 1-0  [[2,0],[1,1]]
//   d2  ( 1, 1,0): 000->110 1-0, 001->111 0-0                              [[1,0],[1,0]]
//   d3  ( 0, 1,0): 000->100 1-0, 001->101 0-1, 010->110 1-0, 011->111 0-0  [[1,1],[2,0]]
//   d4  (-1, 1,0): 010->100 1-0, 011->101 0-1                              [[0,1],[1,0]]
//   d5  ( 0, 0,1): 000->001 1-0, 010->011 1-0, 100->101 0-1, 110->111 0-0  [[1,1],[2,0]]
//   d6  ( 1, 0,1): 000->011 1-0, 100->111 0-0                              [[1,0],[1,0]]
//   d7  ( 0, 1,1): 000->101 1-1, 010->111 1-0                              [[0,0],[1,1]]
//   d8  (-1, 0,1): 010->001 1-0, 110->101 0-1                              [[0,1],[1,0]]
//   d9  ( 0,-1,1): 100->001 0-0, 110->011 0-0                              [[2,0],[0,0]]
//   d10 ( 1, 1,1): 000->111 1-0                                            [[0,0],[1,0]]
//   d11 (-1, 1,1): 010->101 1-1                                            [[0,0],[0,1]]
//   d12 ( 1,-1,1): 100->011 0-0                                            [[1,0],[0,0]]
//   d13 (-1,-1,1): 110->001 0-0                                            [[1,0],[0,0]]
// (d4 vs d8 and d11 vs d12 tell the x -> j, y -> i reading from its transpose.)
// Features (entropy, energy, contrast, homogeneity, mu, variance, correlation) of each P:
//  A = P[[.5,0],[.25,.25]] (d1): H = -(.5 ln .5 + 2 (.25 ln .25)) = 1.5 ln 2; energy .375;
//      contrast .25; homogeneity .5 + .25 + .25/2 = .875; mu = (P10 + P01 + 2 P11)/2 = .375;
//      row marginal (.5, .5), column marginal (.75, .25):
//      s2 = (.375^2 .5 + .625^2 .5 + .375^2 .75 + .625^2 .25) / 2 = .234375;
//      cov = .375^2 .5 - .625 .375 .25 + .625^2 .25 = .109375; corr = 7/15.
//  B = P[[.5,0],[.5,0]] (d2, d6): H = ln 2; energy .5; contrast .5; homogeneity .75; mu .25;
//      s2 = (.25^2 .5 + .75^2 .5 + .25^2) / 2 = .1875; cov = .25^2 .5 - .75 .25 .5 = -.0625;
//      corr = -1/3.
//  C = P[[.25,.25],[.5,0]] (d3, d5): H = 1.5 ln 2; energy .375; contrast .75; homogeneity
//      .25 + .75/2 = .625; mu = .375; marginals row (.5, .5), column (.75, .25) as in A, so
//      s2 = .234375; cov = .375^2 .25 - .375 .625 .25 - .625 .375 .5 = -.140625; corr = -.6.
//  D = P[[0,.5],[.5,0]] (d4, d8): H = ln 2; energy .5; contrast 1; homogeneity .5; mu .5;
//      s2 = .25; cov = -.25; corr = -1.
//  E = P[[0,0],[.5,.5]] (d7): H = ln 2; energy .5; contrast .5; homogeneity .75; mu .75;
//      s2 = (.25^2 + .75^2 .5 + .25^2 .5) / 2 = .1875; cov = -.25 .75 .5 + .25^2 .5 = -.0625;
//      corr = -1/3.
//  F = P00 = 1 (d9, d12, d13): (0, 1, 0, 1, 0, 0, 0), the variance-0 case.
//  G = P10 = 1 (d10): (0, 1, 1, .5, .5, .25, -.25/.25 = -1).
//  K = P11 = 1 (d11): (0, 1, 0, 1, 1, 0, 0).
TEST(ComsdTest, HandComputedTwoByTwoGrid) {
  const PointCloud cloud({{0, 0, 0}, {1, 0, 0}, {0, 1, 1}, {0, 0, 0}});
  const double ln2 = std::log(2.0);
  const std::vector<double> a = {1.5 * ln2, .375, .25, .875, .375, .234375, 7.0 / 15.0};
  const std::vector<double> b = {ln2, .5, .5, .75, .25, .1875, -1.0 / 3.0};
  const std::vector<double> c = {1.5 * ln2, .375, .75, .625, .375, .234375, -.6};
  const std::vector<double> d = {ln2, .5, 1, .5, .5, .25, -1};
  const std::vector<double> e = {ln2, .5, .5, .75, .75, .1875, -1.0 / 3.0};
  const std::vector<double> f = {0, 1, 0, 1, 0, 0, 0};
  const std::vector<double> g = {0, 1, 1, .5, .5, .25, -1};
  const std::vector<double> k = {0, 1, 0, 1, 1, 0, 0};
  const std::vector<const std::vector<double>*> expected = {&a, &b, &c, &d, &c, &b, &e,
                                                            &d, &f, &g, &k, &f, &f};

  const std::vector<float> out = Describe(*MakeComsd(2), cloud);
  ASSERT_EQ(out.size(), 91u);
  for (int dir = 0; dir < kNumDirections; ++dir) {
    for (int feature = 0; feature < kNumFeatures; ++feature) {
      EXPECT_NEAR(out[dir * kNumFeatures + feature], (*expected[dir])[feature], 1e-7)
          << "direction " << dir + 1 << " feature " << feature;
    }
  }

  // The counts themselves, from the table above.
  const int64_t table[kNumDirections][4] = {{2, 0, 1, 1}, {1, 0, 1, 0}, {1, 1, 2, 0}, {0, 1, 1, 0},
                                            {1, 1, 2, 0}, {1, 0, 1, 0}, {0, 0, 1, 1}, {0, 1, 1, 0},
                                            {2, 0, 0, 0}, {0, 0, 1, 0}, {0, 0, 0, 1}, {1, 0, 0, 0},
                                            {1, 0, 0, 0}};
  AllCounts hand;
  for (int dir = 0; dir < kNumDirections; ++dir) {
    for (int cell = 0; cell < 4; ++cell) hand[dir].counts[cell / 2][cell % 2] = table[dir][cell];
  }
  auto stats = ValidateCloud(cloud);
  ASSERT_TRUE(stats.ok());
  const auto grid = comsd_internal::Voxelize(cloud, *stats, 2);
  for (PopcountPath path : {PopcountPath::kPortable, PopcountPath::kHardware}) {
    ExpectCountsEqual(hand, comsd_internal::CountCooccurrences(grid, path), "hand");
  }
}

// N = 3 and three points on x, so y and z have zero extent and map to index 0; x spans
// [0, 2]: x = 0 -> j = floor(0/2 * 2) = 0, x = 0.99 -> floor(0.99) = 0, x = 2 -> 2.
// Filled: V[0,0,0] and V[0,2,0]. Direction d1 (1,0,0) has 2 x 3 x 3 = 18 pairs; the filled
// ones are sources of 000->010 (1-0) and targets of 010->020 (0-1); 16 pairs are 0-0:
// P = [[16/18, 1/18], [1/18, 0]]; contrast = 2/18; mu = (1/18 + 1/18)/2 = 1/18.
TEST(ComsdTest, HandComputedFlatCloud) {
  const PointCloud cloud({{0, 7, -1}, {0.99f, 7, -1}, {2, 7, -1}});
  const std::vector<float> out = Describe(*MakeComsd(3), cloud);
  ASSERT_EQ(out.size(), 91u);
  const double p00 = 16.0 / 18, p01 = 1.0 / 18;
  EXPECT_NEAR(out[0], -(p00 * std::log(p00) + 2 * p01 * std::log(p01)), 1e-7);
  EXPECT_NEAR(out[1], p00 * p00 + 2 * p01 * p01, 1e-7);
  EXPECT_NEAR(out[2], 2.0 / 18, 1e-7);
  EXPECT_NEAR(out[4], 1.0 / 18, 1e-7);
  for (float v : out) EXPECT_TRUE(std::isfinite(v));
}

TEST(ComsdTest, VoxelizeMatchesFormulaAndFillsBothEnds) {
  for (int n : {2, 3, 50, 64, 65, 100, 130, 512}) {
    const PointCloud cloud = RandomCloud(300, 7 + n);
    auto stats = ValidateCloud(cloud);
    ASSERT_TRUE(stats.ok());
    const auto grid = comsd_internal::Voxelize(cloud, *stats, n);
    ASSERT_EQ(grid.words, (n + 63) / 64);
    ASSERT_EQ(grid.bits.size(), static_cast<size_t>(n) * n * grid.words);

    // Every point's voxel is set, and nothing else is: the grid holds exactly the distinct
    // reference voxels.
    const auto indices = RefIndices(cloud, n);
    std::vector<size_t> linear;
    bool low[3] = {false, false, false}, high[3] = {false, false, false};
    for (const auto& [i, j, k] : indices) {
      EXPECT_TRUE(grid.Get(i, j, k)) << "n=" << n << " voxel " << i << "," << j << "," << k;
      linear.push_back((static_cast<size_t>(i) * n + j) * n + k);
      const int index[3] = {i, j, k};
      for (int a = 0; a < 3; ++a) {
        low[a] |= index[a] == 0;
        high[a] |= index[a] == n - 1;
      }
    }
    std::sort(linear.begin(), linear.end());
    linear.erase(std::unique(linear.begin(), linear.end()), linear.end());
    size_t set_bits = 0;
    for (size_t w = 0; w < grid.bits.size(); ++w) {
      for (uint64_t word = grid.bits[w]; word != 0; word &= word - 1) ++set_bits;
      // Bits past k = n - 1 stay clear: the shifted counting relies on it.
      if (w % grid.words == static_cast<size_t>(grid.words - 1) && n % 64 != 0) {
        EXPECT_EQ(grid.bits[w] >> (n % 64), 0u) << "n=" << n;
      }
    }
    EXPECT_EQ(set_bits, linear.size()) << "n=" << n;
    // The box's extreme points land in the first and last cell of every axis.
    for (int a = 0; a < 3; ++a) {
      EXPECT_TRUE(low[a]) << "n=" << n << " axis " << a;
      EXPECT_TRUE(high[a]) << "n=" << n << " axis " << a;
    }
  }
}

TEST(ComsdTest, MatchesBruteForceReference) {
  for (int n : {2, 3, 7, 50, 63, 64, 65, 100, 128, 130}) {
    for (size_t points : {5u, 400u, 6000u}) {
      const PointCloud cloud = RandomCloud(points, static_cast<uint32_t>(n * 1000 + points));
      const std::string context = absl::StrCat("n=", n, " points=", points);
      const RefGrid ref_grid = RefVoxelize(cloud, n);
      const AllCounts ref_counts = RefCount(ref_grid);
      const std::vector<double> ref = RefFeatures(ref_counts);

      auto stats = ValidateCloud(cloud);
      ASSERT_TRUE(stats.ok());
      const auto grid = comsd_internal::Voxelize(cloud, *stats, n);
      for (PopcountPath path : {PopcountPath::kPortable, PopcountPath::kHardware}) {
        ExpectCountsEqual(ref_counts, comsd_internal::CountCooccurrences(grid, path), context);
      }
      const std::vector<float> out = Describe(*MakeComsd(n), cloud);
      ASSERT_EQ(out.size(), ref.size());
      for (size_t f = 0; f < ref.size(); ++f) {
        // Both sides compute in double; only the final cast to float may round differently.
        EXPECT_NEAR(out[f], ref[f], 1e-6 * std::max(1.0, std::abs(ref[f])))
            << context << " value " << f;
      }
    }
  }
}

TEST(ComsdTest, PopcountPathsAreIdenticalOnRandomGrids) {
  if (!comsd_internal::HardwarePopcountAvailable()) {
    GTEST_SKIP() << "no POPCNT on this CPU: kHardware falls back to the portable path";
  }
  std::mt19937_64 rng(42);
  for (int n : {2, 5, 63, 64, 65, 127, 129, 200}) {
    comsd_internal::PackedGrid grid;
    grid.n = n;
    grid.words = (n + 63) / 64;
    grid.bits.resize(static_cast<size_t>(n) * n * grid.words);
    for (size_t w = 0; w < grid.bits.size(); ++w) {
      // Keep bits at k >= n clear, as Voxelize does.
      const int used = std::min(64, n - static_cast<int>(w % grid.words) * 64);
      const uint64_t mask = used == 64 ? ~uint64_t{0} : (uint64_t{1} << used) - 1;
      grid.bits[w] = rng() & rng() & mask;  // about a quarter of the voxels filled
    }
    const AllCounts portable = comsd_internal::CountCooccurrences(grid, PopcountPath::kPortable);
    const AllCounts hardware = comsd_internal::CountCooccurrences(grid, PopcountPath::kHardware);
    ExpectCountsEqual(portable, hardware, absl::StrCat("n=", n));
    for (int d = 0; d < kNumDirections; ++d) {
      const auto dir = kDirections[d];
      const int64_t pairs = int64_t{n - std::abs(dir.dx)} * (n - std::abs(dir.dy)) * (n - dir.dz);
      const auto& c = portable[d].counts;
      EXPECT_EQ(c[0][0] + c[0][1] + c[1][0] + c[1][1], pairs);
      for (int a = 0; a < 2; ++a) {
        for (int b = 0; b < 2; ++b) EXPECT_GE(c[a][b], 0);
      }
    }
  }
}

// Coordinates are multiples of 1/16 and the transforms are exact in float (integer shifts,
// scales 2.5 and 0.375), so (v - vmin) / (vmax - vmin) is the same real number and rounds
// the same: the descriptor must be bit-identical, not merely close. (With arbitrary floats a
// point within one rounding of a cell boundary may legitimately change cell.)
TEST(ComsdTest, TranslationAndScaleInvariant) {
  std::mt19937 rng(3);
  std::uniform_int_distribution<int> coord(-160, 160);
  PointCloud cloud;
  for (int p = 0; p < 3000; ++p) {
    cloud.Add(coord(rng) / 16.0f, coord(rng) / 32.0f, coord(rng) / 8.0f);
  }
  auto comsd = MakeComsd(20);
  const std::vector<float> base = Describe(*comsd, cloud);
  for (float scale : {1.0f, 2.5f, 0.375f}) {
    for (const Eigen::Vector3f& shift : {Eigen::Vector3f(0, 0, 0), Eigen::Vector3f(3, -7, 100)}) {
      PointCloud moved;
      for (size_t p = 0; p < cloud.size(); ++p) {
        moved.Add(Eigen::Vector3f(cloud.point(p) * scale + shift));
      }
      EXPECT_EQ(Describe(*comsd, moved), base) << "scale " << scale << " shift " << shift.x();
    }
  }
}

TEST(ComsdTest, PointOrderDoesNotMatter) {
  const PointCloud cloud = RandomCloud(5000, 11);
  std::vector<size_t> order(cloud.size());
  for (size_t p = 0; p < order.size(); ++p) order[p] = p;
  std::shuffle(order.begin(), order.end(), std::mt19937(5));
  PointCloud shuffled;
  for (size_t p : order) shuffled.Add(cloud.point(p));
  auto comsd = MakeComsd(50);
  EXPECT_EQ(Describe(*comsd, shuffled), Describe(*comsd, cloud));
}

TEST(ComsdTest, RepeatedRunsAreBitIdentical) {
  const PointCloud cloud = RandomCloud(20000, 13);
  auto comsd = MakeComsd(50);
  const std::vector<float> first = Describe(*comsd, cloud);
  for (int run = 0; run < 5; ++run) EXPECT_EQ(Describe(*comsd, cloud), first);
  // A second object with the same spec gives the same bits too.
  EXPECT_EQ(Describe(*MakeComsd(50), cloud), first);
}

TEST(ComsdTest, ZeroExtentAxesGiveFiniteValues) {
  // A flat cloud (z constant) and a line (y and z constant) are valid: only an all-identical
  // cloud is refused.
  PointCloud flat, line;
  std::mt19937 rng(17);
  std::uniform_real_distribution<float> u(-1, 1);
  for (int p = 0; p < 1000; ++p) {
    flat.Add(u(rng), u(rng), 0.25f);
    line.Add(u(rng), -3.0f, 0.25f);
  }
  for (int n : {2, 50, 70}) {
    auto comsd = MakeComsd(n);
    for (const PointCloud* cloud : {&flat, &line}) {
      const std::vector<float> out = Describe(*comsd, *cloud);
      ASSERT_EQ(out.size(), 91u);
      for (float v : out) EXPECT_TRUE(std::isfinite(v));
      // Only the k = 0 plane is filled, so along (0, 0, 1) no pair ends on a filled voxel.
      auto stats = ValidateCloud(*cloud);
      ASSERT_TRUE(stats.ok());
      const auto counts = comsd_internal::CountCooccurrences(
          comsd_internal::Voxelize(*cloud, *stats, n), PopcountPath::kPortable);
      EXPECT_EQ(counts[4].counts[0][1], 0);
      EXPECT_EQ(counts[4].counts[1][1], 0);
      EXPECT_GT(counts[4].counts[1][0], 0);
    }
  }
}

// An extent beyond float range takes the double path; with power-of-two coordinates its
// indices equal those of the same cloud scaled down into the float path.
TEST(ComsdTest, HugeExtentStaysFinite) {
  const float big = std::ldexp(1.0f, 127);
  const float half = std::ldexp(1.0f, 126);
  const PointCloud huge({{-big, 0, 1}, {-half, 1, 2}, {0, 2, 3}, {half, 3, 4}, {big, 4, 5}});
  const PointCloud small({{-128, 0, 1}, {-64, 1, 2}, {0, 2, 3}, {64, 3, 4}, {128, 4, 5}});
  auto comsd = MakeComsd(5);
  const std::vector<float> out = Describe(*comsd, huge);
  ASSERT_EQ(out.size(), 91u);
  EXPECT_EQ(out, Describe(*comsd, small));
}

}  // namespace
}  // namespace shapeid
