#ifndef SHAPEID_CORE_KNN_KNN_KD_TREE_H_
#define SHAPEID_CORE_KNN_KNN_KD_TREE_H_

// Internal to core/knn: an exact kd-tree search (nanoflann) for low-dimensional galleries,
// and the lazily filled cache of trees a KnnIndex keeps. nanoflann stays inside
// knn_kd_tree.cc; no exception leaves it.

#include <array>
#include <atomic>
#include <cstdint>
#include <memory>
#include <shared_mutex>
#include <vector>

#include "absl/base/thread_annotations.h"
#include "core/knn/knn_feature_storage.h"
#include "core/knn/knn_kernels.h"
#include "core/knn/knn_options.h"

namespace shapeid {
namespace knn_internal {

// When KnnIndex uses a kd-tree instead of brute force. Medians from bench/knn_bench.cc
// (uniform random data, k = 5, one query, AVX-512 brute force; microseconds):
//
//   d   n      brute  tree        d   n      brute  tree
//   3   5k     1.3    0.6         8   5k     2.1    5.3
//   3   100k   20     1.3         8   100k   42     29
//   6   1k     0.7    1.1         12  100k   62     110
//   6   10k    2.7    2.2         81  100k   610    29000
//   6   100k   28     5.2
//
// The tree wins clearly only for d <= 6 and n of about 10k and more. Building costs about
// as much as 500 brute-force queries (21 ms for 100k x 6, 1.4 ms for 10k x 6), so a tree
// is built only once kKdTreeBuildAfterQueries queries since the last change have asked for
// it (ski rental): a gallery that changes every few queries never pays for a tree it
// would not use, the worst case (a change right after each build) costs about twice the
// brute-force time, and a gallery that keeps serving gets the tree's speed.
inline constexpr int kKdTreeMaxDimension = 6;
inline constexpr int64_t kKdTreeMinSize = 10000;
inline constexpr int64_t kKdTreeBuildAfterQueries = 512;

class KdTree {
 public:
  // A tree over a row-major copy of `rows` whose metric multiplies the difference in
  // dimension j by scale[j] (`scale` has rows.dim() entries; all ones for unscaled). nullptr
  // if nanoflann failed (the caller falls back to brute force).
  static std::unique_ptr<const KdTree> Build(const FeatureStorage& rows, std::vector<float> scale);

  virtual ~KdTree() = default;

  // Offers to `top` every sample that can be among its best k (at least those). Distances
  // are computed exactly as the brute-force kernels compute them (DistanceSq with this
  // tree's scale), so `top` ends with exactly the brute-force answer, ties included.
  // False if nanoflann failed; `top` is then unusable.
  virtual bool Search(const float* query, TopK* top) const = 0;

  // The scale the tree was built with.
  virtual const std::vector<float>& scale() const = 0;
};

// One tree per FeatureScaling, built on demand. Get may be called concurrently; Clear and
// assignment need exclusive access (they run only from KnnIndex mutations). Copies share
// the (immutable) trees.
class TreeCache {
 public:
  TreeCache() = default;
  TreeCache(const TreeCache& other);
  TreeCache& operator=(const TreeCache& other);
  // A move copies (three pointers): the mutex cannot move.
  TreeCache(TreeCache&& other) noexcept : TreeCache(static_cast<const TreeCache&>(other)) {}
  TreeCache& operator=(TreeCache&& other) noexcept {
    return *this = static_cast<const TreeCache&>(other);
  }

  // The tree for `scaling` over `rows`, whose metric uses the rows.dim() factors at `scale`
  // (nullptr: all ones). If it is not built yet: with `force` it is built now; otherwise
  // this call is counted and the tree is built by the kKdTreeBuildAfterQueries-th call
  // since the last Clear, nullptr until then (use brute force). nullptr also if the build
  // failed; the failure is remembered until Clear, so it is not retried per query.
  std::shared_ptr<const KdTree> Get(FeatureScaling scaling, const FeatureStorage& rows,
                                    const float* scale, bool force) const;
  void Clear();

 private:
  struct Slot {
    bool attempted = false;
    std::shared_ptr<const KdTree> tree;
  };
  // std::shared_mutex rather than absl::Mutex: Debian's prebuilt Abseil is not built for
  // ThreadSanitizer, which then cannot see absl::Mutex's ordering; pthread locks it can.
  mutable std::shared_mutex mu_;
  mutable std::array<Slot, 3> slots_ ABSL_GUARDED_BY(mu_);
  // Queries that wanted a tree not built yet, per scaling. Not copied.
  mutable std::array<std::atomic<int64_t>, 3> asked_ = {};
};

}  // namespace knn_internal
}  // namespace shapeid

#endif  // SHAPEID_CORE_KNN_KNN_KD_TREE_H_
