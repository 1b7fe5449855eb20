#include "core/gallery/gallery_snapshot.h"

#include <utility>

#include "absl/strings/str_cat.h"
#include "core/status_macros.h"

namespace shapeid {

std::map<std::string, int64_t> GallerySnapshot::LabelCounts() const {
  std::map<std::string, int64_t> counts;
  for (const auto& [label, ids] : ids_by_label_) {
    counts.emplace(label, static_cast<int64_t>(ids.size()));
  }
  return counts;
}

absl::StatusOr<std::vector<float>> GallerySnapshot::Describe(const PointCloud& cloud,
                                                             const CloudLimits& limits) const {
  return descriptor_->Compute(cloud, limits);
}

absl::StatusOr<GalleryClassification> GallerySnapshot::Classify(const PointCloud& cloud,
                                                                const CloudLimits& limits,
                                                                int k) const {
  if (empty()) {
    return absl::FailedPreconditionError(
        absl::StrCat("gallery '", name_, "' has no samples; train it before classifying"));
  }
  const absl::Time start = absl::Now();
  SHAPEID_ASSIGN_OR_RETURN(std::vector<float> features, Describe(cloud, limits));
  const absl::Time described = absl::Now();
  SHAPEID_ASSIGN_OR_RETURN(KnnResult knn, index_.Classify(features, KnnFor(k)));
  GalleryClassification answer = Answer(std::move(knn));
  answer.describe_time = described - start;
  answer.search_time = absl::Now() - described;
  return answer;
}

absl::StatusOr<GalleryClassification> GallerySnapshot::ClassifyFeatures(
    absl::Span<const float> features, int k) const {
  if (empty()) {
    return absl::FailedPreconditionError(
        absl::StrCat("gallery '", name_, "' has no samples; train it before classifying"));
  }
  const absl::Time start = absl::Now();
  SHAPEID_ASSIGN_OR_RETURN(KnnResult knn, index_.Classify(features, KnnFor(k)));
  GalleryClassification answer = Answer(std::move(knn));
  answer.search_time = absl::Now() - start;
  return answer;
}

KnnOptions GallerySnapshot::KnnFor(int k) const {
  KnnOptions knn = options_.knn;
  if (k > 0) knn.k = k;
  return knn;
}

GalleryClassification GallerySnapshot::Answer(KnnResult knn) const {
  GalleryClassification answer;
  // A non-empty index always returns at least one neighbour.
  answer.unknown = options_.reject_distance > 0 && !knn.neighbors.empty() &&
                   knn.neighbors.front().distance > options_.reject_distance;
  answer.label = answer.unknown ? std::string(kUnknownLabel) : knn.label;
  answer.confidence = answer.unknown ? 0.0 : knn.confidence;
  answer.knn = std::move(knn);
  return answer;
}

}  // namespace shapeid
