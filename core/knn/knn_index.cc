#include "core/knn/knn_index.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

#include "absl/container/flat_hash_set.h"
#include "absl/strings/str_cat.h"
#include "core/knn/knn_kd_tree.h"
#include "core/status_macros.h"

namespace shapeid {

using knn_internal::BlockFloats;
using knn_internal::Candidate;
using knn_internal::FeatureOffset;
using knn_internal::kBlockLanes;

namespace {

// 1 / v as a float factor in [FLT_MIN, FLT_MAX]: never 0 (0 * inf would make a NaN
// distance) and never inf, whatever the gallery's spread.
float SafeReciprocal(double v) {
  const double r = 1.0 / v;
  return static_cast<float>(std::clamp(r, static_cast<double>(std::numeric_limits<float>::min()),
                                       static_cast<double>(std::numeric_limits<float>::max())));
}

}  // namespace

KnnIndex::KnnIndex(int dimension)
    : dim_(dimension),
      mean_(dimension, 0.0),
      m2_(dimension, 0.0),
      max_abs_(dimension, 0.0f),
      zscore_scale_(dimension, 1.0f),
      maxabs_scale_(dimension, 1.0f),
      trees_(std::make_unique<knn_internal::TreeCache>()) {}

absl::StatusOr<KnnIndex> KnnIndex::Create(int dimension) {
  if (dimension < 1 || dimension > kMaxDimension) {
    return absl::InvalidArgumentError(
        absl::StrCat("kNN index dimension must be in [1, ", kMaxDimension, "], got ", dimension));
  }
  return KnnIndex(dimension);
}

KnnIndex::KnnIndex(const KnnIndex& other)
    : dim_(other.dim_),
      storage_(other.storage_),
      ids_(other.ids_),
      label_of_slot_(other.label_of_slot_),
      labels_(other.labels_),
      label_index_(other.label_index_),
      slot_of_id_(other.slot_of_id_),
      mean_(other.mean_),
      m2_(other.m2_),
      max_abs_(other.max_abs_),
      zscore_scale_(other.zscore_scale_),
      maxabs_scale_(other.maxabs_scale_),
      trees_(std::make_unique<knn_internal::TreeCache>(other.trees_ ? *other.trees_
                                                                    : knn_internal::TreeCache())) {}

KnnIndex& KnnIndex::operator=(const KnnIndex& other) {
  if (this != &other) *this = KnnIndex(other);
  return *this;
}

KnnIndex::KnnIndex(KnnIndex&& other) noexcept = default;
KnnIndex& KnnIndex::operator=(KnnIndex&& other) noexcept = default;
KnnIndex::~KnnIndex() = default;

absl::Status KnnIndex::Add(uint64_t id, absl::string_view label, absl::Span<const float> features) {
  if (features.size() != static_cast<std::size_t>(dim_)) {
    return absl::InvalidArgumentError(
        absl::StrCat("sample ", id, " has ", features.size(), " features; the index holds ", dim_));
  }
  for (std::size_t j = 0; j < features.size(); ++j) {
    if (!std::isfinite(features[j])) {
      return absl::InvalidArgumentError(absl::StrCat("sample ", id, ": feature ", j, " is ",
                                                     features[j], "; features must be finite"));
    }
  }
  if (label.empty()) {
    return absl::InvalidArgumentError(absl::StrCat("sample ", id, " has an empty label"));
  }
  if (slot_of_id_.contains(id)) {
    return absl::AlreadyExistsError(absl::StrCat("sample id ", id, " is already in the index"));
  }

  const int64_t slot = size();
  if (slot % kBlockLanes == 0) storage_.resize(storage_.size() + BlockFloats(dim_), 0.0f);
  for (int j = 0; j < dim_; ++j) storage_[FeatureOffset(slot, dim_, j)] = features[j];

  auto [it, inserted] = label_index_.try_emplace(label, static_cast<int32_t>(labels_.size()));
  if (inserted) labels_.emplace_back(label);
  ids_.push_back(id);
  label_of_slot_.push_back(it->second);
  slot_of_id_.emplace(id, slot);

  Accumulate(slot);
  UpdateScaleFactors();
  if (trees_) trees_->Clear();
  return absl::OkStatus();
}

absl::Status KnnIndex::Remove(absl::Span<const uint64_t> ids) {
  absl::flat_hash_set<int64_t> doomed;
  for (uint64_t id : ids) {
    auto it = slot_of_id_.find(id);
    if (it == slot_of_id_.end()) {
      return absl::NotFoundError(absl::StrCat("sample id ", id, " is not in the index"));
    }
    doomed.insert(it->second);
  }
  if (doomed.empty()) return absl::OkStatus();

  // Compact in place, keeping order; relabel so labels_ holds only labels still in use.
  const int64_t old_size = size();
  std::vector<std::string> old_labels = std::move(labels_);
  labels_.clear();
  label_index_.clear();
  slot_of_id_.clear();
  int64_t dst = 0;
  for (int64_t src = 0; src < old_size; ++src) {
    if (doomed.contains(src)) continue;
    if (dst != src) {
      for (int j = 0; j < dim_; ++j) {
        storage_[FeatureOffset(dst, dim_, j)] = storage_[FeatureOffset(src, dim_, j)];
      }
    }
    const std::string& label = old_labels[static_cast<std::size_t>(label_of_slot_[src])];
    auto [it, inserted] = label_index_.try_emplace(label, static_cast<int32_t>(labels_.size()));
    if (inserted) labels_.push_back(label);
    ids_[dst] = ids_[src];
    label_of_slot_[dst] = it->second;
    slot_of_id_.emplace(ids_[dst], dst);
    ++dst;
  }
  ids_.resize(dst);
  label_of_slot_.resize(dst);
  const int64_t blocks = (dst + kBlockLanes - 1) / kBlockLanes;
  storage_.resize(static_cast<std::size_t>(blocks) * BlockFloats(dim_));
  for (int64_t slot = dst; slot < blocks * kBlockLanes; ++slot) {
    for (int j = 0; j < dim_; ++j) storage_[FeatureOffset(slot, dim_, j)] = 0.0f;
  }

  RecomputeStatistics();
  if (trees_) trees_->Clear();
  return absl::OkStatus();
}

void KnnIndex::Accumulate(int64_t slot) {
  // Welford's update: numerically stable, and recomputing over the same samples in the
  // same order reproduces it bit for bit (Remove relies on that).
  const double count = static_cast<double>(slot + 1);
  for (int j = 0; j < dim_; ++j) {
    const float xf = Feature(slot, j);
    const double x = xf;
    const double delta = x - mean_[j];
    mean_[j] += delta / count;
    m2_[j] += delta * (x - mean_[j]);
    max_abs_[j] = std::max(max_abs_[j], std::fabs(xf));
  }
}

void KnnIndex::RecomputeStatistics() {
  std::fill(mean_.begin(), mean_.end(), 0.0);
  std::fill(m2_.begin(), m2_.end(), 0.0);
  std::fill(max_abs_.begin(), max_abs_.end(), 0.0f);
  for (int64_t slot = 0; slot < size(); ++slot) Accumulate(slot);
  UpdateScaleFactors();
}

void KnnIndex::UpdateScaleFactors() {
  const double n = static_cast<double>(size());
  for (int j = 0; j < dim_; ++j) {
    const double std_dev = n > 0 ? std::sqrt(m2_[j] / n) : 0.0;
    zscore_scale_[j] = std_dev > 0.0 ? SafeReciprocal(std_dev) : 1.0f;
    maxabs_scale_[j] = max_abs_[j] > 0.0f ? SafeReciprocal(max_abs_[j]) : 1.0f;
  }
}

const float* KnnIndex::ScaleData(FeatureScaling scaling) const {
  switch (scaling) {
    case FeatureScaling::kZScore:
      return zscore_scale_.data();
    case FeatureScaling::kMaxAbs:
      return maxabs_scale_.data();
    case FeatureScaling::kNone:
      break;
  }
  return nullptr;
}

std::vector<float> KnnIndex::ScaleFactors(FeatureScaling scaling) const {
  const float* scale = ScaleData(scaling);
  if (scale == nullptr) return std::vector<float>(dim_, 1.0f);
  return std::vector<float>(scale, scale + dim_);
}

absl::Status KnnIndex::ValidateQuery(absl::Span<const float> query, int k) const {
  if (k < 1) return absl::InvalidArgumentError(absl::StrCat("k must be at least 1, got ", k));
  if (query.size() != static_cast<std::size_t>(dim_)) {
    return absl::InvalidArgumentError(
        absl::StrCat("query has ", query.size(), " features; the index holds ", dim_));
  }
  for (std::size_t j = 0; j < query.size(); ++j) {
    if (!std::isfinite(query[j])) {
      return absl::InvalidArgumentError(
          absl::StrCat("query feature ", j, " is ", query[j], "; features must be finite"));
    }
  }
  if (empty()) {
    return absl::FailedPreconditionError("the kNN index is empty; add samples before querying");
  }
  return absl::OkStatus();
}

std::vector<Candidate> KnnIndex::FindNearest(absl::Span<const float> query, int k,
                                             FeatureScaling scaling, SimdLevel level,
                                             Engine engine) const {
  const int kk = static_cast<int>(std::min<int64_t>(k, size()));
  const float* scale = ScaleData(scaling);
  const bool forced_tree = engine == Engine::kKdTree;
  if (engine == Engine::kAuto) {
    engine = dim_ <= knn_internal::kKdTreeMaxDimension && size() >= knn_internal::kKdTreeMinSize
                 ? Engine::kKdTree
                 : Engine::kBruteForce;
  }
  if (engine == Engine::kKdTree && trees_) {
    // Forced (tests) builds now; automatic builds once the tree has paid for itself.
    std::shared_ptr<const knn_internal::KdTree> tree =
        trees_->Get(scaling, View(), scale, /*force=*/forced_tree);
    if (tree) {
      knn_internal::TopK top(kk);
      if (tree->Search(query.data(), &top)) return top.TakeSorted();
    }
    // Not built yet, or nanoflann failed (allocation): brute force gives the same answer.
  }
  knn_internal::TopK top(kk);
  knn_internal::ScanBlocks(level, View(), query.data(), scale, &top);
  return top.TakeSorted();
}

absl::StatusOr<std::vector<Neighbor>> KnnIndex::SearchWith(absl::Span<const float> query, int k,
                                                           FeatureScaling scaling, SimdLevel level,
                                                           Engine engine) const {
  SHAPEID_RETURN_IF_ERROR(ValidateQuery(query, k));
  if (FeatureScalingName(scaling) == "unknown") {
    return absl::InvalidArgumentError(
        absl::StrCat("invalid feature scaling value ", static_cast<int>(scaling)));
  }
  return ToNeighbors(FindNearest(query, k, scaling, level, engine));
}

std::vector<Neighbor> KnnIndex::ToNeighbors(const std::vector<Candidate>& nearest) const {
  std::vector<Neighbor> neighbors;
  neighbors.reserve(nearest.size());
  for (const Candidate& c : nearest) {
    const std::size_t slot = static_cast<std::size_t>(c.slot);
    neighbors.push_back(Neighbor{ids_[slot],
                                 labels_[static_cast<std::size_t>(label_of_slot_[slot])],
                                 std::sqrt(static_cast<double>(c.distance_sq))});
  }
  return neighbors;
}

absl::StatusOr<std::vector<Neighbor>> KnnIndex::Search(absl::Span<const float> query, int k,
                                                       FeatureScaling scaling) const {
  return SearchWith(query, k, scaling, ActiveSimdLevel(), Engine::kAuto);
}

absl::StatusOr<KnnResult> KnnIndex::Classify(absl::Span<const float> query,
                                             const KnnOptions& options) const {
  SHAPEID_RETURN_IF_ERROR(ValidateKnnOptions(options));
  SHAPEID_RETURN_IF_ERROR(ValidateQuery(query, options.k));
  const std::vector<Candidate> nearest =
      FindNearest(query, options.k, options.scaling, ActiveSimdLevel(), Engine::kAuto);

  KnnResult result;
  result.neighbors = ToNeighbors(nearest);
  const bool by_distance = options.weighting == VoteWeighting::kDistance;
  bool any_zero = false;
  for (const Candidate& c : nearest) any_zero = any_zero || c.distance_sq == 0.0f;

  // Weights summed in neighbour order; classes listed in order of their nearest neighbour.
  std::vector<int> vote_of_label(labels_.size(), -1);
  std::vector<int32_t> vote_label;
  std::vector<double> vote_weight;
  for (std::size_t i = 0; i < nearest.size(); ++i) {
    double w = 1.0;
    if (by_distance && any_zero) {
      w = nearest[i].distance_sq == 0.0f ? 1.0 : 0.0;
    } else if (by_distance) {
      w = 1.0 / result.neighbors[i].distance;
    }
    const int32_t label = label_of_slot_[static_cast<std::size_t>(nearest[i].slot)];
    int& v = vote_of_label[static_cast<std::size_t>(label)];
    if (v < 0) {
      v = static_cast<int>(vote_label.size());
      vote_label.push_back(label);
      vote_weight.push_back(0.0);
    }
    vote_weight[static_cast<std::size_t>(v)] += w;
  }
  std::vector<int> order(vote_label.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = static_cast<int>(i);
  // Stable: equal weights keep nearest-neighbour order.
  std::stable_sort(order.begin(), order.end(), [&](int a, int b) {
    return vote_weight[static_cast<std::size_t>(a)] > vote_weight[static_cast<std::size_t>(b)];
  });
  double total = 0.0;
  for (double w : vote_weight) total += w;
  for (int v : order) {
    result.votes.push_back(ClassVote{labels_[static_cast<std::size_t>(vote_label[v])],
                                     vote_weight[static_cast<std::size_t>(v)]});
  }
  result.label = result.votes.front().label;
  // total is 0 only if every neighbour is infinitely far (features near the float limit).
  result.confidence = total > 0.0 ? result.votes.front().weight / total : 1.0;
  return result;
}

}  // namespace shapeid
