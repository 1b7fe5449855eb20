#include "core/descriptors/point_network.h"

#include <string>
#include <utility>
#include <vector>

#include "absl/status/status.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"

namespace shapeid {
namespace {

using ::testing::HasSubstr;

PointNetwork::Layer LayerOf(std::vector<std::vector<float>> rows, std::vector<float> bias) {
  PointNetwork::Layer layer;
  layer.weight.resize(static_cast<Eigen::Index>(rows.size()),
                      static_cast<Eigen::Index>(rows[0].size()));
  for (size_t r = 0; r < rows.size(); ++r) {
    for (size_t c = 0; c < rows[r].size(); ++c) layer.weight(r, c) = rows[r][c];
  }
  layer.bias = Eigen::Map<Eigen::VectorXf>(bias.data(), static_cast<Eigen::Index>(bias.size()));
  return layer;
}

// 3 -> 2 (x + 1, -y) -> 2 (identity): pooled = (max x + 1, max -y) over points, both >= 0.
PointNetwork Tiny() {
  std::vector<PointNetwork::Layer> layers;
  layers.push_back(LayerOf({{1, 0, 0}, {0, -1, 0}}, {1, 0}));
  layers.push_back(LayerOf({{1, 0}, {0, 1}}, {0, 0}));
  absl::StatusOr<PointNetwork> network =
      PointNetwork::Create("tiny", "# tiny\n", PointNetwork::Frame::kBox, 16, std::move(layers));
  EXPECT_TRUE(network.ok()) << network.status();
  return std::move(*network);
}

TEST(PointNetworkTest, EmbedsTheUnitLengthMaxOverPointsOfTheLastLayer) {
  const PointNetwork network = Tiny();
  Eigen::Matrix3Xf points(3, 3);
  points << 0.5f, -1.0f, 2.0f,  //
      -3.0f, 1.0f, 0.0f,        //
      7.0f, 7.0f, 7.0f;
  std::vector<float> out(2);
  network.Embed(points, out.data());
  // Pooled (3, 3): x + 1 peaks at 3, -y at 3 (ReLU keeps it).
  EXPECT_FLOAT_EQ(out[0], 1 / std::sqrt(2.0f));
  EXPECT_FLOAT_EQ(out[1], 1 / std::sqrt(2.0f));
  EXPECT_EQ(network.dimension(), 2);
  EXPECT_EQ(network.MultiplyAddsPerPoint(), 3 * 2 + 2 * 2);
}

TEST(PointNetworkTest, OrderAndRepeatsOfPointsChangeNothing) {
  const PointNetwork network = Tiny();
  Eigen::Matrix3Xf points(3, 4), shuffled(3, 6);
  points << 0.1f, 0.4f, -0.2f, 0.3f, -0.5f, 0.2f, 0.9f, -0.1f, 0, 0, 0, 0;
  shuffled << points.col(3), points.col(1), points.col(0), points.col(2), points.col(1),
      points.col(3);
  std::vector<float> a(2), b(2);
  network.Embed(points, a.data());
  network.Embed(shuffled, b.data());
  EXPECT_EQ(a, b);
}

TEST(PointNetworkTest, AllUnitsDeadGivesZeroNotNan) {
  std::vector<PointNetwork::Layer> layers;
  layers.push_back(LayerOf({{0, 0, 0}}, {-1}));
  auto network = PointNetwork::Create("dead", "", PointNetwork::Frame::kBox, 4, std::move(layers));
  ASSERT_TRUE(network.ok());
  Eigen::Matrix3Xf points = Eigen::Matrix3Xf::Ones(3, 2);
  float out = -1;
  network->Embed(points, &out);
  EXPECT_EQ(out, 0.0f);
}

TEST(PointNetworkTest, CreateRefusesShapesThatDoNotChainAndOutOfRangeOptions) {
  std::vector<PointNetwork::Layer> unchained;
  unchained.push_back(LayerOf({{1, 0, 0}}, {0}));
  unchained.push_back(LayerOf({{1, 0}}, {0}));  // expects 2 inputs, gets 1
  EXPECT_THAT(PointNetwork::Create("x", "", PointNetwork::Frame::kBox, 8, std::move(unchained))
                  .status()
                  .message(),
              HasSubstr("do not chain"));
  std::vector<PointNetwork::Layer> one;
  one.push_back(LayerOf({{1, 0, 0}}, {0}));
  EXPECT_FALSE(PointNetwork::Create("x", "", PointNetwork::Frame::kBox, 0, one).ok());
  EXPECT_FALSE(PointNetwork::Create("", "", PointNetwork::Frame::kBox, 8, one).ok());
  EXPECT_FALSE(PointNetwork::Create("x", "", static_cast<PointNetwork::Frame>(7), 8, one).ok());
  EXPECT_FALSE(PointNetwork::Create("x", "", PointNetwork::Frame::kBox, 8, {}).ok());
  one[0].weight(0, 0) = std::nanf("");
  EXPECT_FALSE(PointNetwork::Create("x", "", PointNetwork::Frame::kBox, 8, one).ok());
}

TEST(PointNetworkTest, ParseOfSerializeKeepsEveryBit) {
  const PointNetwork network = Tiny();
  const std::string bytes = network.Serialize();
  absl::StatusOr<PointNetwork> parsed = PointNetwork::Parse(bytes);
  ASSERT_TRUE(parsed.ok()) << parsed.status();
  EXPECT_EQ(parsed->Serialize(), bytes);
  EXPECT_EQ(parsed->name(), "tiny");
  EXPECT_EQ(parsed->card(), "# tiny\n");
  EXPECT_EQ(parsed->frame(), PointNetwork::Frame::kBox);
  EXPECT_EQ(parsed->max_points(), 16u);
  ASSERT_EQ(parsed->layers().size(), 2u);
  EXPECT_EQ(parsed->layers()[0].weight, network.layers()[0].weight);
}

TEST(PointNetworkTest, ParseRefusesDamageAsDataLoss) {
  const std::string bytes = Tiny().Serialize();
  const auto expect_data_loss = [](const std::string& b, const std::string& why) {
    const absl::Status status = PointNetwork::Parse(b).status();
    EXPECT_EQ(status.code(), absl::StatusCode::kDataLoss) << why;
    EXPECT_THAT(status.message(), HasSubstr("not a shapeid point network")) << why;
  };
  expect_data_loss("", "empty");
  expect_data_loss("SHPDMLP", "another magic");
  expect_data_loss(bytes.substr(0, bytes.size() - 1), "truncated");
  for (size_t i = 8; i < bytes.size(); i += 7) {
    std::string flipped = bytes;
    flipped[i] ^= 0x10;
    expect_data_loss(flipped, "a flipped bit at byte " + std::to_string(i));
  }
}

}  // namespace
}  // namespace shapeid
