#ifndef SHAPEID_CORE_KNN_KNN_OPTIONS_H_
#define SHAPEID_CORE_KNN_KNN_OPTIONS_H_

#include <cstdint>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"

namespace shapeid {

// How features are rescaled before Euclidean distances are taken (spec section 4). The
// statistics are always those of the gallery the query is run against, never of the query.
enum class FeatureScaling {
  // Raw features. Right when every dimension already has the same unit (one histogram).
  kNone,
  // (x - mean_d) / std_d, population std (ddof = 0) over the gallery; a dimension whose std
  // is 0 is left unscaled (factor 1). Equalises dimensions of different spread; outliers in
  // the gallery shrink a dimension's influence.
  kZScore,
  // x / max_i |x_id| over the gallery; a dimension that is all zeros is left unscaled. The
  // dissertation author's choice; keeps zeros at zero and signs; one outlier rescales a
  // whole dimension.
  kMaxAbs,
};

// How the k neighbors vote for a class.
enum class VoteWeighting {
  // One vote per neighbor.
  kUniform,
  // 1 / distance per neighbor. When any neighbor is at distance exactly 0, only the
  // zero-distance neighbors vote, one vote each (scikit-learn's rule).
  kDistance,
};

struct KnnOptions {
  // Number of neighbors, >= 1. A k larger than the gallery is clamped to the gallery size.
  // k = 1 is the published setting; larger k smooths label noise but blurs small classes.
  int k = 1;
  // Default uniform: with k = 1 both weightings agree; with larger k, kDistance lets a very
  // close neighbor outvote several far ones.
  VoteWeighting weighting = VoteWeighting::kUniform;
  // Default none: descriptors are usually histograms with one unit. Use kMaxAbs to
  // reproduce the author's runs, kZScore when dimensions have unrelated units.
  FeatureScaling scaling = FeatureScaling::kNone;
};

// Approximate search for large galleries: inverted lists over k-means cells (IVF-Flat, the
// scheme of Faiss's IndexIVFFlat; core/knn/knn_ivf.h). A query reads only the `probes`
// cells nearest to it, so its cost is about probes / lists of an exact scan, and it can miss
// a neighbor that lies in a cell it did not probe (recall: docs/performance.md). Distances,
// ranking and votes of what it finds are exact. A server-wide setting, not a gallery's: the
// lists are derived from the stored vectors and rebuilt when a gallery loads.
struct ApproximateOptions {
  // Searches go approximate once an index holds at least this many feature vectors (views
  // of all samples); 0 (the default) keeps every search exact. Below ~10^5 vectors an exact
  // scan takes well under a millisecond and approximation buys nothing.
  int64_t min_vectors = 0;
  // Cells. 0: kDefaultListsPerSqrt * sqrt(vectors), at most kMaxLists; each cell averages
  // at least 64 vectors. More cells make each probe cheaper but the build dearer (its cost
  // grows with vectors x lists).
  int lists = 0;
  // Cells a query vector reads. 0: kDefaultProbes. More probes: better recall, slower.
  int probes = 0;

  // Where a server (and `shapeid eval --local`, which answers as one) turns approximation
  // on: a view-augmented gallery of ~3,000 objects, whose pose-variant queries take ~3 ms
  // to scan exactly and lose nothing at the default probes (docs/performance.md).
  static constexpr int64_t kServedMinVectors = 50'000;
  static constexpr double kDefaultListsPerSqrt = 1.0;
  static constexpr int kMaxLists = 1 << 16;
  static constexpr int kDefaultProbes = 32;
};

// InvalidArgument for a negative field.
absl::Status ValidateApproximateOptions(const ApproximateOptions& options);

// Text forms: "none" | "zscore" | "maxabs" and "uniform" | "distance" (lower case; parsing
// also accepts upper case and surrounding spaces). Unknown names are InvalidArgument and the
// message lists the accepted ones.
absl::StatusOr<FeatureScaling> ParseFeatureScaling(absl::string_view text);
absl::string_view FeatureScalingName(FeatureScaling scaling);
absl::StatusOr<VoteWeighting> ParseVoteWeighting(absl::string_view text);
absl::string_view VoteWeightingName(VoteWeighting weighting);

// InvalidArgument when k < 1 or an enum holds a value outside its enumerators.
absl::Status ValidateKnnOptions(const KnnOptions& options);

}  // namespace shapeid

#endif  // SHAPEID_CORE_KNN_KNN_OPTIONS_H_
