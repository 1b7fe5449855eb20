#ifndef SHAPEID_CORE_KNN_KNN_KERNELS_H_
#define SHAPEID_CORE_KNN_KNN_KERNELS_H_

// Internal to core/knn: the brute-force distance kernels and the bounded best-k set they
// feed. Not part of the kNN API; KnnIndex is.

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <new>
#include <utility>
#include <vector>

#include "core/knn/knn_shared_chunks.h"
#include "core/simd.h"

namespace shapeid {
namespace knn_internal {

// Rows (feature vectors) are stored in blocks of kBlockLanes, dimension-major inside a block:
//   block b = [dim 0: r0 .. r31][dim 1: r0 .. r31] ... [dim d-1: r0 .. r31]
// so one query accumulates 32 distances per block with vertical SIMD only (two AVX-512 or
// four AVX2 registers per dimension, i.e. independent add chains): no horizontal sums, no
// dimension tails, and the gallery is read once, front to back, as one sequential stream.
// (Why 32 and one stream: docs/performance.md, bench/knn_bench.cc.) The last block is zero-padded;
// padding lanes are never reported. Row `row` lives at block row / 32, lane row % 32.
inline constexpr int kBlockLanes = 32;
inline constexpr std::size_t kStorageAlignment = 64;  // one cache line, one zmm load

inline std::size_t BlockFloats(int dim) { return static_cast<std::size_t>(dim) * kBlockLanes; }
inline std::size_t FeatureOffset(int64_t row, int dim, int j) {
  return static_cast<std::size_t>(row / kBlockLanes) * BlockFloats(dim) +
         static_cast<std::size_t>(j) * kBlockLanes + static_cast<std::size_t>(row % kBlockLanes);
}

// Arrays of 2 MiB and more (the approximate index's lists) are aligned to 2 MiB and marked
// for transparent huge pages: on a VM each 4 KiB page's first touch is a costly fault, and
// scans miss the TLB less.
inline constexpr std::size_t kHugePageBytes = std::size_t{2} << 20;

// Asks the kernel for huge pages over [p, p + bytes); a hint, so failure is harmless.
void AdviseHugePages(void* p, std::size_t bytes);

template <typename T>
struct AlignedAllocator {
  using value_type = T;
  AlignedAllocator() = default;
  template <typename U>
  AlignedAllocator(const AlignedAllocator<U>&) {}  // NOLINT: allocator rebinding
  static std::size_t AlignmentFor(std::size_t n) {
    return n * sizeof(T) >= kHugePageBytes ? kHugePageBytes : kStorageAlignment;
  }
  T* allocate(std::size_t n) {
    const std::size_t alignment = AlignmentFor(n);
    void* p = ::operator new(n * sizeof(T), std::align_val_t(alignment));
    if (alignment == kHugePageBytes) AdviseHugePages(p, n * sizeof(T));
    return static_cast<T*>(p);
  }
  void deallocate(T* p, std::size_t n) { ::operator delete(p, std::align_val_t(AlignmentFor(n))); }
  friend bool operator==(const AlignedAllocator&, const AlignedAllocator&) { return true; }
  friend bool operator!=(const AlignedAllocator&, const AlignedAllocator&) { return false; }
};
using AlignedFloats = std::vector<float, AlignedAllocator<float>>;

// A candidate neighbor: squared distance in the scaled space, storage row and the query
// vector that scored it. Candidates are ordered by (distance, row, query): rows of a sample
// are contiguous and samples are stored in insertion order, so among equal distances the
// earlier-added sample wins, and within a sample the earlier view, then the earlier query.
struct Candidate {
  float distance_sq;
  int64_t row;
  int query;
};
inline bool Before(const Candidate& a, const Candidate& b) {
  if (a.distance_sq != b.distance_sq) return a.distance_sq < b.distance_sq;
  if (a.row != b.row) return a.row < b.row;
  return a.query < b.query;
}
// Before as a function object: the heap algorithms inline it, which they do not always
// do through a function pointer.
inline constexpr auto kBefore = [](const Candidate& a, const Candidate& b) { return Before(a, b); };

// The best k candidates seen so far, at most one per group (sample): a max-heap on
// Before, so the current k-th is at the front. A group's entry is its best candidate, so
// many views of one sample, or many queries matching it, take one place, not several.
// Offer accepts candidates in any order (kernels offer one query's rows in increasing
// order, the kd-tree path out of order); the result is the same: the k groups with the
// smallest best candidate, each with that candidate.
class TopK {
 public:
  // (*group_of_row)[row] is the group of each row; nullptr when every row is a group of its
  // own (one view per sample). Then `rows_repeat` says whether a row may be offered more
  // than once (several query vectors): if not, the per-offer search for the row's group is
  // skipped.
  explicit TopK(int k, const SharedChunks<int64_t>* group_of_row = nullptr,
                bool rows_repeat = false)
      : k_(static_cast<std::size_t>(k)),
        group_of_row_(group_of_row),
        grouped_(group_of_row != nullptr || rows_repeat) {
    heap_.reserve(k_);
  }

