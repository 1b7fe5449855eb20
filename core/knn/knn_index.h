#ifndef SHAPEID_CORE_KNN_KNN_INDEX_H_
#define SHAPEID_CORE_KNN_KNN_INDEX_H_

#include <algorithm>
#include <atomic>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "absl/types/span.h"
#include "core/knn/knn_feature_storage.h"
#include "core/knn/knn_ivf.h"
#include "core/knn/knn_kd_tree.h"
#include "core/knn/knn_kernels.h"
#include "core/knn/knn_options.h"
#include "core/knn/knn_sample_table.h"
#include "core/knn/knn_statistics.h"
#include "core/knn/knn_vote.h"
#include "core/simd.h"

namespace shapeid {

// Whether a search may use the index's inverted lists (KnnIndex::UpdateApproximate).
enum class SearchMode {
  // Approximate when the index has lists, else exact.
  kDefault,
  // Always exact, e.g. to measure the lists' recall or for a caller that must not miss.
  kExact,
};

// An exact k-nearest-neighbor classifier over a gallery of labeled samples.
//
// A sample (one id, one label) holds one or more feature vectors, its views: e.g. partial
// scans of one object made at training time. A query may likewise be several vectors (e.g.
// one descriptor under the axis permutations its canonical frame cannot tell apart). The
// distance between a query and a sample is the smallest over all (query vector, view)
// pairs, and the k nearest are k distinct samples, so an object with many views takes one
// place among the neighbors and casts one vote, however many of its views are close.
//
// The index is Faiss's split of one: the feature storage (knn_feature_storage.h), the id
// map and labels (knn_sample_table.h), running statistics (knn_statistics.h), the search
// engines behind one dispatch (brute force in knn_kernels.h, kd-tree in knn_kd_tree.h,
// inverted lists in knn_ivf.h) and the vote (knn_vote.h, a free function). Storage and id map
// live in fixed-size blocks that copies share: copying an index costs O(blocks) pointer
// copies, and Add to a copy copies only the blocks it writes (the last one), so a gallery
// that commits by copying its snapshot and adding to the copy pays O(block), not O(gallery).
//
// Feature vectors are kept raw (unscaled). Feature scaling only multiplies each dimension's
// difference by a factor w_d (the z-score offset cancels in a difference), so a query
// computes sqrt(sum_d ((q_d - x_d) * w_d)^2) directly on raw features. That keeps Add
// O(features added) (only running statistics change, never the stored gallery) and lets
// every query pick its scaling.
//
// Search is brute force over a SIMD-friendly blocked layout (knn_kernels.h), picked at run
// time for the CPU (core/simd.h), with exact early abandonment of blocks that cannot beat
// the current k-th; every SIMD level gives bit-identical results. For low dimensions and
// large galleries of one view per sample (knn_kd_tree.h: d <= 6, n >= 10k) a kd-tree takes
// over for one-vector queries once enough have run since the last change to pay for
// building it; it returns exactly what brute force returns, ties included.
//
// Galleries of a million vectors and more may opt in to approximate search
// (UpdateApproximate): inverted lists over k-means cells (knn_ivf.h) that a query reads
// only in part, with the same kernels and exact distances.
//
// Thread safety: const methods may run concurrently from any number of threads. Add, Remove
// and assignment need exclusive access (no concurrent queries); a gallery that must keep
// answering while it changes should mutate a copy and swap it in.
class KnnIndex {
 public:
  // Most features per view this index accepts.
  static constexpr int kMaxDimension = 1 << 16;
  // Most views per sample, and vectors per query, this index accepts.
  static constexpr int kMaxViews = 1 << 16;
  // Largest |feature| Add and queries accept (real descriptors stay below 2e4), and the least
  // spread (std, max|x|) that scaling divides by (real ones exceed 2e-5): docs/security.md.
  // So |scaled difference| <= 2e8 * 1e8 = 2e16, and a squared distance over kMaxDimension
  // (65536) dimensions <= 65536 * (2e16)^2 = 2.6e37 < FLT_MAX (3.4e38): always finite.
  static constexpr float kMaxFeatureMagnitude = 1e8f;
  static constexpr double kMinScaleSpread = 1e-8;

  // An empty index for samples of `dimension` features. InvalidArgument unless
  // 1 <= dimension <= kMaxDimension.
  static absl::StatusOr<KnnIndex> Create(int dimension);

  // A copy shares every block of the original (O(size() / block) pointer copies); a change
  // to either copies the blocks it writes.
  KnnIndex(const KnnIndex& other) = default;
  KnnIndex& operator=(const KnnIndex& other) = default;
  KnnIndex(KnnIndex&& other) noexcept = default;
  KnnIndex& operator=(KnnIndex&& other) noexcept = default;
  ~KnnIndex() = default;

