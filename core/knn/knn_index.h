#ifndef SHAPEID_CORE_KNN_KNN_INDEX_H_
#define SHAPEID_CORE_KNN_KNN_INDEX_H_

#include <algorithm>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "absl/container/flat_hash_map.h"
#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "absl/types/span.h"
#include "core/knn/knn_kernels.h"
#include "core/knn/knn_options.h"
#include "core/simd.h"

namespace shapeid {

namespace knn_internal {
class TreeCache;
}  // namespace knn_internal

struct Neighbor {
  uint64_t id = 0;
  std::string label;
  // Euclidean distance in the scaled feature space. Computed in float (the kernels' sum of
  // squares, see knn_kernels.h), reported as double.
  double distance = 0.0;
};

struct ClassVote {
  std::string label;
  double weight = 0.0;
};

struct KnnResult {
  // The winning class: the most vote weight; among equal weights, the class of the nearest
  // neighbour.
  std::string label;
  // The winner's share of the total vote weight, in (0, 1].
  double confidence = 0.0;
  // min(k, size()) neighbours, nearest first; equal distances in the order the samples were
  // added.
  std::vector<Neighbor> neighbors;
  // One entry per class present among the neighbours, most weight first, ties in the order
  // of each class's nearest neighbour (so votes[0].label == label). Under distance weighting
  // with a zero-distance neighbour, the classes without one appear with weight 0.
  std::vector<ClassVote> votes;
};

// An exact k-nearest-neighbour classifier over a gallery of labelled feature vectors.
//
// Samples are kept raw (unscaled). Feature scaling only multiplies each dimension's
// difference by a factor w_d (the z-score offset cancels in a difference), so a query
// computes sqrt(sum_d ((q_d - x_d) * w_d)^2) directly on raw features. That keeps Add O(d)
// (only running statistics change, never the stored gallery), lets every query pick its
// scaling, and costs one multiply per feature in a loop that is bound by memory bandwidth
// anyway. A scaled copy would make every Add rescale the whole gallery.
//
// Search is brute force over a SIMD-friendly blocked layout (knn_kernels.h), picked at run
// time for the CPU (core/simd.h); every SIMD level gives bit-identical results. For low
// dimensions and large galleries (knn_kd_tree.h: d <= 6, n >= 10k) a kd-tree takes over
// once enough queries have run since the last change to pay for building it; it returns
// exactly what brute force returns, ties included.
//
// Thread safety: const methods may run concurrently from any number of threads. Add, Remove
// and assignment need exclusive access (no concurrent queries); a gallery that must keep
// answering while it changes should mutate a copy and swap it in.
class KnnIndex {
 public:
  // Most features per sample this index accepts.
  static constexpr int kMaxDimension = 1 << 16;

  // An empty index for samples of `dimension` features. InvalidArgument unless
  // 1 <= dimension <= kMaxDimension.
  static absl::StatusOr<KnnIndex> Create(int dimension);

  KnnIndex(const KnnIndex& other);
  KnnIndex& operator=(const KnnIndex& other);
  KnnIndex(KnnIndex&& other) noexcept;
  KnnIndex& operator=(KnnIndex&& other) noexcept;
  ~KnnIndex();

  int dimension() const { return dim_; }
  int64_t size() const { return static_cast<int64_t>(ids_.size()); }
  bool empty() const { return ids_.empty(); }
  bool Contains(uint64_t id) const { return slot_of_id_.contains(id); }
  // Distinct labels currently in the index.
  int num_labels() const { return static_cast<int>(labels_.size()); }

  // The sample in `slot` (0 <= slot < size(), insertion order): what a store or an export
  // needs to rebuild this index bit for bit by Add-ing the slots in order.
  uint64_t IdAt(int64_t slot) const { return ids_[static_cast<size_t>(slot)]; }
  const std::string& LabelAt(int64_t slot) const {
    return labels_[static_cast<size_t>(label_of_slot_[static_cast<size_t>(slot)])];
  }
  // Writes the slot's dimension() features to `out`, which must hold that many.
  void CopyFeatures(int64_t slot, float* out) const {
    for (int j = 0; j < dim_; ++j) out[j] = Feature(slot, j);
  }

  // Appends one sample. Errors, with nothing changed: InvalidArgument if features.size() is
  // not dimension(), a feature is NaN or infinite, or the label is empty; AlreadyExists if
  // the id is present. O(dimension) amortised.
  absl::Status Add(uint64_t id, absl::string_view label, absl::Span<const float> features);