  bool full() const { return heap_.size() == k_; }
  // Squared distance of the current k-th; meaningful only when full().
  float threshold() const { return heap_.front().distance_sq; }
  // The largest squared distance Offer can still accept: threshold() when full(), +inf
  // before. Kernels skip candidates above it; an equal one may still win on (row, query).
  float limit() const { return full() ? threshold() : std::numeric_limits<float>::infinity(); }

  // O(log k), plus O(k) to find the row's group when there are groups.
  void Offer(float distance_sq, int64_t row, int query = 0);

  // The kept candidates, best first. Leaves the set empty.
  std::vector<Candidate> TakeSorted() {
    std::sort_heap(heap_.begin(), heap_.end(), kBefore);
    return std::move(heap_);
  }

 private:
  // Restores the heap after heap_[i] got better: in a max-heap, it sinks.
  void SiftDown(std::size_t i);

  int64_t GroupOf(int64_t row) const {
    return group_of_row_ != nullptr ? (*group_of_row_)[row] : row;
  }

  std::size_t k_;
  const SharedChunks<int64_t>* group_of_row_;
  bool grouped_;
  std::vector<Candidate> heap_;
};

// A read-only view of blocked storage holding `size` rows of `dim` features. The kernels
// report the view's local row r as row_ids[r] when row_ids is set (an inverted list of the
// approximate index, whose rows are a subset of the gallery's), else as row_base + r (a
// block-aligned slice of the gallery).
struct BlockedView {
  const float* data;  // kStorageAlignment-aligned, ceil(size / kBlockLanes) blocks
  int64_t size;
  int dim;
  int64_t row_base = 0;
  const int64_t* row_ids = nullptr;

  int64_t RowId(int64_t local) const {
    return row_ids != nullptr ? row_ids[local] : row_base + local;
  }
};

// Early abandonment: after kAbandonFirstCheck dimensions of a block, then after twice as
// many, and so on while at least a quarter of the block is left, a kernel drops the block
// for the current query if all 32 partial sums exceed top->limit(): partial sums only
// grow, so no lane of it could be accepted. Exact: the blocks it keeps are summed as
// before. It pays when a prefix of the dimensions holds most of a distance, as in
// descriptors ordered low frequency first (DFSD, DCT coefficients), where most blocks go
// at the first test. It does not test once less than a quarter of the block is left:
// skipping a short tail saves little reading and breaks the sequential stream the
// hardware prefetcher follows (on uniform 100k x 81 features, where blocks go only after
// ~64 dimensions, testing there made scans ~25 % slower). Figures: bench/knn_bench.cc,
// BM_MultiView.
inline constexpr int kAbandonFirstCheck = 16;

// Offers every row of `view` to `top` for each of the `num_queries` query vectors at
// `queries` (dim floats each, one after another), block by block so a block is read from
// memory once for all queries (on 9 views x 240 dims and 9 query vectors, ~1.4x faster
// than a pass per query, although a pass per query abandons against a tighter limit
// sooner). `scale` (dim factors) or nullptr for unscaled features.
// `abandon` false turns off early abandonment (tests and benchmarks compare the two).
// `query_ids`, when set, names query vector q as query_ids[q] in the candidates (the
// approximate index scans a list with only the queries that probed it). The
// squared distance of one row is, in float and in this order:
//   acc = 0; for j in 0..dim-1: { e = query[j] - x[j]; e = e * scale[j]; acc = acc + e * e; }
// at every SIMD level (build uses -ffp-contract=off), so all levels give bit-identical
// distances, nullptr equals a scale of all ones, and abandoning never changes the distance
// of a row it keeps.
void ScanBlocks(SimdLevel level, const BlockedView& view, const float* queries, int num_queries,
                const float* scale, bool abandon, TopK* top, const int* query_ids = nullptr);

// The same squared distance for one row whose feature j is at x[j * stride].
float DistanceSq(const float* query, const float* scale, const float* x, std::ptrdiff_t stride,
                 int dim);

}  // namespace knn_internal
}  // namespace shapeid

#endif  // SHAPEID_CORE_KNN_KNN_KERNELS_H_
