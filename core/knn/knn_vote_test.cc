#include "core/knn/knn_vote.h"

#include <vector>

#include "gtest/gtest.h"

namespace shapeid {
namespace {

Neighbor N(const char* label, double distance) {
  Neighbor n;
  n.label = label;
  n.distance = distance;
  return n;
}

TEST(VoteTest, UniformTiesGoToTheNearestClass) {
  const std::vector<Neighbor> neighbors = {N("b", 1), N("a", 2), N("a", 3), N("b", 4)};
  KnnResult result;
  Vote(neighbors, VoteWeighting::kUniform, &result);
  EXPECT_EQ(result.label, "b");
  EXPECT_DOUBLE_EQ(result.confidence, 0.5);
  ASSERT_EQ(result.votes.size(), 2u);
  EXPECT_EQ(result.votes[1].label, "a");
  EXPECT_DOUBLE_EQ(result.votes[1].weight, 2.0);
}

TEST(VoteTest, DistanceWeighting) {
  const std::vector<Neighbor> neighbors = {N("b", 1), N("a", 2), N("a", 2)};
  KnnResult result;
  Vote(neighbors, VoteWeighting::kDistance, &result);
  // a: 1/2 + 1/2 = 1 ties b's 1/1: the nearest neighbor's class wins.
  EXPECT_EQ(result.label, "b");
  EXPECT_DOUBLE_EQ(result.confidence, 0.5);
}

TEST(VoteTest, ZeroDistanceNeighborsAloneVote) {
  const std::vector<Neighbor> neighbors = {N("a", 0), N("b", 0), N("b", 0.5), N("c", 1)};
  KnnResult result;
  Vote(neighbors, VoteWeighting::kDistance, &result);
  ASSERT_EQ(result.votes.size(), 3u);
  EXPECT_EQ(result.label, "a");
  EXPECT_DOUBLE_EQ(result.votes[0].weight, 1.0);
  EXPECT_DOUBLE_EQ(result.votes[1].weight, 1.0);
  EXPECT_EQ(result.votes[2].label, "c");
  EXPECT_DOUBLE_EQ(result.votes[2].weight, 0.0);
  EXPECT_DOUBLE_EQ(result.confidence, 0.5);
}

}  // namespace
}  // namespace shapeid
