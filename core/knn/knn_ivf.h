#ifndef SHAPEID_CORE_KNN_KNN_IVF_H_
#define SHAPEID_CORE_KNN_KNN_IVF_H_

// Internal to core/knn: the approximate index of large galleries, inverted lists over
// k-means cells ("IVF-Flat", the scheme of Faiss's IndexIVFFlat), and ApproximateIndex, its
// lifecycle over a growing gallery. KnnIndex owns one; see ApproximateOptions (knn_options.h)
// for when it is used.

#include <atomic>
#include <cstdint>
#include <memory>
#include <vector>

#include "absl/status/status.h"
#include "absl/types/span.h"
#include "core/knn/knn_feature_storage.h"
#include "core/knn/knn_kernels.h"
#include "core/knn/knn_options.h"
#include "core/simd.h"

namespace shapeid {
namespace knn_internal {

// Rows [0, indexed_rows()) of a gallery, partitioned into cells by their nearest centroid,
// each cell's rows copied into their own blocked run (an inverted list), so a query reads
// only the lists of the cells nearest to it, as sequential streams. The gallery's later rows
// (its tail) are not in the lists; KnnIndex scans them exactly.
//
// Exactness: a list scan computes the same distance, bit for bit, as a gallery scan
// (same kernels), and reports gallery row numbers, so what the lists find is ranked and
// tie-broken exactly as brute force would. What is approximate is only which rows are
// looked at: a neighbor in a cell the query did not probe is missed. Probing every list
// is exact.
//
// Immutable once built, so snapshots of a gallery share it; thread-safe for queries.
class InvertedLists {
 public:
  // Clusters rows [0, rows) of `gallery` (rows a multiple of kBlockLanes, at least one
  // block) into min(lists, rows / kMinRowsPerList) cells, in the metric of `scale` (dim
  // factors, or nullptr for raw features), and fills the lists. Deterministic: the same
  // rows give the same lists. Uses up to `threads` threads. Cost: about
  // (kTrainRowsPerList * kIterations + rows) * lists * dim multiply-adds, less what early
  // abandonment saves. nullptr if `cancel` (may be null) turns true meanwhile: it is read
  // between iterations and chunks of rows, so a build stops within a fraction of a second.
  static std::shared_ptr<const InvertedLists> Build(SimdLevel level, const FeatureStorage& gallery,
                                                    int64_t rows, const float* scale, int lists,
                                                    int threads,
                                                    const std::atomic<bool>* cancel = nullptr);

  // The same cells with rows [indexed_rows(), rows) of `gallery` added to their nearest
  // cell's list (rows a multiple of kBlockLanes, >= indexed_rows()). Cost: the new rows
  // times lists * dim, plus a copy of the lists.
  std::shared_ptr<const InvertedLists> Extend(SimdLevel level, const FeatureStorage& gallery,
                                              int64_t rows, const float* scale, int threads) const;

  // The same cells after the gallery dropped rows and closed up, keeping order (`gallery`
  // is the gallery after the removal): new_row_of_old[row] is each old row's new number,
  // or -1 if it was removed. Rows that end up at or past the last whole block of the kept
  // indexed rows leave the lists (and become tail). nullptr if no block of indexed rows is
  // left. Cost: a copy of the lists; no clustering.
  std::shared_ptr<const InvertedLists> Renumber(const FeatureStorage& gallery,
                                                absl::Span<const int64_t> new_row_of_old) const;

  // Gallery rows [0, indexed_rows()) are in the lists; a multiple of kBlockLanes.
  int64_t indexed_rows() const { return indexed_rows_; }
  int num_lists() const { return static_cast<int>(list_size_.size()); }
  int dim() const { return dim_; }
  // The heap of the lists (a copy of every filed row), centroids and row tables. O(1).
  int64_t memory_bytes() const;
  // Rows of each list (tests and benchmarks: how balanced the cells are).
  absl::Span<const int64_t> list_sizes() const { return list_size_; }

