#include "core/gallery/gallery_snapshot.h"

#include <algorithm>
#include <utility>

#include "absl/strings/str_cat.h"
#include "core/gallery/gallery.h"
#include "core/status_macros.h"

namespace shapeid {

std::map<std::string, int64_t> GallerySnapshot::LabelCounts() const {
  std::map<std::string, int64_t> counts;
  for (auto& [label, count] : index_.LabelCounts()) counts.emplace(std::move(label), count);
  return counts;
}

StoredGallery GallerySnapshot::ToStored() const {
  StoredGallery stored;
  static_cast<GalleryMetadata&>(stored) = meta_;
  stored.samples.resize(static_cast<size_t>(index_.size()));
  for (int64_t slot = 0; slot < index_.size(); ++slot) {
    StoredSample& sample = stored.samples[static_cast<size_t>(slot)];
    sample.id = index_.IdAt(slot);
    sample.label = index_.LabelAt(slot);
    // Every view of the sample, one after another (augmented galleries have several).
    sample.features.resize(static_cast<size_t>(index_.ViewsAt(slot)) *
                           static_cast<size_t>(index_.dimension()));
    index_.CopyFeatures(slot, sample.features.data());
    if (auto provenance = Provenance(sample.id)) sample.provenance = *provenance;
  }
  return stored;
}

std::shared_ptr<const SampleProvenance> GallerySnapshot::Provenance(uint64_t id) const {
  const auto* entry = provenance_.Find(id);
  return entry == nullptr ? nullptr : entry->second;
}

SamplePage GallerySnapshot::ListSamples(absl::string_view label, uint64_t after_id,
                                        size_t page_size) const {
  // The page_size smallest qualifying ids, plus one to tell whether more remain: a max-heap
  // of (id, slot) holding the best page_size + 1 seen so far.
  const size_t keep = std::max<size_t>(page_size, 1) + 1;
  std::vector<std::pair<uint64_t, int64_t>> best;
  best.reserve(std::min<size_t>(keep, static_cast<size_t>(index_.size())));
  for (int64_t slot = 0; slot < index_.size(); ++slot) {
    const uint64_t id = index_.IdAt(slot);
    if (id <= after_id || (!label.empty() && index_.LabelAt(slot) != label)) continue;
    if (best.size() < keep) {
      best.emplace_back(id, slot);
      std::push_heap(best.begin(), best.end());
    } else if (id < best.front().first) {
      std::pop_heap(best.begin(), best.end());
      best.back() = {id, slot};
      std::push_heap(best.begin(), best.end());
    }
  }
  std::sort_heap(best.begin(), best.end());
  SamplePage page;
  page.more = best.size() == keep;
  if (page.more) best.pop_back();
  for (const auto& [id, slot] : best) {
    page.samples.push_back(
        SampleInfo{id, index_.LabelAt(slot), index_.ViewsAt(slot), Provenance(id)});
  }
  return page;
}

absl::Status GallerySnapshot::AddSample(uint64_t id, absl::string_view label,
                                        absl::Span<const float> features,
                                        SampleProvenance provenance) {
  SHAPEID_RETURN_IF_ERROR(index_.Add(id, label, features));
  if (!provenance.empty()) {
    auto shared = std::make_shared<const SampleProvenance>(std::move(provenance));
    provenance_bytes_ += static_cast<int64_t>(ProvenanceBytes(*shared));
    provenance_memory_ += static_cast<int64_t>(ProvenanceMemoryBytes(*shared));
    provenance_.Insert({id, std::move(shared)});
  }
  return absl::OkStatus();
}

absl::Status GallerySnapshot::RemoveSamples(absl::Span<const uint64_t> ids) {
  SHAPEID_RETURN_IF_ERROR(index_.Remove(ids));
  for (uint64_t id : ids) {
    const auto* entry = provenance_.Find(id);
    if (entry == nullptr) continue;  // none, or a duplicate id already erased
    provenance_bytes_ -= static_cast<int64_t>(ProvenanceBytes(*entry->second));
    provenance_memory_ -= static_cast<int64_t>(ProvenanceMemoryBytes(*entry->second));
    provenance_.Erase(id);
  }
  return absl::OkStatus();
}

absl::Status GallerySnapshot::CheckCompatible() const {
  if (incompatible_.empty()) return absl::OkStatus();
  return absl::FailedPreconditionError(incompatible_);
}

absl::StatusOr<std::vector<float>> GallerySnapshot::Describe(const PointCloud& cloud,
                                                             const CloudLimits& limits) const {
  SHAPEID_RETURN_IF_ERROR(CheckCompatible());
  return descriptor_->Compute(cloud, limits);
}

absl::StatusOr<std::vector<float>> GallerySnapshot::DescribeForTraining(
    const PointCloud& cloud, const CloudLimits& limits) const {
  SHAPEID_RETURN_IF_ERROR(CheckCompatible());
  return shapeid::DescribeForTraining(*descriptor_, cloud, meta_.options.augment, limits);
}

absl::Status GallerySnapshot::RequireSamples(absl::string_view doing) const {
  if (!empty()) return absl::OkStatus();
  return absl::FailedPreconditionError(
      absl::StrCat("gallery '", meta_.name, "' has no samples; train it before ", doing));
}

absl::StatusOr<GalleryClassification> GallerySnapshot::Classify(const PointCloud& cloud,
                                                                const CloudLimits& limits, int k,
                                                                SearchMode mode) const {
  SHAPEID_RETURN_IF_ERROR(CheckCompatible());
  SHAPEID_RETURN_IF_ERROR(RequireSamples("classifying"));
  const absl::Time start = absl::Now();
  // The query with its pose variants (core/descriptor.h): a sample's distance is the least
  // over them, so a frame that guessed wrong between near-equal axes costs nothing.
  std::vector<float> queries, variants;
  SHAPEID_RETURN_IF_ERROR(descriptor_->ComputeWithPoseVariants(cloud, &queries, &variants, limits));
  queries.insert(queries.end(), variants.begin(), variants.end());
  const absl::Time described = absl::Now();
  SHAPEID_ASSIGN_OR_RETURN(KnnResult knn, index_.Classify(queries, KnnFor(k), mode));
  GalleryClassification answer = Answer(std::move(knn), queries);
  answer.describe_time = described - start;
  answer.search_time = absl::Now() - described;
  return answer;
}

absl::StatusOr<GalleryClassification> GallerySnapshot::ClassifyFeatures(
    absl::Span<const float> features, int k, SearchMode mode) const {
  SHAPEID_RETURN_IF_ERROR(CheckCompatible());
  SHAPEID_RETURN_IF_ERROR(RequireSamples("classifying"));
  const absl::Time start = absl::Now();
  SHAPEID_ASSIGN_OR_RETURN(KnnResult knn, index_.Classify(features, KnnFor(k), mode));
  GalleryClassification answer = Answer(std::move(knn), features);
  answer.search_time = absl::Now() - start;
  return answer;
}

KnnOptions GallerySnapshot::KnnFor(int k) const {
  KnnOptions knn = meta_.options.knn;
  if (k > 0) knn.k = k;
  return knn;
}

void GallerySnapshot::RefreshHeadAnswers() {
  head_answers_ = false;
  if (head_ == nullptr || head_->classifier.dimension() != dimension()) return;
  const std::vector<std::pair<std::string, int64_t>> counts = index_.LabelCounts();
  if (counts.size() != head_->labels.size()) return;
  for (const auto& [label, count] : counts) {
    if (head_->ClassOf(label) < 0) return;
  }
  head_answers_ = true;
}

GalleryClassification GallerySnapshot::Answer(KnnResult knn,
                                              absl::Span<const float> queries) const {
  GalleryClassification answer;
  // A non-empty index always returns at least one neighbor.
  answer.unknown = meta_.options.reject_distance > 0 && !knn.neighbors.empty() &&
                   knn.neighbors.front().distance > meta_.options.reject_distance;
  answer.label = answer.unknown ? std::string(kUnknownLabel) : knn.label;
  answer.confidence = answer.unknown ? 0.0 : knn.confidence;
  if (!answer.unknown && head_answers_) {
    // The head's probabilities (averaged over the query's pose variants) and the kNN vote's
    // shares, half each: each corrects the other's mistakes on views unlike the gallery's.
    absl::StatusOr<std::vector<float>> scores = head_->classifier.Probabilities(queries);
    if (scores.ok()) {
      double total = 0;
      for (const ClassVote& vote : knn.votes) total += vote.weight;
      for (float& score : *scores) score *= 0.5f;
      for (const ClassVote& vote : knn.votes) {
        const int c = head_->ClassOf(vote.label);
        if (c >= 0 && total > 0) (*scores)[c] += static_cast<float>(0.5 * vote.weight / total);
      }
      const size_t best = std::max_element(scores->begin(), scores->end()) - scores->begin();
      answer.label = head_->labels[best];
      answer.confidence = (*scores)[best];
      answer.by_head = true;
    }
  }
  answer.provenance.reserve(knn.neighbors.size());
  for (const auto& neighbor : knn.neighbors) answer.provenance.push_back(Provenance(neighbor.id));
  answer.knn = std::move(knn);
  return answer;
}

}  // namespace shapeid
