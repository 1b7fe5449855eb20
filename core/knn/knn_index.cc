#include "core/knn/knn_index.h"

#include <algorithm>
#include <cmath>
#include <utility>

#include "absl/container/flat_hash_set.h"
#include "absl/strings/str_cat.h"
#include "core/status_macros.h"

namespace shapeid {

using knn_internal::Candidate;
using knn_internal::kBlockLanes;

namespace {

// Finite and within +-kMaxFeatureMagnitude (false for NaN).
bool InBound(float value) { return std::fabs(value) <= KnnIndex::kMaxFeatureMagnitude; }

absl::Status OutOfBound(absl::string_view what, float value) {
  return absl::InvalidArgumentError(absl::StrCat(what, " is ", value,
                                                 "; features must be finite and within +-",
                                                 KnnIndex::kMaxFeatureMagnitude));
}

}  // namespace

KnnIndex::KnnIndex(int dimension) : storage_(dimension), statistics_(dimension, kMinScaleSpread) {}

absl::StatusOr<KnnIndex> KnnIndex::Create(int dimension) {
  if (dimension < 1 || dimension > kMaxDimension) {
    return absl::InvalidArgumentError(
        absl::StrCat("kNN index dimension must be in [1, ", kMaxDimension, "], got ", dimension));
  }
  return KnnIndex(dimension);
}

void KnnIndex::CopyFeatures(int64_t sample, float* out) const {
  const int dim = dimension();
  for (int64_t row = samples_.FirstRow(sample); row < samples_.FirstRow(sample + 1); ++row) {
    storage_.CopyRow(row, out);
    out += dim;
  }
}

std::vector<float> KnnIndex::Features(int64_t sample) const {
  std::vector<float> features(static_cast<std::size_t>(ViewsAt(sample)) *
                              static_cast<std::size_t>(dimension()));
  CopyFeatures(sample, features.data());
  return features;
}

absl::Status KnnIndex::Add(uint64_t id, absl::string_view label, absl::Span<const float> features) {
  const int dim_int = dimension();
  const std::size_t dim = static_cast<std::size_t>(dim_int);
  if (features.empty() || features.size() % dim != 0) {
    return absl::InvalidArgumentError(
        absl::StrCat("sample ", id, ": features.size() ", features.size(),
                     " is not a positive multiple of the dimension ", dim_int));
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
  if (samples_.Contains(id)) {
    return absl::AlreadyExistsError(absl::StrCat("sample id ", id, " is already in the index"));
  }
  for (std::size_t v = 0; v < views; ++v) {
    storage_.Append(features.data() + v * dim);
    statistics_.Add(features.data() + v * dim);
  }
  samples_.Append(id, label, static_cast<int64_t>(views));
  statistics_.UpdateFactors();
  trees_.Clear();
  return absl::OkStatus();
}

absl::Status KnnIndex::Remove(absl::Span<const uint64_t> ids) {
  absl::flat_hash_set<uint64_t> doomed;
  for (uint64_t id : ids) {
    if (!samples_.Contains(id)) {
      return absl::NotFoundError(absl::StrCat("sample id ", id, " is not in the index"));
    }
    doomed.insert(id);
  }
  if (doomed.empty()) return absl::OkStatus();

  // The samples before the first removed one keep their rows, so their blocks stay shared;
  // the kept samples after it are appended again, in order. The sample table is rebuilt
  // (labels renumbered in order of first appearance among the samples left).
  const knn_internal::SampleTable old_samples = std::move(samples_);
  const knn_internal::FeatureStorage old_storage = storage_;
  samples_ = knn_internal::SampleTable();
  int64_t first_doomed = 0;
  while (!doomed.contains(old_samples.IdAt(first_doomed))) ++first_doomed;
  storage_.Truncate(old_samples.FirstRow(first_doomed));
  // Only the inverted lists need to know where each row went.
  const bool renumber = approximate_.lists() != nullptr;
  std::vector<int64_t> new_row_of_old(renumber ? static_cast<std::size_t>(old_storage.rows()) : 0,
                                      -1);
  std::vector<float> row(static_cast<std::size_t>(dimension()));
  for (int64_t s = 0; s < old_samples.size(); ++s) {
    const uint64_t id = old_samples.IdAt(s);
    if (doomed.contains(id)) continue;
    const int64_t first = old_samples.FirstRow(s);
    const int64_t end = old_samples.FirstRow(s + 1);
    for (int64_t r = first; r < end; ++r) {
      if (renumber) new_row_of_old[static_cast<std::size_t>(r)] = samples_.num_rows() + (r - first);
      if (s >= first_doomed) {
        old_storage.CopyRow(r, row.data());
        storage_.Append(row.data());
      }
    }
    samples_.Append(id, old_samples.LabelAt(s), end - first);
  }

  statistics_.Reset();
  for (int64_t r = 0; r < storage_.rows(); ++r) {
    storage_.CopyRow(r, row.data());
    statistics_.Add(row.data());
  }
  statistics_.UpdateFactors();
  trees_.Clear();
  if (renumber) approximate_.Renumber(storage_, new_row_of_old);
  return absl::OkStatus();
}

bool KnnIndex::ApproximateInStep(const ApproximateOptions& options, FeatureScaling scaling) const {
  if (!ValidateApproximateOptions(options).ok() || FeatureScalingName(scaling) == "unknown") {
    return true;
  }
  return approximate_.InStep(options, scaling, storage_);
}

absl::Status KnnIndex::UpdateApproximate(const ApproximateOptions& options, FeatureScaling scaling,
                                         const std::atomic<bool>* cancel) {
  SHAPEID_RETURN_IF_ERROR(ValidateApproximateOptions(options));
  if (FeatureScalingName(scaling) == "unknown") {
    return absl::InvalidArgumentError(
        absl::StrCat("invalid feature scaling value ", static_cast<int>(scaling)));
  }
  return approximate_.Update(options, scaling, storage_, statistics_.Factors(scaling), cancel);
}

int KnnIndex::approximate_lists() const {
  return approximate_.lists() != nullptr ? approximate_.lists()->num_lists() : 0;
}

int64_t KnnIndex::approximate_filed_vectors() const {
  return approximate_.lists() != nullptr ? approximate_.lists()->indexed_rows() : 0;
}

std::vector<float> KnnIndex::ScaleFactors(FeatureScaling scaling) const {
  const float* scale = statistics_.Factors(scaling);
  if (scale == nullptr) return std::vector<float>(static_cast<std::size_t>(dimension()), 1.0f);
  return std::vector<float>(scale, scale + dimension());
}

absl::Status KnnIndex::ValidateQuery(absl::Span<const float> queries, int k) const {
  if (k < 1) return absl::InvalidArgumentError(absl::StrCat("k must be at least 1, got ", k));
  const int dim_int = dimension();
  const std::size_t dim = static_cast<std::size_t>(dim_int);
  if (queries.empty() || queries.size() % dim != 0) {
    return absl::InvalidArgumentError(absl::StrCat("query has ", queries.size(),
                                                   " features, not a positive multiple of the ",
                                                   "dimension ", dim_int));
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
  const int num_queries = static_cast<int>(queries.size() / static_cast<std::size_t>(dimension()));
  const float* scale = statistics_.Factors(scaling);
  // The tree knows rows, not samples, and answers one query vector.
  const bool one_to_one = num_rows() == size() && num_queries == 1;
  const bool forced_tree = engine == Engine::kKdTree;
  const knn_internal::InvertedLists* lists = approximate_.lists();
  if (engine == Engine::kAuto && mode == SearchMode::kDefault && lists != nullptr) {
    // The probed cells, then the rows filed in no list yet (from a block boundary).
    knn_internal::TopK top(kk, samples_.sample_of_row(), /*rows_repeat=*/num_queries > 1);
    lists->Search(level, queries.data(), num_queries, scale, approximate_.probes(), early_abandon,
                  &top);
    storage_.Scan(level, lists->indexed_rows(), queries.data(), num_queries, scale, early_abandon,
                  &top);
    // Probed cells can hold fewer than k samples (small or emptied cells); then the exact
    // scan below answers, so a search always returns min(k, size()) neighbors.
    if (top.full()) {
      if (approximate != nullptr) *approximate = true;
      return top.TakeSorted();
    }
    engine = Engine::kBruteForce;
  }
  if (engine == Engine::kAuto) {
    engine =
        dimension() <= knn_internal::kKdTreeMaxDimension && size() >= knn_internal::kKdTreeMinSize
            ? Engine::kKdTree
            : Engine::kBruteForce;
  }
  if (engine == Engine::kKdTree && one_to_one) {
    // Forced (tests) builds now; automatic builds once the tree has paid for itself.
    std::shared_ptr<const knn_internal::KdTree> tree =
        trees_.Get(scaling, storage_, scale, /*force=*/forced_tree);
    if (tree) {
      knn_internal::TopK top(kk);
      if (tree->Search(queries.data(), &top)) return top.TakeSorted();
    }
    // Not built yet, or nanoflann failed (allocation): brute force gives the same answer.
  }
  // With one row per sample and one query, every offer is of a distinct sample: no groups.
  knn_internal::TopK top(kk, samples_.sample_of_row(), /*rows_repeat=*/num_queries > 1);
  storage_.Scan(level, 0, queries.data(), num_queries, scale, early_abandon, &top);
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
    const int64_t sample = samples_.SampleOfRow(c.row);
    neighbors.push_back(Neighbor{samples_.IdAt(sample), samples_.LabelAt(sample),
                                 std::sqrt(static_cast<double>(c.distance_sq)),
                                 static_cast<int>(c.row - samples_.FirstRow(sample)), c.query});
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
  result.neighbors =
      ToNeighbors(FindNearest(queries, options.k, options.scaling, ActiveSimdLevel(), Engine::kAuto,
                              /*early_abandon=*/true, mode, &result.approximate));
  Vote(result.neighbors, options.weighting, &result);
  return result;
}

}  // namespace shapeid
