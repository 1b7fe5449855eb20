#include "core/knn/knn_vote.h"

#include <algorithm>
#include <cstddef>

#include "absl/container/flat_hash_map.h"
#include "absl/strings/string_view.h"

namespace shapeid {

void Vote(absl::Span<const Neighbor> neighbors, VoteWeighting weighting, KnnResult* result) {
  const bool by_distance = weighting == VoteWeighting::kDistance;
  bool any_zero = false;
  for (const Neighbor& n : neighbors) any_zero = any_zero || n.distance == 0.0;

  // Weights summed in neighbor order; classes listed in order of their nearest neighbor.
  absl::flat_hash_map<absl::string_view, std::size_t> vote_of_label;
  std::vector<absl::string_view> vote_label;
  std::vector<double> vote_weight;
  for (const Neighbor& n : neighbors) {
    double w = 1.0;
    if (by_distance && any_zero) {
      w = n.distance == 0.0 ? 1.0 : 0.0;
    } else if (by_distance) {
      w = 1.0 / n.distance;
    }
    const auto [it, inserted] = vote_of_label.try_emplace(n.label, vote_label.size());
    if (inserted) {
      vote_label.push_back(n.label);
      vote_weight.push_back(0.0);
    }
    vote_weight[it->second] += w;
  }
  std::vector<std::size_t> order(vote_label.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
  // Stable: equal weights keep nearest-neighbor order.
  std::stable_sort(order.begin(), order.end(),
                   [&](std::size_t a, std::size_t b) { return vote_weight[a] > vote_weight[b]; });
  double total = 0.0;
  for (double w : vote_weight) total += w;
  result->votes.clear();
  for (std::size_t v : order) {
    result->votes.push_back(ClassVote{std::string(vote_label[v]), vote_weight[v]});
  }
  result->label = result->votes.empty() ? std::string() : result->votes.front().label;
  // Distances are finite, so the winner's weight is positive (1, or 1 / distance): total > 0
  // and the share is in (0, 1]. The 1.0 only guards the division.
  result->confidence =
      total > 0.0 && !result->votes.empty() ? result->votes.front().weight / total : 1.0;
}

}  // namespace shapeid
