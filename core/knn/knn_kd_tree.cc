#include "core/knn/knn_kd_tree.h"

#include <cstddef>
#include <exception>
#include <limits>
#include <mutex>
#include <shared_mutex>
#include <utility>

#include "nanoflann.hpp"

namespace shapeid {
namespace knn_internal {
namespace {

// nanoflann reads points through this adaptor; the rows are owned by the tree.
struct RowsAdaptor {
  const float* rows = nullptr;
  std::size_t n = 0;
  int dim = 0;

  std::size_t kdtree_get_point_count() const { return n; }
  float kdtree_get_pt(std::size_t i, std::size_t j) const {
    return rows[i * static_cast<std::size_t>(dim) + j];
  }
  template <class BBox>
  bool kdtree_get_bbox(BBox&) const {
    return false;
  }
};

// Scaled Euclidean metric. Leaf distances are the brute-force kernels' float sums
// (DistanceSq), so accepted candidates carry bit-identical distances. Node bounds are
// computed in double; they can differ from a float distance by its rounding (at most about
// (dim + 5) * 2^-24 relative, plus underflow), so the result set below widens its
// threshold by more than that before nanoflann prunes with it. Pruning is therefore
// conservative: a node is skipped only if nothing in it can tie or beat the k-th.
struct ScaledL2 {
  using ElementType = float;
  using DistanceType = double;

  const RowsAdaptor& data;
  const float* scale;

  ScaledL2(const RowsAdaptor& adaptor, const float* s) : data(adaptor), scale(s) {}

  template <typename Accessor>
  double evalMetric(const float* a, Accessor b, std::size_t size) const {
    return DistanceSq(a, scale, data.rows + static_cast<std::size_t>(b) * data.dim, 1,
                      static_cast<int>(size));
  }
  template <typename U, typename V>
  double accum_dist(const U a, const V b, std::size_t j) const {
    const double e = (static_cast<double>(a) - static_cast<double>(b)) * scale[j];
    return e * e;
  }
};

// Feeds nanoflann's candidates to TopK, which orders them by (distance, slot): nanoflann
// visits leaves out of slot order, and its own result set would drop a tie with a lower
// slot found after the k-th was filled.
class TopKResultSet {
 public:
  using DistanceType = double;

  explicit TopKResultSet(TopK* top) : top_(top) {}

  bool full() const { return top_->full(); }
  std::size_t size() const { return 0; }  // unused by findNeighbors' callers here
  DistanceType worstDist() const {
    if (!top_->full()) return std::numeric_limits<double>::max();
    return static_cast<double>(top_->threshold()) * (1.0 + kRelativeSlack) + kAbsoluteSlack;
  }
  bool addPoint(DistanceType dist, uint32_t index) {
    // dist holds a float exactly (evalMetric); narrowing is lossless.
    const float d = static_cast<float>(dist);
    if (!top_->full() || !(d > top_->threshold())) top_->Offer(d, index);
    return true;
  }

 private:
  // Float rounding of the sum is below (dim + 5) * 2^-24 relative: 4e-7 at the automatic
  // limit of 6 dimensions, 1e-4 only past 1600 (tests force trees up to 100). 1e-4 costs a
  // few extra distance computations near the k-th. The absolute term covers terms that
  // underflow to zero in float but not in double.
  static constexpr double kRelativeSlack = 1e-4;
  static constexpr double kAbsoluteSlack = 1e-30;
  TopK* top_;
};

using Tree = nanoflann::KDTreeSingleIndexAdaptor<ScaledL2, RowsAdaptor, -1, uint32_t>;

class NanoflannKdTree final : public KdTree {
 public:
  NanoflannKdTree(std::vector<float> rows, std::size_t n, int dim, std::vector<float> scale)
      : rows_(std::move(rows)), scale_(std::move(scale)) {
    adaptor_.rows = rows_.data();
    adaptor_.n = n;
    adaptor_.dim = dim;
    tree_ = std::make_unique<Tree>(
        dim, adaptor_, nanoflann::KDTreeSingleIndexAdaptorParams(kLeafSize), scale_.data());
  }

  bool Search(const float* query, TopK* top) const override {
    try {
      TopKResultSet result(top);
      tree_->findNeighbors(result, query, nanoflann::SearchParams());
      return true;
    } catch (const std::exception&) {
      return false;
    }
  }

  const std::vector<float>& scale() const override { return scale_; }

 private:
  static constexpr std::size_t kLeafSize = 16;
  std::vector<float> rows_;
  std::vector<float> scale_;
  RowsAdaptor adaptor_;
  std::unique_ptr<Tree> tree_;  // refers to adaptor_ and scale_; declared last
};

}  // namespace

std::unique_ptr<const KdTree> KdTree::Build(const FeatureStorage& storage,
                                            std::vector<float> scale) {
  if (storage.rows() <= 0 || storage.rows() > std::numeric_limits<uint32_t>::max()) return nullptr;
  try {
    const std::size_t n = static_cast<std::size_t>(storage.rows());
    const std::size_t dim = static_cast<std::size_t>(storage.dim());
    std::vector<float> rows(n * dim);
    for (std::size_t i = 0; i < n; ++i) storage.CopyRow(static_cast<int64_t>(i), &rows[i * dim]);
    return std::make_unique<NanoflannKdTree>(std::move(rows), n, storage.dim(), std::move(scale));
  } catch (const std::exception&) {
    return nullptr;
  }
}

TreeCache::TreeCache(const TreeCache& other) {
  std::shared_lock lock(other.mu_);
  slots_ = other.slots_;
}

TreeCache& TreeCache::operator=(const TreeCache& other) {
  if (this == &other) return *this;
  std::array<Slot, 3> copy;
  {
    std::shared_lock lock(other.mu_);
    copy = other.slots_;
  }
  std::unique_lock lock(mu_);
  slots_ = std::move(copy);
  return *this;
}

std::shared_ptr<const KdTree> TreeCache::Get(FeatureScaling scaling, const FeatureStorage& rows,
                                             const float* scale, bool force) const {
  const std::size_t i = static_cast<std::size_t>(scaling);
  {
    std::shared_lock lock(mu_);
    if (slots_[i].attempted) return slots_[i].tree;
  }
  if (!force && asked_[i].fetch_add(1, std::memory_order_relaxed) + 1 < kKdTreeBuildAfterQueries) {
    return nullptr;
  }
  std::unique_lock lock(mu_);
  Slot& slot = slots_[i];
  if (!slot.attempted) {
    // Built under the lock: concurrent queries wait for one build instead of each building
    // their own.
    std::vector<float> factors(static_cast<std::size_t>(rows.dim()), 1.0f);
    if (scale != nullptr) factors.assign(scale, scale + rows.dim());
    slot.tree = KdTree::Build(rows, std::move(factors));
    slot.attempted = true;
  }
  return slot.tree;
}

void TreeCache::Clear() {
  std::unique_lock lock(mu_);
  slots_ = {};
  for (auto& a : asked_) a.store(0, std::memory_order_relaxed);
}

}  // namespace knn_internal
}  // namespace shapeid
