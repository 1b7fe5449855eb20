#ifndef SHAPEID_CORE_KNN_KNN_VOTE_H_
#define SHAPEID_CORE_KNN_KNN_VOTE_H_

// The result types of a kNN search and the vote that turns neighbors into a class. Outside
// the index: a vote needs only the neighbors.

#include <cstdint>
#include <string>
#include <vector>

#include "absl/types/span.h"
#include "core/knn/knn_options.h"

namespace shapeid {

// One of the nearest samples: the closest (view, query vector) pair decides its distance.
struct Neighbor {
  uint64_t id = 0;
  std::string label;
  // Euclidean distance in the scaled feature space, always finite. Computed in float (the
  // kernels' sum of squares, see knn_kernels.h), reported as double.
  double distance = 0.0;
  // Which of the sample's views and which of the query vectors are that close; among equal
  // distances, the first view, then the first query.
  int view = 0;
  int query = 0;
};

struct ClassVote {
  std::string label;
  double weight = 0.0;
};

struct KnnResult {
  // The winning class: the most vote weight; among equal weights, the class of the nearest
  // neighbor.
  std::string label;
  // The winner's share of the total vote weight, in (0, 1].
  double confidence = 0.0;
  // min(k, size()) distinct samples, nearest first; equal distances in the order the
  // samples were added.
  std::vector<Neighbor> neighbors;
  // One entry per class present among the neighbors, most weight first, ties in the order
  // of each class's nearest neighbor (so votes[0].label == label). Under distance weighting
  // with a zero-distance neighbor, the classes without one appear with weight 0.
  std::vector<ClassVote> votes;
  // True when the search read the index's inverted lists: the neighbors are exact
  // distances, but a nearer sample in a cell that was not probed may be missing.
  bool approximate = false;
};

// The vote of `neighbors` (nearest first, at least one, finite distances) under `weighting`:
// one vote per neighbor (kUniform), or 1 / distance (kDistance; when some neighbor is at
// distance 0, only those vote, one each). Fills result->votes, label and confidence; leaves
// its other fields alone. O(neighbors).
void Vote(absl::Span<const Neighbor> neighbors, VoteWeighting weighting, KnnResult* result);

}  // namespace shapeid

#endif  // SHAPEID_CORE_KNN_KNN_VOTE_H_
