#include "core/knn/knn_index.h"

#include <algorithm>
#include <cmath>
#include <thread>
#include <utility>

#include "absl/container/flat_hash_set.h"
#include "absl/strings/str_cat.h"
#include "core/knn/knn_ivf.h"
#include "core/knn/knn_kd_tree.h"
#include "core/status_macros.h"

namespace shapeid {

using knn_internal::BlockFloats;
using knn_internal::Candidate;
using knn_internal::FeatureOffset;
using knn_internal::kBlockLanes;

namespace {

// The scale factor for a spread > 0: 1 / spread, but at most 1 / kMinScaleSpread, which
// keeps every scaled distance finite (knn_index.h). A spread is at most
// kMaxFeatureMagnitude, so the factor is never 0 (0 * a large difference would hide it).
float ScaleFactor(double spread) {
  return static_cast<float>(1.0 / std::max(spread, KnnIndex::kMinScaleSpread));
}

// Finite and within +-kMaxFeatureMagnitude (false for NaN).
bool InBound(float value) { return std::fabs(value) <= KnnIndex::kMaxFeatureMagnitude; }

absl::Status OutOfBound(absl::string_view what, float value) {
  return absl::InvalidArgumentError(absl::StrCat(what, " is ", value,
                                                 "; features must be finite and within +-",
                                                 KnnIndex::kMaxFeatureMagnitude));
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
      label_of_sample_(other.label_of_sample_),
      num_rows_(other.num_rows_),
      first_row_(other.first_row_),
      sample_of_row_(other.sample_of_row_),
      labels_(other.labels_),
      label_counts_(other.label_counts_),
      label_index_(other.label_index_),
      sample_of_id_(other.sample_of_id_),
      mean_(other.mean_),
      m2_(other.m2_),
      max_abs_(other.max_abs_),
      zscore_scale_(other.zscore_scale_),
      maxabs_scale_(other.maxabs_scale_),
      trees_(std::make_unique<knn_internal::TreeCache>(other.trees_ ? *other.trees_
                                                                    : knn_internal::TreeCache())),
      lists_(other.lists_),
      lists_options_(other.lists_options_),
      lists_scaling_(other.lists_scaling_),
      lists_trained_rows_(other.lists_trained_rows_) {}

KnnIndex& KnnIndex::operator=(const KnnIndex& other) {
  if (this != &other) *this = KnnIndex(other);
  return *this;
}

KnnIndex::KnnIndex(KnnIndex&& other) noexcept = default;
KnnIndex& KnnIndex::operator=(KnnIndex&& other) noexcept = default;
KnnIndex::~KnnIndex() = default;

void KnnIndex::CopyFeatures(int64_t sample, float* out) const {
  for (int64_t row = FirstRow(sample); row < FirstRow(sample + 1); ++row) {
    for (int j = 0; j < dim_; ++j) *out++ = Feature(row, j);
  }
}

std::vector<std::pair<std::string, int64_t>> KnnIndex::LabelCounts() const {
  std::vector<std::pair<std::string, int64_t>> counts;
  counts.reserve(labels_.size());
  for (std::size_t l = 0; l < labels_.size(); ++l) counts.emplace_back(labels_[l], label_counts_[l]);
  return counts;
}

std::vector<uint64_t> KnnIndex::IdsWithLabel(absl::string_view label) const {
  std::vector<uint64_t> ids;
  const auto it = label_index_.find(label);
  if (it == label_index_.end()) return ids;
  ids.reserve(static_cast<std::size_t>(label_counts_[static_cast<std::size_t>(it->second)]));
  for (std::size_t s = 0; s < ids_.size(); ++s) {
    if (label_of_sample_[s] == it->second) ids.push_back(ids_[s]);
  }
  return ids;
}

std::vector<float> KnnIndex::Features(int64_t sample) const {
  std::vector<float> features(static_cast<std::size_t>(ViewsAt(sample)) *
                              static_cast<std::size_t>(dim_));
  CopyFeatures(sample, features.data());
  return features;
}

absl::Status KnnIndex::Add(uint64_t id, absl::string_view label, absl::Span<const float> features) {
  const std::size_t dim = static_cast<std::size_t>(dim_);
  if (features.empty() || features.size() % dim != 0) {
    return absl::InvalidArgumentError(
        absl::StrCat("sample ", id, ": features.size() ", features.size(),
                     " is not a positive multiple of the dimension ", dim_));
  }
  const std::size_t views = features.size() / dim;
  if (views > static_cast<std::size_t>(kMaxViews)) {
    return absl::InvalidArgumentError(
        absl::StrCat("sample ", id, " has ", views, " views; at most ", kMaxViews, " are allowed"));
  }
  for (std::size_t i = 0; i < features.size(); ++i) {
    if (!InBound(features[i])) {
      return OutOfBound(
          absl::StrCat("sample ", id, ": ", views > 1 ? absl::StrCat("view ", i / dim, " ") : "",
                       "feature ", i % dim),
          features[i]);
    }
  }
  if (label.empty()) {
    return absl::InvalidArgumentError(absl::StrCat("sample ", id, " has an empty label"));
  }
  if (sample_of_id_.contains(id)) {
    return absl::AlreadyExistsError(absl::StrCat("sample id ", id, " is already in the index"));
  }

  const int64_t sample = size();
  const int64_t first_row = num_rows();
  if (views > 1 && first_row_.empty()) {
    // The first sample with several views: rows and samples part ways from here on.
    first_row_.resize(static_cast<std::size_t>(sample) + 1);
    sample_of_row_.resize(static_cast<std::size_t>(first_row));
    for (int64_t s = 0; s <= sample; ++s) first_row_[static_cast<std::size_t>(s)] = s;
    for (int64_t row = 0; row < first_row; ++row) sample_of_row_[static_cast<std::size_t>(row)] = row;
  }
  for (std::size_t v = 0; v < views; ++v) {
    const int64_t row = first_row + static_cast<int64_t>(v);
    if (row % kBlockLanes == 0) storage_.resize(storage_.size() + BlockFloats(dim_), 0.0f);
    for (int j = 0; j < dim_; ++j) storage_[FeatureOffset(row, dim_, j)] = features[v * dim + j];
    if (!first_row_.empty()) sample_of_row_.push_back(sample);
    num_rows_ = row + 1;
    Accumulate(row);
  }
  if (!first_row_.empty()) first_row_.push_back(num_rows_);

  auto [it, inserted] = label_index_.try_emplace(label, static_cast<int32_t>(labels_.size()));
  if (inserted) {
    labels_.emplace_back(label);
    label_counts_.push_back(0);
  }
  ++label_counts_[static_cast<std::size_t>(it->second)];
  ids_.push_back(id);
  label_of_sample_.push_back(it->second);
  sample_of_id_.emplace(id, sample);

  UpdateScaleFactors();
  if (trees_) trees_->Clear();
  return absl::OkStatus();
}

absl::Status KnnIndex::Remove(absl::Span<const uint64_t> ids) {
  absl::flat_hash_set<int64_t> doomed;
  for (uint64_t id : ids) {
    auto it = sample_of_id_.find(id);
    if (it == sample_of_id_.end()) {
      return absl::NotFoundError(absl::StrCat("sample id ", id, " is not in the index"));
    }
    doomed.insert(it->second);
  }
  if (doomed.empty()) return absl::OkStatus();

  // Compact in place, keeping order; relabel so labels_ holds only labels still in use.
  const int64_t old_size = size();
  std::vector<std::string> old_labels = std::move(labels_);
  const std::vector<int64_t> old_first_row = std::move(first_row_);
  auto old_first = [&old_first_row](int64_t s) {
    return old_first_row.empty() ? s : old_first_row[static_cast<std::size_t>(s)];
  };
  labels_.clear();
  label_counts_.clear();
  label_index_.clear();
  sample_of_id_.clear();
  std::vector<int64_t> first_row = {0};
  std::vector<int64_t> sample_of_row;
  bool several_views = false;
  // Only the inverted lists need to know where each row went.
  std::vector<int64_t> new_row_of_old(lists_ ? static_cast<std::size_t>(num_rows_) : 0, -1);
  int64_t dst = 0;
  int64_t dst_row = 0;
  for (int64_t src = 0; src < old_size; ++src) {
    if (doomed.contains(src)) continue;
    several_views = several_views || old_first(src + 1) - old_first(src) > 1;
    for (int64_t row = old_first(src); row < old_first(src + 1); ++row, ++dst_row) {
      if (lists_) new_row_of_old[static_cast<std::size_t>(row)] = dst_row;
      if (dst_row != row) {
        for (int j = 0; j < dim_; ++j) {
          storage_[FeatureOffset(dst_row, dim_, j)] = storage_[FeatureOffset(row, dim_, j)];
        }
      }
      sample_of_row.push_back(dst);
    }
    const std::string& label = old_labels[static_cast<std::size_t>(label_of_sample_[src])];
    auto [it, inserted] = label_index_.try_emplace(label, static_cast<int32_t>(labels_.size()));
    if (inserted) {
      labels_.push_back(label);
      label_counts_.push_back(0);
    }
    ++label_counts_[static_cast<std::size_t>(it->second)];
    ids_[dst] = ids_[src];
    label_of_sample_[dst] = it->second;
    sample_of_id_.emplace(ids_[dst], dst);
    first_row.push_back(dst_row);
    ++dst;
  }
  num_rows_ = dst_row;
  // Back to the identity maps when every remaining sample has one view.
  first_row_ = several_views ? std::move(first_row) : std::vector<int64_t>();
  sample_of_row_ = several_views ? std::move(sample_of_row) : std::vector<int64_t>();
  ids_.resize(dst);
  label_of_sample_.resize(dst);
  const int64_t blocks = (dst_row + kBlockLanes - 1) / kBlockLanes;
  storage_.resize(static_cast<std::size_t>(blocks) * BlockFloats(dim_));
  for (int64_t row = dst_row; row < blocks * kBlockLanes; ++row) {
    for (int j = 0; j < dim_; ++j) storage_[FeatureOffset(row, dim_, j)] = 0.0f;
  }

  RecomputeStatistics();
  if (trees_) trees_->Clear();
  if (lists_) lists_ = lists_->Renumber(View(), new_row_of_old);
  return absl::OkStatus();
}

KnnIndex::ApproximateStep KnnIndex::PlanApproximate(const ApproximateOptions& options,
                                                    FeatureScaling scaling) const {
  const int64_t whole_blocks = WholeBlockRows();
  if (options.min_vectors == 0 || num_rows() < options.min_vectors ||
      dim_ <= knn_internal::kKdTreeMaxDimension || whole_blocks == 0) {
    return lists_ != nullptr ? ApproximateStep::kDrop : ApproximateStep::kNothing;
  }
  if (lists_ == nullptr || options.lists != lists_options_.lists || scaling != lists_scaling_ ||
      whole_blocks >= 4 * lists_trained_rows_) {
    return ApproximateStep::kBuild;
  }
  if (whole_blocks - lists_->indexed_rows() > lists_->indexed_rows() / 16) {
    return ApproximateStep::kExtend;
  }
  return ApproximateStep::kNothing;
}

bool KnnIndex::ApproximateInStep(const ApproximateOptions& options, FeatureScaling scaling) const {
  if (!ValidateApproximateOptions(options).ok() || FeatureScalingName(scaling) == "unknown") {
    return true;
  }
  // Probes only change how the lists are read.
  return PlanApproximate(options, scaling) == ApproximateStep::kNothing &&
         (lists_ == nullptr || options.probes == lists_options_.probes);
}

absl::Status KnnIndex::UpdateApproximate(const ApproximateOptions& options,
                                         FeatureScaling scaling,
                                         const std::atomic<bool>* cancel) {
  SHAPEID_RETURN_IF_ERROR(ValidateApproximateOptions(options));
  if (FeatureScalingName(scaling) == "unknown") {
    return absl::InvalidArgumentError(
        absl::StrCat("invalid feature scaling value ", static_cast<int>(scaling)));
  }
  const int64_t whole_blocks = WholeBlockRows();
  const int threads = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  const float* scale = ScaleData(scaling);
  switch (PlanApproximate(options, scaling)) {
    case ApproximateStep::kNothing:
      break;
    case ApproximateStep::kDrop:
      lists_.reset();
      break;
    case ApproximateStep::kBuild: {
      const int lists =
          options.lists > 0
              ? options.lists
              : static_cast<int>(std::clamp<double>(
                    std::round(ApproximateOptions::kDefaultListsPerSqrt *
                               std::sqrt(static_cast<double>(num_rows()))),
                    1.0, ApproximateOptions::kMaxLists));
      auto built = knn_internal::InvertedLists::Build(ActiveSimdLevel(), View(), whole_blocks,
                                                      scale, lists, threads, cancel);
      if (built == nullptr) return absl::CancelledError("approximate index build cancelled");
      lists_ = std::move(built);
      lists_trained_rows_ = whole_blocks;
      lists_scaling_ = scaling;
      break;
    }
    case ApproximateStep::kExtend:
      lists_ = lists_->Extend(ActiveSimdLevel(), View(), whole_blocks, scale, threads);
      break;
  }
  lists_options_ = options;
  return absl::OkStatus();
}

int KnnIndex::approximate_lists() const { return lists_ ? lists_->num_lists() : 0; }

int64_t KnnIndex::approximate_filed_vectors() const {
  return lists_ ? lists_->indexed_rows() : 0;
}

void KnnIndex::Accumulate(int64_t row) {
  // Welford's update: numerically stable, and recomputing over the same rows in the same
  // order reproduces it bit for bit (Remove relies on that).
  const double count = static_cast<double>(row + 1);
  for (int j = 0; j < dim_; ++j) {
    const float xf = Feature(row, j);
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
  for (int64_t row = 0; row < num_rows(); ++row) Accumulate(row);
  UpdateScaleFactors();
}

void KnnIndex::UpdateScaleFactors() {
  const double n = static_cast<double>(num_rows());
  for (int j = 0; j < dim_; ++j) {
    const double std_dev = n > 0 ? std::sqrt(m2_[j] / n) : 0.0;
    zscore_scale_[j] = std_dev > 0.0 ? ScaleFactor(std_dev) : 1.0f;
    maxabs_scale_[j] = max_abs_[j] > 0.0f ? ScaleFactor(max_abs_[j]) : 1.0f;
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

absl::Status KnnIndex::ValidateQuery(absl::Span<const float> queries, int k) const {
  if (k < 1) return absl::InvalidArgumentError(absl::StrCat("k must be at least 1, got ", k));
  const std::size_t dim = static_cast<std::size_t>(dim_);
  if (queries.empty() || queries.size() % dim != 0) {
    return absl::InvalidArgumentError(absl::StrCat("query has ", queries.size(),
                                                   " features, not a positive multiple of the ",
                                                   "dimension ", dim_));
  }
  // The kernels count query vectors in an int.
  if (queries.size() / dim > static_cast<std::size_t>(kMaxViews)) {
    return absl::InvalidArgumentError(absl::StrCat(
        "query has ", queries.size() / dim, " vectors; at most ", kMaxViews, " are allowed"));
  }
  for (std::size_t i = 0; i < queries.size(); ++i) {
    if (!InBound(queries[i])) {
      return OutOfBound(
          absl::StrCat("query ", queries.size() > dim ? absl::StrCat("vector ", i / dim, " ") : "",
                       "feature ", i % dim),
          queries[i]);
    }
  }
  if (empty()) {
    return absl::FailedPreconditionError("the kNN index is empty; add samples before querying");
  }
  return absl::OkStatus();
}

std::vector<Candidate> KnnIndex::FindNearest(absl::Span<const float> queries, int k,
                                             FeatureScaling scaling, SimdLevel level, Engine engine,
                                             bool early_abandon, SearchMode mode,
                                             bool* approximate) const {
  const int kk = static_cast<int>(std::min<int64_t>(k, size()));
  const int num_queries = static_cast<int>(queries.size() / static_cast<std::size_t>(dim_));
  const float* scale = ScaleData(scaling);
  // The tree knows rows, not samples, and answers one query vector.
  const bool one_to_one = num_rows() == size() && num_queries == 1;
  const bool forced_tree = engine == Engine::kKdTree;
  if (engine == Engine::kAuto && mode == SearchMode::kDefault && lists_ != nullptr) {
    // The probed cells, then the rows filed in no list yet (from a block boundary).
    knn_internal::TopK top(kk, sample_of_row_.empty() ? nullptr : sample_of_row_.data(),
                           /*rows_repeat=*/num_queries > 1);
    const int probes = lists_options_.probes > 0 ? lists_options_.probes
                                                 : ApproximateOptions::kDefaultProbes;
    lists_->Search(level, queries.data(), num_queries, scale, probes, early_abandon, &top);
    const int64_t filed = lists_->indexed_rows();
    const knn_internal::BlockedView tail{
        storage_.data() + static_cast<std::size_t>(filed / kBlockLanes) * BlockFloats(dim_),
        num_rows() - filed, dim_, filed};
    knn_internal::ScanBlocks(level, tail, queries.data(), num_queries, scale, early_abandon, &top);
    // Probed cells can hold fewer than k samples (small or emptied cells); then the exact
    // scan below answers, so a search always returns min(k, size()) neighbours.
    if (top.full()) {
      if (approximate != nullptr) *approximate = true;
      return top.TakeSorted();
    }
    engine = Engine::kBruteForce;
  }
  if (engine == Engine::kAuto) {
    engine = dim_ <= knn_internal::kKdTreeMaxDimension && size() >= knn_internal::kKdTreeMinSize
                 ? Engine::kKdTree
                 : Engine::kBruteForce;
  }
  if (engine == Engine::kKdTree && one_to_one && trees_) {
    // Forced (tests) builds now; automatic builds once the tree has paid for itself.
    std::shared_ptr<const knn_internal::KdTree> tree =
        trees_->Get(scaling, View(), scale, /*force=*/forced_tree);
    if (tree) {
      knn_internal::TopK top(kk);
      if (tree->Search(queries.data(), &top)) return top.TakeSorted();
    }
    // Not built yet, or nanoflann failed (allocation): brute force gives the same answer.
  }
  // With one row per sample and one query, every offer is of a distinct sample: no groups.
  knn_internal::TopK top(kk, sample_of_row_.empty() ? nullptr : sample_of_row_.data(),
                         /*rows_repeat=*/num_queries > 1);
  knn_internal::ScanBlocks(level, View(), queries.data(), num_queries, scale, early_abandon, &top);
  return top.TakeSorted();
}

absl::StatusOr<std::vector<Neighbor>> KnnIndex::SearchWith(absl::Span<const float> queries, int k,
                                                           FeatureScaling scaling, SimdLevel level,
                                                           Engine engine, bool early_abandon,
                                                           SearchMode mode) const {
  SHAPEID_RETURN_IF_ERROR(ValidateQuery(queries, k));
  if (FeatureScalingName(scaling) == "unknown") {
    return absl::InvalidArgumentError(
        absl::StrCat("invalid feature scaling value ", static_cast<int>(scaling)));
  }
  return ToNeighbors(FindNearest(queries, k, scaling, level, engine, early_abandon, mode));
}

std::vector<Neighbor> KnnIndex::ToNeighbors(const std::vector<Candidate>& nearest) const {
  std::vector<Neighbor> neighbors;
  neighbors.reserve(nearest.size());
  for (const Candidate& c : nearest) {
    const std::size_t sample = static_cast<std::size_t>(SampleOfRow(c.row));
    neighbors.push_back(Neighbor{ids_[sample],
                                 labels_[static_cast<std::size_t>(label_of_sample_[sample])],
                                 std::sqrt(static_cast<double>(c.distance_sq)),
                                 static_cast<int>(c.row - FirstRow(static_cast<int64_t>(sample))),
                                 c.query});
  }
  return neighbors;
}

absl::StatusOr<std::vector<Neighbor>> KnnIndex::Search(absl::Span<const float> queries, int k,
                                                       FeatureScaling scaling,
                                                       SearchMode mode) const {
  return SearchWith(queries, k, scaling, ActiveSimdLevel(), Engine::kAuto,
                    /*early_abandon=*/true, mode);
}

absl::StatusOr<KnnResult> KnnIndex::Classify(absl::Span<const float> queries,
                                             const KnnOptions& options, SearchMode mode) const {
  SHAPEID_RETURN_IF_ERROR(ValidateKnnOptions(options));
  SHAPEID_RETURN_IF_ERROR(ValidateQuery(queries, options.k));
  KnnResult result;
  const std::vector<Candidate> nearest = FindNearest(
      queries, options.k, options.scaling, ActiveSimdLevel(), Engine::kAuto,
      /*early_abandon=*/true, mode, &result.approximate);

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
    const int32_t label = label_of_sample_[static_cast<std::size_t>(
        SampleOfRow(nearest[i].row))];
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
  // Distances are finite (kMaxFeatureMagnitude), so the winner's weight is positive (1, or
  // 1 / distance): total > 0 and the share is in (0, 1]. The 1.0 only guards the division.
  result.confidence = total > 0.0 ? result.votes.front().weight / total : 1.0;
  return result;
}

}  // namespace shapeid
