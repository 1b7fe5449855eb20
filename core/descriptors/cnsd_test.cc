#include "core/descriptors/cnsd.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include "absl/strings/str_cat.h"
#include "core/descriptor_registry.h"
#include "core/descriptors/cnsd_downsample.h"
#include "core/testing/test_clouds.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"

namespace shapeid {
namespace {

using ::testing::HasSubstr;
namespace ci = cnsd_internal;

using testing_clouds::SphereCloud;
using testing_clouds::UniformCloud;

std::vector<SimdLevel> AvailableLevels() {
  std::vector<SimdLevel> levels = {SimdLevel::kScalar};
  if (DetectedSimdLevel() >= SimdLevel::kAvx2) levels.push_back(SimdLevel::kAvx2);
  if (DetectedSimdLevel() >= SimdLevel::kAvx512) levels.push_back(SimdLevel::kAvx512);
  return levels;
}

std::vector<float> Features(const PointCloud& cloud, const std::vector<double>& thresholds,
                            SimdLevel level) {
  std::vector<float> out(2 * thresholds.size());
  const absl::Status status = ci::ComputeFeatures(cloud, thresholds, level, absl::MakeSpan(out));
  EXPECT_TRUE(status.ok()) << status;
  return out;
}

// The definition, literally: an explicit n x n matrix of squared distances on the same
// normalized floats and the same squared bounds, and a direct count per threshold.
std::vector<float> BruteForce(const PointCloud& cloud, const std::vector<double>& thresholds) {
  const std::vector<float> xyz = ci::NormalizedXyz(cloud);
  const size_t n = cloud.size();
  std::vector<float> d2(n * n);
  float max_d2 = 0;
  for (size_t i = 0; i < n; ++i) {
    for (size_t j = 0; j < n; ++j) {
      const float dx = xyz[3 * j] - xyz[3 * i];
      const float dy = xyz[3 * j + 1] - xyz[3 * i + 1];
      const float dz = xyz[3 * j + 2] - xyz[3 * i + 2];
      d2[i * n + j] = (dx * dx + dy * dy) + dz * dz;
      max_d2 = std::max(max_d2, d2[i * n + j]);
    }
  }
  std::vector<float> out;
  for (double t : thresholds) {
    const float bound = ci::SquaredThreshold(t, max_d2);
    uint64_t sum = 0, max = 0;
    for (size_t i = 0; i < n; ++i) {
      uint64_t degree = 0;
      for (size_t j = 0; j < n; ++j) degree += (j != i && d2[i * n + j] <= bound);
      sum += degree;
      max = std::max(max, degree);
    }
    out.push_back(static_cast<float>(static_cast<double>(sum) / (double(n) * double(n))));
    out.push_back(static_cast<float>(static_cast<double>(max) / double(n)));
  }
  return out;
}

TEST(CnsdTest, HandComputedFourPoints) {
  // A(0,0,1) B(1,0,1) C(0,2,1) D(3,0,1). Distances: AB 1, AC 2, BD 2, BC sqrt5 = 2.236,
  // AD 3, CD sqrt13 = 3.606 = d_max. Weights: AB .277, AC .555, BD .555, BC .620, AD .832,
  // CD 1. Thresholds 0.3, 0.65, 1 (0.3 + 2 * 0.35 snapped to t_end = 1).
  //  T=0.3:  AB.                 degrees A1 B1 C0 D0: avg 2/16 = .125, max 1/4 = .25
  //  T=0.65: AB AC BD BC.        degrees A2 B3 C2 D1: avg 8/16 = .5,   max 3/4 = .75
  //  T=1:    all 6 (CD exactly). degrees 3 3 3 3:     avg 12/16 = .75, max 3/4 = .75
  const PointCloud cloud = {{0, 0, 1}, {1, 0, 1}, {0, 2, 1}, {3, 0, 1}};
  auto d = CreateDescriptor("cnsd:t_start=0.3,t_end=1,t_step=0.35");
  ASSERT_TRUE(d.ok()) << d.status();
  EXPECT_EQ((*d)->spec().ToString(),
            "cnsd:t_start=0.3,t_end=1,t_step=0.35,max_points=8000,downsample=voxel,seed=0");
  ASSERT_EQ((*d)->dimension(), 6u);
  const std::vector<float> expected = {0.125f, 0.25f, 0.5f, 0.75f, 0.75f, 0.75f};
  auto v = (*d)->Compute(cloud);
  ASSERT_TRUE(v.ok()) << v.status();
  EXPECT_EQ(*v, expected);
  const std::vector<double> thresholds = ci::Thresholds(0.3, 1, 0.35);
  ASSERT_EQ(thresholds.size(), 3u);
  EXPECT_EQ(thresholds.back(), 1.0);
  for (SimdLevel level : AvailableLevels()) {
    EXPECT_EQ(Features(cloud, thresholds, level), expected) << SimdLevelName(level);
  }
}

TEST(CnsdTest, PairsExactlyAtAThresholdAreJoined) {
  // Five points at x = 0..4; d_max = 4; T = 0.25, 0.5, 0.75, 1 join pairs with d <= 1, 2, 3,
  // 4, and every distance is exactly k * T * d_max (all binary fractions).
  //  d<=1: 0-1 1-2 2-3 3-4           degrees 1 2 2 2 1: avg 8/25,  max 2/5
  //  d<=2: + 0-2 1-3 2-4             degrees 2 3 4 3 2: avg 14/25, max 4/5
  //  d<=3: + 0-3 1-4                 degrees 3 4 4 4 3: avg 18/25, max 4/5
  //  d<=4: + 0-4                     degrees 4 4 4 4 4: avg 20/25, max 4/5
  const PointCloud cloud = {{0, 0, 0}, {1, 0, 0}, {2, 0, 0}, {3, 0, 0}, {4, 0, 0}};
  const std::vector<float> expected = {float(8.0 / 25),  float(2.0 / 5),   float(14.0 / 25),
                                       float(4.0 / 5),   float(18.0 / 25), float(4.0 / 5),
                                       float(20.0 / 25), float(4.0 / 5)};
  for (SimdLevel level : AvailableLevels()) {
    EXPECT_EQ(Features(cloud, ci::Thresholds(0.25, 1, 0.25), level), expected)
        << SimdLevelName(level);
  }
}

TEST(CnsdTest, MatchesBruteForceOnRandomClouds) {
  const std::vector<std::vector<double>> threshold_sets = {
      ci::Thresholds(0.05, 0.95, 0.05),   // the default, 19: register table lookups
      ci::Thresholds(0.0, 1.0, 0.01),     // 101: gathered table lookups, counters in memory
      ci::Thresholds(0.3, 0.7, 0.05),     // 9: counters packed in 2 words
      ci::Thresholds(0.02, 0.62, 0.02),   // 31: counters packed in 4 words, the most
      ci::Thresholds(0.5, 0.5025, 1e-4),  // 26 of the finest steps: the tightest approximation
  };
  for (size_t n : {3, 17, 100, 1000}) {
    const PointCloud cloud = UniformCloud(n, static_cast<uint32_t>(n));
    for (const auto& thresholds : threshold_sets) {
      const std::vector<float> expected = BruteForce(cloud, thresholds);
      for (SimdLevel level : AvailableLevels()) {
        EXPECT_EQ(Features(cloud, thresholds, level), expected)
            << "n=" << n << " S=" << thresholds.size() << " " << SimdLevelName(level);
      }
    }
  }
}

TEST(CnsdTest, MatchesBruteForceOnALatticeFullOfTies) {
  // Integer lattice points: squared distances are integers, and with steps of 1/64 many of
  // them fall exactly on a bound, the worst case for the kernels' bucket approximation.
  PointCloud cloud;
  for (int i = 0; i < 6; ++i) {
    for (int j = 0; j < 6; ++j) {
      for (int k = 0; k < 5; ++k) cloud.Add(float(i), float(j), float(k));
    }
  }
  for (const auto& thresholds : {ci::Thresholds(1.0 / 64, 1.0, 1.0 / 64),
                                 ci::Thresholds(0.05, 0.95, 0.05), ci::Thresholds(0.1, 1.0, 0.1)}) {
    const std::vector<float> expected = BruteForce(cloud, thresholds);
    for (SimdLevel level : AvailableLevels()) {
      EXPECT_EQ(Features(cloud, thresholds, level), expected)
          << "S=" << thresholds.size() << " " << SimdLevelName(level);
    }
  }
}

TEST(CnsdTest, UnevenThresholdsAreStillExact) {
  // The vector kernels assume evenly spaced thresholds; other lists take the exact path.
  const PointCloud cloud = UniformCloud(300, 21);
  const std::vector<double> thresholds = {0.1, 0.5, 0.55, 0.56, 1.0};
  const std::vector<float> expected = BruteForce(cloud, thresholds);
  for (SimdLevel level : AvailableLevels()) {
    EXPECT_EQ(Features(cloud, thresholds, level), expected) << SimdLevelName(level);
  }
}

TEST(CnsdTest, InvariantToTranslationAndScale) {
  auto d = CreateDescriptor("cnsd");
  ASSERT_TRUE(d.ok()) << d.status();
  const size_t n = 500;
  const PointCloud cloud = SphereCloud(n, 7);
  PointCloud moved, scaled, doubled;
  for (size_t i = 0; i < n; ++i) {
    const Eigen::Vector3f p = cloud.point(i);
    moved.Add(p + Eigen::Vector3f(12.5f, -7.25f, 3.0f));
    scaled.Add(3.7f * p);
    doubled.Add(4.0f * p);
  }
  const auto base = (*d)->Compute(cloud);
  ASSERT_TRUE(base.ok()) << base.status();
  // Rounding can move a pair that sits on a bound across it: 2/n^2 on an average, 1/n on a
  // maximum.
  for (const PointCloud* other : {&moved, &scaled}) {
    const auto v = (*d)->Compute(*other);
    ASSERT_TRUE(v.ok()) << v.status();
    for (size_t k = 0; k < base->size(); ++k) EXPECT_NEAR((*v)[k], (*base)[k], 2.0 / n) << k;
  }
  // A power-of-two scale changes no rounding at all.
  EXPECT_EQ(*(*d)->Compute(doubled), *base);
}

TEST(CnsdTest, InvariantToPointOrderAndRepeatableBitForBit) {
  auto d = CreateDescriptor("cnsd");
  ASSERT_TRUE(d.ok()) << d.status();
  const PointCloud cloud = UniformCloud(777, 3);
  std::vector<size_t> order(cloud.size());
  for (size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::shuffle(order.begin(), order.end(), std::mt19937(11));
  PointCloud shuffled;
  for (size_t i : order) shuffled.Add(cloud.point(i));
  const auto first = (*d)->Compute(cloud);
  ASSERT_TRUE(first.ok()) << first.status();
  EXPECT_EQ(*(*d)->Compute(cloud), *first);
  EXPECT_EQ(*(*d)->Compute(shuffled), *first);
}

TEST(CnsdTest, AllSimdLevelsAgreeBitForBit) {
  // 4500 points: rows long enough for the packed kernels to spread their byte counters
  // into memory more than once (every 4080 pairs with AVX-512, 2040 with AVX2).
  for (const auto& [cloud, thresholds] :
       {std::make_pair(SphereCloud(4500, 5), ci::Thresholds(0.05, 0.95, 0.05)),
        std::make_pair(SphereCloud(1500, 6), ci::Thresholds(0, 1, 0.003))}) {
    const std::vector<float> scalar = Features(cloud, thresholds, SimdLevel::kScalar);
    for (SimdLevel level : AvailableLevels()) {
      EXPECT_EQ(Features(cloud, thresholds, level), scalar)
          << "S=" << thresholds.size() << " " << SimdLevelName(level);
    }
  }
  if (AvailableLevels().size() < 3) GTEST_SKIP() << "this CPU lacks AVX2 or AVX-512";
}

TEST(CnsdTest, CloudsOverMaxPointsAreDownsampledFirst) {
  const PointCloud cloud = SphereCloud(3000, 17);
  const std::vector<double> thresholds = ci::Thresholds(0.05, 0.95, 0.05);
  for (const char* spec : {"cnsd:max_points=500", "cnsd:max_points=500,downsample=random,seed=5"}) {
    auto d = CreateDescriptor(spec);
    ASSERT_TRUE(d.ok()) << d.status();
    const auto v = (*d)->Compute(cloud);
    ASSERT_TRUE(v.ok()) << spec << ": " << v.status();
    ASSERT_EQ(v->size(), 38u);
    for (float f : *v) EXPECT_TRUE(std::isfinite(f) && f >= 0 && f <= 1) << spec;
    const PointCloud reduced = std::string(spec).find("random") != std::string::npos
                                   ? ci::RandomDownsample(cloud, 500, 5)
                                   : ci::VoxelDownsample(cloud, 500);
    EXPECT_EQ(*v, Features(reduced, thresholds, ActiveSimdLevel())) << spec;
  }
}

TEST(CnsdTest, RandomSubsetOfCoincidentPointsIsAnError) {
  // 19 copies of the origin and one other point; some seed keeps only copies.
  PointCloud cloud;
  for (int i = 0; i < 19; ++i) cloud.Add(0, 0, 0);
  cloud.Add(1, 0, 0);
  const std::vector<float> zeros(3 * 8, 0.0f);
  uint64_t seed = 0;
  while (ci::RandomDownsample(cloud, 8, seed).xyz() != absl::Span<const float>(zeros)) ++seed;
  auto d = CreateDescriptor(absl::StrCat("cnsd:max_points=8,downsample=random,seed=", seed));
  ASSERT_TRUE(d.ok()) << d.status();
  const auto v = (*d)->Compute(cloud);
  EXPECT_EQ(v.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(v.status().message(), HasSubstr("all 8 points coincide"));
  EXPECT_THAT(v.status().message(), HasSubstr("after downsampling 20 points to 8"));
}

TEST(CnsdTest, InvalidCloudsAreRejectedWithTheProblemNamed) {
  auto d = CreateDescriptor("cnsd");
  ASSERT_TRUE(d.ok()) << d.status();
  const auto two = (*d)->Compute(PointCloud{{0, 0, 0}, {1, 0, 0}});
  EXPECT_EQ(two.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(two.status().message(), HasSubstr("at least 3"));
  const auto nan = (*d)->Compute(PointCloud{{0, 0, 0}, {1, 0, 0}, {0, std::nanf(""), 0}});
  EXPECT_EQ(nan.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(nan.status().message(), HasSubstr("non-finite"));
  const auto same = (*d)->Compute(PointCloud{{1, 2, 3}, {1, 2, 3}, {1, 2, 3}});
  EXPECT_EQ(same.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(same.status().message(), HasSubstr("identical"));
}

TEST(CnsdTest, InvalidSpecsAreRejectedWithClearMessages) {
  const std::pair<const char*, const char*> cases[] = {
      {"cnsd:t_step=0", "t_step=0 is outside [0.0001, 1]"},
      {"cnsd:t_start=0.9,t_end=0.5", "t_start=0.9 is greater than t_end=0.5"},
      {"cnsd:t_end=1.5", "t_end=1.5 is outside [0, 1]"},
      {"cnsd:max_points=2", "max_points=2 is outside [8, 100000]"},
      {"cnsd:downsample=foo", "downsample=foo is not one of voxel, random"},
      {"cnsd:seed=-1", "seed=-1 is outside"},
      {"cnsd:bogus=1", "cnsd has no parameter \"bogus\""},
  };
  for (const auto& [spec, message] : cases) {
    const auto d = CreateDescriptor(spec);
    EXPECT_EQ(d.status().code(), absl::StatusCode::kInvalidArgument) << spec;
    EXPECT_THAT(d.status().message(), HasSubstr(message)) << spec;
  }
}

TEST(CnsdTest, CanonicalSpecNormalisesNumbersAndRoundTrips) {
  auto d = CreateDescriptor("cnsd:t_start=5e-2,downsample=RANDOM,t_step=0.050");
  ASSERT_TRUE(d.ok()) << d.status();
  EXPECT_EQ((*d)->spec().ToString(),
            "cnsd:t_start=0.05,t_end=0.95,t_step=0.05,max_points=8000,downsample=random,seed=0");
  EXPECT_EQ((*d)->dimension(), 38u);
  auto odd = CreateDescriptor("cnsd:t_start=0.1234567890123,t_end=1,t_step=0.0001");
  ASSERT_TRUE(odd.ok()) << odd.status();
  EXPECT_THAT((*odd)->spec().ToString(), HasSubstr("t_start=0.1234567890123,"));
  EXPECT_EQ((*odd)->dimension(), 2u * 8766);
  auto again = CreateDescriptor((*odd)->spec().ToString());
  ASSERT_TRUE(again.ok()) << again.status();
  EXPECT_EQ((*again)->spec(), (*odd)->spec());
  const std::vector<double> t = ci::Thresholds(0.05, 0.95, 0.05);
  ASSERT_EQ(t.size(), 19u);
  EXPECT_EQ(t.front(), 0.05);
  EXPECT_EQ(t.back(), 0.95);
}

}  // namespace
}  // namespace shapeid
