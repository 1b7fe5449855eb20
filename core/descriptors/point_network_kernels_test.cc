#include "core/descriptors/point_network_kernels.h"

#include <cstring>
#include <vector>

#include "Eigen/Core"
#include "core/random.h"
#include "gtest/gtest.h"

namespace shapeid::point_network_internal {
namespace {

struct Case {
  int inputs, units;
  size_t stride;
  std::vector<float> weight, bias, activations;
};

Case RandomCase(int inputs, int units, size_t stride, uint64_t seed) {
  SplitMix64 random(seed);
  const auto draw = [&random] { return static_cast<float>(random.Uniform() * 2 - 1); };
  Case c{inputs, units, stride, {}, {}, {}};
  for (int i = 0; i < inputs * units; ++i) c.weight.push_back(draw());
  for (int u = 0; u < units; ++u) c.bias.push_back(draw() * 0.5f);
  for (size_t i = 0; i < static_cast<size_t>(inputs) * stride; ++i) {
    c.activations.push_back(draw());
  }
  return c;
}

LayerInput InputOf(const Case& c) {
  LayerInput in;
  in.weight = c.weight.data();
  in.bias = c.bias.data();
  in.inputs = c.inputs;
  in.units = c.units;
  in.activations = c.activations.data();
  in.stride = c.stride;
  return in;
}

std::vector<SimdLevel> Levels() {
  std::vector<SimdLevel> levels = {SimdLevel::kScalar};
  if (DetectedSimdLevel() >= SimdLevel::kAvx2) levels.push_back(SimdLevel::kAvx2);
  if (DetectedSimdLevel() >= SimdLevel::kAvx512) levels.push_back(SimdLevel::kAvx512);
  return levels;
}

TEST(PointNetworkKernelsTest, EveryLevelGivesTheSameBitsAsScalar) {
  // Unit counts that are and are not multiples of the kernel's four.
  for (const auto& [inputs, units] : {std::pair{3, 64}, {64, 128}, {7, 5}, {1, 1}, {13, 258}}) {
    for (const size_t stride : {kPointBlock, 3 * kPointBlock}) {
      const Case c = RandomCase(inputs, units, stride, 17 * inputs + units);
      std::vector<float> want(static_cast<size_t>(units) * stride), want_pooled(units);
      DenseReluLayer(InputOf(c), want.data(), want_pooled.data(), SimdLevel::kScalar);
      for (const SimdLevel level : Levels()) {
        std::vector<float> got(want.size(), -1), pooled(units, -1);
        DenseReluLayer(InputOf(c), got.data(), pooled.data(), level);
        EXPECT_EQ(std::memcmp(got.data(), want.data(), want.size() * sizeof(float)), 0)
            << SimdLevelName(level) << " " << inputs << " -> " << units;
        EXPECT_EQ(std::memcmp(pooled.data(), want_pooled.data(), units * sizeof(float)), 0)
            << SimdLevelName(level);
        std::vector<float> pooled_only(units, -1);
        DenseReluLayer(InputOf(c), nullptr, pooled_only.data(), level);
        EXPECT_EQ(pooled_only, pooled) << "pooling without writing the activations";
      }
    }
  }
}

TEST(PointNetworkKernelsTest, ComputesReluOfTheAffineMapAndItsMaximumOverPoints) {
  const Case c = RandomCase(24, 36, 2 * kPointBlock, 5);
  using RowMajor = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
  const RowMajor w =
      Eigen::Map<const Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>(
          c.weight.data(), 36, 24)
          .cast<double>();
  const RowMajor x =
      Eigen::Map<const Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>(
          c.activations.data(), 24, 2 * kPointBlock)
          .cast<double>();
  RowMajor want = w * x;
  for (int u = 0; u < 36; ++u) want.row(u).array() += c.bias[u];
  want = want.cwiseMax(0.0);
  std::vector<float> got(36 * 2 * kPointBlock), pooled(36);
  DenseReluLayer(InputOf(c), got.data(), pooled.data(), ActiveSimdLevel());
  for (int u = 0; u < 36; ++u) {
    for (size_t p = 0; p < 2 * kPointBlock; ++p) {
      EXPECT_NEAR(got[u * 2 * kPointBlock + p], want(u, static_cast<Eigen::Index>(p)), 1e-5);
    }
    EXPECT_NEAR(pooled[u], want.row(u).maxCoeff(), 1e-5);
    EXPECT_GE(pooled[u], 0.0f);
  }
}

}  // namespace
}  // namespace shapeid::point_network_internal