  // Removes the samples with these ids. NotFound (and nothing removed) if any id is absent;
  // duplicates in `ids` are ignored. The remaining samples keep their relative order (which
  // is the tie-break order) and statistics are recomputed exactly, as if the remaining
  // samples had been added in order. O(size() * dimension()) per call, so batch removals.
  absl::Status Remove(absl::Span<const uint64_t> ids);
  absl::Status Remove(uint64_t id) { return Remove(absl::MakeConstSpan(&id, 1)); }

  // The min(k, size()) nearest samples to `query` in the space of `scaling`, nearest first,
  // ties in insertion order. FailedPrecondition if the index is empty; InvalidArgument if
  // k < 1, the query has the wrong dimension or a non-finite feature.
  absl::StatusOr<std::vector<Neighbor>> Search(
      absl::Span<const float> query, int k, FeatureScaling scaling = FeatureScaling::kNone) const;

  // Search with options.k and options.scaling, then the vote of options.weighting. Same
  // errors as Search, plus ValidateKnnOptions.
  absl::StatusOr<KnnResult> Classify(absl::Span<const float> query,
                                     const KnnOptions& options) const;

  // For tests and benchmarks only: Search on a chosen engine and SIMD level (lowered to
  // DetectedSimdLevel() if the CPU lacks it). kKdTree builds its tree at once.
  enum class Engine { kAuto, kBruteForce, kKdTree };
  absl::StatusOr<std::vector<Neighbor>> SearchForTesting(absl::Span<const float> query, int k,
                                                         FeatureScaling scaling, SimdLevel level,
                                                         Engine engine) const {
    return SearchWith(query, k, scaling, std::min(level, DetectedSimdLevel()), engine);
  }

  // The per-dimension factors w_d that `scaling` multiplies feature differences by (all
  // ones for kNone; 1 / std and 1 / max|x| for the others, 1 where those are 0). Empty
  // index: all ones.
  std::vector<float> ScaleFactors(FeatureScaling scaling) const;

 private:
  explicit KnnIndex(int dimension);

  absl::Status ValidateQuery(absl::Span<const float> query, int k) const;
  // Squared distances, best first. Query already validated.
  std::vector<knn_internal::Candidate> FindNearest(absl::Span<const float> query, int k,
                                                   FeatureScaling scaling, SimdLevel level,
                                                   Engine engine) const;
  absl::StatusOr<std::vector<Neighbor>> SearchWith(absl::Span<const float> query, int k,
                                                   FeatureScaling scaling, SimdLevel level,
                                                   Engine engine) const;
  std::vector<Neighbor> ToNeighbors(const std::vector<knn_internal::Candidate>& nearest) const;
  // nullptr for kNone.
  const float* ScaleData(FeatureScaling scaling) const;
  knn_internal::BlockedView View() const {
    return knn_internal::BlockedView{storage_.data(), size(), dim_};
  }
  float Feature(int64_t slot, int j) const {
    return storage_[knn_internal::FeatureOffset(slot, dim_, j)];
  }
  // Folds sample `slot` (the count-th, 1-based) into the running statistics.
  void Accumulate(int64_t slot);
  void RecomputeStatistics();
  void UpdateScaleFactors();

  int dim_;
  knn_internal::AlignedFloats storage_;  // blocked layout, see knn_kernels.h
  std::vector<uint64_t> ids_;            // by slot
  std::vector<int32_t> label_of_slot_;   // index into labels_
  std::vector<std::string> labels_;      // distinct labels, in order of first appearance
  absl::flat_hash_map<std::string, int32_t> label_index_;
  absl::flat_hash_map<uint64_t, int64_t> slot_of_id_;

  // Running statistics per dimension, updated by Add in slot order (Welford, double), and
  // the float factors queries use.
  std::vector<double> mean_;
  std::vector<double> m2_;
  std::vector<float> max_abs_;
  std::vector<float> zscore_scale_;
  std::vector<float> maxabs_scale_;

  // kd-trees built lazily by const queries; dropped by every mutation.
  std::unique_ptr<knn_internal::TreeCache> trees_;
};

}  // namespace shapeid

#endif  // SHAPEID_CORE_KNN_KNN_INDEX_H_