  // Features per view.
  int dimension() const { return storage_.dim(); }
  // Samples (distinct ids), not views.
  int64_t size() const { return samples_.size(); }
  bool empty() const { return samples_.size() == 0; }
  // Stored feature vectors: the views of all samples.
  int64_t num_rows() const { return storage_.rows(); }
  // An estimate of the heap the index holds: the feature blocks (4 bytes a feature, blocks
  // padded to whole kernel blocks and, at a gallery's end, room to grow), the id map and
  // labels, the statistics and the inverted lists (a second copy of the filed rows), counted
  // whole even where a copy of the index shares them; a kd-tree's cache (d <= 6) left out.
  // O(1): kept as the index changes. About 1 KiB per view of a 240-float descriptor.
  int64_t memory_bytes() const {
    return storage_.memory_bytes() + samples_.memory_bytes() + statistics_.memory_bytes() +
           (approximate_.lists() != nullptr ? approximate_.lists()->memory_bytes() : 0);
  }
  bool Contains(uint64_t id) const { return samples_.Contains(id); }
  // Distinct labels currently in the index.
  int num_labels() const { return samples_.num_labels(); }
  // Samples per distinct label, labels in order of first appearance. O(num_labels()).
  std::vector<std::pair<std::string, int64_t>> LabelCounts() const {
    return samples_.LabelCounts();
  }
  // The ids of the samples labeled `label`, in insertion order; empty if there are none.
  // O(size()): for removals by label, which cost O(size() * dimension()) anyway.
  std::vector<uint64_t> IdsWithLabel(absl::string_view label) const {
    return samples_.IdsWithLabel(label);
  }

  // Samples are numbered 0 .. size() - 1 in insertion order. IdAt, LabelAt and
  // CopyFeatures are what a store or an export needs: Add-ing every sample in order, with
  // CopyFeatures' output as its features, rebuilds this index bit for bit.
  uint64_t IdAt(int64_t sample) const { return samples_.IdAt(sample); }
  const std::string& LabelAt(int64_t sample) const { return samples_.LabelAt(sample); }
  int ViewsAt(int64_t sample) const {
    return static_cast<int>(samples_.FirstRow(sample + 1) - samples_.FirstRow(sample));
  }
  // Writes the sample's ViewsAt(sample) * dimension() features, view after view, to `out`,
  // which must hold that many.
  void CopyFeatures(int64_t sample, float* out) const;
  // The same features in a new vector.
  std::vector<float> Features(int64_t sample) const;

  // Appends one sample whose views are the consecutive dimension()-long runs of
  // `features`. Errors, with nothing changed: InvalidArgument if features.size() is not a
  // positive multiple of dimension() (or is more than kMaxViews views), a feature is NaN,
  // infinite or beyond +-kMaxFeatureMagnitude (the message names the sample, the feature and
  // the bound), or the label is empty; AlreadyExists if the id is present. Every way into a
  // gallery (training, imports, stores' loads, replication) passes here.
  // O(features.size()) plus, on a copy, one block of features and of each per-sample table
  // copied (at most 2 MiB of features and a few tens of KiB of ids and labels).
  absl::Status Add(uint64_t id, absl::string_view label, absl::Span<const float> features);

  // Removes the samples with these ids, every view of each. NotFound (and nothing
  // removed) if any id is absent; duplicates in `ids` are ignored. The remaining samples
  // keep their relative order (which is the tie-break order) and statistics are recomputed
  // exactly, as if the remaining samples had been added in order.
  // O(num_rows() * dimension()) per call, so batch removals: the statistics are recomputed
  // over every row, the blocks from the first removed row on are rewritten (those before it
  // stay shared), and the id map is rebuilt.
  absl::Status Remove(absl::Span<const uint64_t> ids);
  absl::Status Remove(uint64_t id) { return Remove(absl::MakeConstSpan(&id, 1)); }

  // The min(k, size()) nearest distinct samples to `queries` in the space of `scaling`,
  // nearest first. `queries` is one or more query vectors, dimension() floats each, one
  // after another; a sample's distance is the smallest over its views and the query
  // vectors. Ties go to the earlier-added sample (so results equal a naive double loop's).
  // FailedPrecondition if the index is empty; InvalidArgument if k < 1, queries.size() is
  // not a positive multiple of dimension() (or is more than kMaxViews vectors), or a
  // feature is non-finite or beyond +-kMaxFeatureMagnitude. Every distance is finite. A
  // one-vector query on a one-view gallery is the classic kNN.
  // With inverted lists (UpdateApproximate) and SearchMode::kDefault the search is
  // approximate: only the rows of the probed cells, and those added since the lists were
  // last brought up to date, are looked at.
  absl::StatusOr<std::vector<Neighbor>> Search(absl::Span<const float> queries, int k,
                                               FeatureScaling scaling = FeatureScaling::kNone,
                                               SearchMode mode = SearchMode::kDefault) const;

  // Search with options.k and options.scaling, then the vote of options.weighting: one
  // vote per neighboring sample. Same errors as Search, plus ValidateKnnOptions.
  absl::StatusOr<KnnResult> Classify(absl::Span<const float> queries, const KnnOptions& options,
                                     SearchMode mode = SearchMode::kDefault) const;