  // Offers to `top` the rows of the `probes` lists nearest to each query vector (each list
  // is scanned once, with the query vectors that chose it), with the kernels' exact
  // distances (ScanBlocks), gallery row numbers and query numbers.
  void Search(SimdLevel level, const float* queries, int num_queries, const float* scale,
              int probes, bool abandon, TopK* top) const;

  // Cells get at least this many rows on average: fewer make the centroids noise.
  static constexpr int64_t kMinRowsPerList = 64;
  // Centroids are trained on at most this many rows per cell (Faiss warns below 39).
  static constexpr int64_t kTrainRowsPerList = 64;
  static constexpr int kIterations = 10;

 private:
  InvertedLists() = default;

  // A new, empty set of lists over this one's cells (Extend and Renumber fill it).
  std::shared_ptr<InvertedLists> WithSameCells() const;
  // The nearest centroid of each of `count` row-major vectors.
  void Assign(SimdLevel level, const float* vectors, int64_t count, const float* scale, int threads,
              int32_t* cell) const;
  // Fills the lists from the cells of gallery rows [0, rows).
  void Fill(const FeatureStorage& gallery, int64_t rows, absl::Span<const int32_t> cell_of_row);
  BlockedView Centroids() const { return BlockedView{centroids_.data(), num_centroids_, dim_}; }
  BlockedView List(int list) const;

  int dim_ = 0;
  int64_t num_centroids_ = 0;
  AlignedFloats centroids_;  // blocked, like a gallery: searched with ScanBlocks
  int64_t indexed_rows_ = 0;
  AlignedFloats data_;               // the lists one after another, each block-padded
  std::vector<int64_t> row_ids_;     // gallery row of each stored row (padding: -1)
  std::vector<int64_t> list_start_;  // first stored row of each list; a multiple of 32
  std::vector<int64_t> list_size_;
  std::vector<int32_t> cell_of_row_;  // per indexed gallery row: Extend and Renumber
};

// When a gallery's inverted lists are built, extended, renumbered or dropped, and the lists
// themselves (immutable, shared by copies: copying this is O(1)). Update is O(1) for a gallery
// in step; the steps that cost O(gallery) are an Extend (a copy of the lists, once the rows
// not yet filed pass 1/16 of those filed) and a Build (when the rows have grown 4x).
class ApproximateIndex {
 public:
  // True when Update(options, scaling, ...) would change nothing (or the options are
  // invalid): see KnnIndex::UpdateApproximate for the rules.
  bool InStep(const ApproximateOptions& options, FeatureScaling scaling,
              const FeatureStorage& gallery) const;
  // Brings the lists in step with `gallery` (valid options; `scale` the factors of
  // `scaling`). Cancelled, with nothing changed, if `cancel` turned true during a build.
  absl::Status Update(const ApproximateOptions& options, FeatureScaling scaling,
                      const FeatureStorage& gallery, const float* scale,
                      const std::atomic<bool>* cancel);
  // After the gallery dropped rows (InvertedLists::Renumber).
  void Renumber(const FeatureStorage& gallery, absl::Span<const int64_t> new_row_of_old);

  // Null when searches are exact.
  const InvertedLists* lists() const { return lists_.get(); }
  // Cells a query vector reads.
  int probes() const {
    return options_.probes > 0 ? options_.probes : ApproximateOptions::kDefaultProbes;
  }

 private:
  enum class Step { kNothing, kDrop, kBuild, kExtend };
  Step Plan(const ApproximateOptions& options, FeatureScaling scaling,
            const FeatureStorage& gallery) const;

  // Built with options_.lists and scaling_ over trained_rows_ rows.
  std::shared_ptr<const InvertedLists> lists_;
  ApproximateOptions options_;
  FeatureScaling scaling_ = FeatureScaling::kNone;
  int64_t trained_rows_ = 0;
};

}  // namespace knn_internal
}  // namespace shapeid

#endif  // SHAPEID_CORE_KNN_KNN_IVF_H_