  // Brings the approximate index in step with the vectors; writers call it after a batch
  // of Add or Remove (queries in between stay correct: rows added since are scanned
  // exactly, and Remove renumbers the lists). What it does:
  //  - drops the lists (all searches exact) when options.min_vectors is 0, the index holds
  //    fewer vectors than that, or dimension() <= 6, where an exact kd-tree serves;
  //  - builds them (k-means, knn_ivf.h) the first time, when options.lists or `scaling`
  //    changed, and when the vectors have grown 4x since the cells were trained;
  //  - else files the vectors added since into the existing cells once they are more
  //    than 1/16 of those already filed (until then they are a tail scanned exactly).
  // `scaling` is the metric the cells are trained in: the gallery's. A build takes seconds
  // at 10^6 vectors (docs/performance.md) and uses every core. InvalidArgument for invalid
  // options, Cancelled if `cancel` (may be null) turned true during a build; either way
  // nothing changed.
  absl::Status UpdateApproximate(const ApproximateOptions& options,
                                 FeatureScaling scaling = FeatureScaling::kNone,
                                 const std::atomic<bool>* cancel = nullptr);
  // True when UpdateApproximate with these arguments would change nothing (or the options
  // are invalid): lets a caller skip copying an index only to find it in step.
  bool ApproximateInStep(const ApproximateOptions& options,
                         FeatureScaling scaling = FeatureScaling::kNone) const;
  // True when searches read inverted lists.
  bool approximate() const { return approximate_.lists() != nullptr; }
  // Cells of the lists and vectors filed in them (0 and 0 without lists): for tests,
  // benchmarks and a server's gallery listing.
  int approximate_lists() const;
  int64_t approximate_filed_vectors() const;

  // For tests and benchmarks only: Search on a chosen engine and SIMD level (lowered to
  // DetectedSimdLevel() if the CPU lacks it), with or without early abandonment. kKdTree
  // builds its tree at once; like kAuto it applies only to one-view galleries and
  // one-vector queries, and falls back to brute force otherwise.
  // kAuto also reads the inverted lists when there are some; kBruteForce never does.
  enum class Engine { kAuto, kBruteForce, kKdTree };
  absl::StatusOr<std::vector<Neighbor>> SearchForTesting(absl::Span<const float> queries, int k,
                                                         FeatureScaling scaling, SimdLevel level,
                                                         Engine engine,
                                                         bool early_abandon = true) const {
    return SearchWith(queries, k, scaling, std::min(level, DetectedSimdLevel()), engine,
                      early_abandon);
  }

  // The per-dimension factors w_d that `scaling` multiplies feature differences by (all
  // ones for kNone; 1 / std and 1 / max|x| for the others, 1 where those are 0, and
  // 1 / kMinScaleSpread where they are below kMinScaleSpread: rounding noise, not a scale). The
  // statistics count every view of every sample as one observation, so a sample with more
  // views weighs more; with one view per sample they are the per-sample statistics.
  // Empty index: all ones.
  std::vector<float> ScaleFactors(FeatureScaling scaling) const;

  // For tests: the feature blocks, to see what two copies share.
  const knn_internal::FeatureStorage& StorageForTesting() const { return storage_; }

 private:
  explicit KnnIndex(int dimension);

  absl::Status ValidateQuery(absl::Span<const float> queries, int k) const;
  // The engine dispatch: the nearest distinct samples' best (squared distance, row, query),
  // best first. Queries already validated. Sets *approximate (if not null) when the lists
  // were read.
  std::vector<knn_internal::Candidate> FindNearest(absl::Span<const float> queries, int k,
                                                   FeatureScaling scaling, SimdLevel level,
                                                   Engine engine, bool early_abandon,
                                                   SearchMode mode = SearchMode::kDefault,
                                                   bool* approximate = nullptr) const;
  absl::StatusOr<std::vector<Neighbor>> SearchWith(absl::Span<const float> queries, int k,
                                                   FeatureScaling scaling, SimdLevel level,
                                                   Engine engine, bool early_abandon,
                                                   SearchMode mode = SearchMode::kDefault) const;
  std::vector<Neighbor> ToNeighbors(const std::vector<knn_internal::Candidate>& nearest) const;

  // Rows in the blocked layout, see knn_kernels.h.
  knn_internal::FeatureStorage storage_;
  // Ids, labels and the rows of each sample.
  knn_internal::SampleTable samples_;
  // Over every row in order, as Add saw them.
  knn_internal::RunningStatistics statistics_;
  // kd-trees built lazily by const queries; dropped by every mutation, shared by copies.
  knn_internal::TreeCache trees_;
  // Inverted lists (UpdateApproximate); shared by copies.
  knn_internal::ApproximateIndex approximate_;
};

}  // namespace shapeid

#endif  // SHAPEID_CORE_KNN_KNN_INDEX_H_
