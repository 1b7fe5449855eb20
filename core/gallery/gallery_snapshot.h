#ifndef SHAPEID_CORE_GALLERY_GALLERY_SNAPSHOT_H_
#define SHAPEID_CORE_GALLERY_GALLERY_SNAPSHOT_H_

#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "absl/container/flat_hash_map.h"
#include "absl/status/statusor.h"
#include "absl/time/time.h"
#include "absl/types/span.h"
#include "core/descriptor.h"
#include "core/gallery/gallery_head.h"
#include "core/gallery/gallery_metadata.h"
#include "core/gallery/gallery_options.h"
#include "core/gallery/gallery_store.h"
#include "core/gallery/sample_provenance.h"
#include "core/knn/knn_index.h"
#include "core/knn/knn_shared_chunks.h"
#include "core/point_cloud.h"

namespace shapeid {

// The answer to one classification.
struct GalleryClassification {
  // The answer: knn.label, or kUnknownLabel when the query was rejected.
  std::string label;
  // knn.confidence (the winner's vote share), or 0 when rejected.
  double confidence = 0.0;
  // True when the nearest neighbor was farther than the gallery's reject_distance.
  bool unknown = false;
  // The raw kNN result, reported even when rejected (which class was nearest, how far).
  KnnResult knn;
  // Each neighbor's provenance, in knn.neighbors' order; null for a sample trained without.
  std::vector<std::shared_ptr<const SampleProvenance>> provenance;
  // True when the gallery's trained head (gallery_head.h) took part: label and confidence are
  // then the best of the head's probabilities and the kNN vote shares, half each; false when
  // the kNN vote alone answered. knn is the search's either way.
  bool by_head = false;
  // Server-side time spent computing the descriptor and searching the index.
  absl::Duration describe_time;
  absl::Duration search_time;
};

// One sample as ListSamples gives it: everything but its descriptors.
struct SampleInfo {
  uint64_t id = 0;
  std::string label;
  int views = 1;
  std::shared_ptr<const SampleProvenance> provenance;  // null: none
};

// A page of ListSamples: samples in increasing id order.
struct SamplePage {
  std::vector<SampleInfo> samples;
  // True when samples with larger ids (of the label asked for) remain: the next page starts
  // after samples.back().id.
  bool more = false;
};

// One immutable state of a gallery: what readers hold while writers publish the next one
// (Gallery::Snapshot). Every method is const and thread-safe; a snapshot never changes, so a
// reader that holds one sees the same samples for as long as it holds it.
class GallerySnapshot {
 public:
  // Name, options, times, versions: everything but the samples.
  const GalleryMetadata& metadata() const { return meta_; }
  const std::string& name() const { return meta_.name; }
  // Canonical: descriptor_spec as the registry spells it, every parameter present.
  const GalleryOptions& options() const { return meta_.options; }
  // Null when incompatible() (the spec could not be built here).
  const std::shared_ptr<const Descriptor>& shared_descriptor() const { return descriptor_; }
  // Features per sample.
  int dimension() const { return meta_.dimension; }

  // Empty, or why this server cannot compute descriptors comparable to the stored ones (an
  // unknown descriptor kind, or another DescriptorKind::version). An incompatible gallery
  // loads so that nothing is lost and it can be exported or deleted, but Describe, Classify
  // and training refuse it with FailedPrecondition and this text.
  const std::string& incompatible() const { return incompatible_; }
  // DescriptorKind::version and kShapeidVersion of whatever made the gallery.
  uint32_t descriptor_version() const { return meta_.descriptor_version; }
  const std::string& software_version() const { return meta_.software_version; }

  // Everything a store or an export needs to rebuild this snapshot bit for bit: options,
  // times, versions and every sample in training order. O(num_samples * dimension).
  StoredGallery ToStored() const;
  const KnnIndex& index() const { return index_; }

  int64_t num_samples() const { return index_.size(); }
  bool empty() const { return index_.empty(); }
  // FailedPrecondition "gallery 'NAME' has no samples; train it before `doing`" when empty:
  // the one message of every call that needs samples ("classifying", "recognizing scenes").
  absl::Status RequireSamples(absl::string_view doing) const;
  // FailedPrecondition with incompatible()'s reason when this build cannot describe for the
  // gallery, else OK: so a call is refused before its points are read.
  absl::Status CheckCompatible() const;
  bool Contains(uint64_t id) const { return index_.Contains(id); }
  // The ids of the samples labeled `label`, in training order; empty if none. O(samples).
  std::vector<uint64_t> IdsWithLabel(absl::string_view label) const {
    return index_.IdsWithLabel(label);
  }
  // Samples per label, labels sorted (byte order).
  std::map<std::string, int64_t> LabelCounts() const;
  // The provenance sample `id` was trained with; null when it has none or is absent.
  std::shared_ptr<const SampleProvenance> Provenance(uint64_t id) const;
  // The bytes of provenance text the samples hold: sources, keys and values
  // (ProvenanceBytes summed; at most 8 KiB a sample). O(1).
  int64_t provenance_bytes() const { return provenance_bytes_; }
  // An estimate of the memory the samples hold: their descriptors with the index over them
  // (KnnIndex::memory_bytes: features, ids, labels, inverted lists) and their provenance
  // (ProvenanceMemoryBytes summed, and its table). Counts all this snapshot references,
  // what it shares with the gallery's other snapshots included; not the descriptor object
  // or the metadata (a few KiB). O(1): kept up to date as samples are added and removed.
  // docs/persistence.md states what a sample costs.
  int64_t memory_bytes() const {
    return index_.memory_bytes() + provenance_.memory_bytes() + provenance_memory_;
  }
  // Up to `page_size` (>= 1) samples with ids above `after_id`, labeled `label` (empty:
  // any), in increasing id order: keyset paging, so that a sample added or removed while a
  // client pages through changes no other sample's page. O(num_samples * log(page_size)).
  SamplePage ListSamples(absl::string_view label, uint64_t after_id, size_t page_size) const;

  // The trained head last fitted for this gallery (gallery_head.h), or null. It answers
  // Classify only while head_answers(): its labels are exactly the gallery's; a head fitted
  // before a label was added or removed is kept (for its figures) but answers nothing.
  const std::shared_ptr<const GalleryHead>& head() const { return head_; }
  bool head_answers() const { return head_answers_; }

  // GalleryMetadata's fields.
  absl::Time created() const { return meta_.created; }
  uint64_t incarnation() const { return meta_.incarnation; }
  absl::Time updated() const { return meta_.updated; }
  uint64_t version() const { return meta_.version; }
  // The id the next id-0 sample will get (see kFirstAssignedId in gallery.h).
  uint64_t next_assigned_id() const { return next_assigned_id_; }

  // The gallery's descriptor of `cloud`. Cloud errors are the descriptor's, unchanged
  // (InvalidArgument naming the bad point, ResourceExhausted over `limits`).
  absl::StatusOr<std::vector<float>> Describe(const PointCloud& cloud,
                                              const CloudLimits& limits = {}) const;

  // What the gallery stores for a training cloud: DescribeForTraining (gallery.h) with the
  // gallery's own augmentation. Errors as Describe.
  absl::StatusOr<std::vector<float>> DescribeForTraining(const PointCloud& cloud,
                                                         const CloudLimits& limits = {}) const;

  // Describes `cloud` and classifies it: the descriptor and its pose variants
  // (Descriptor::ComputeWithPoseVariants) are all searched, each sample at its least
  // distance. FailedPrecondition (naming the gallery) when the gallery has no samples,
  // checked before any work; cloud errors as in Describe.
  // `k` > 0 overrides the gallery's k for this call (a client asking for more neighbors).
  // `mode` kExact searches every vector even when the gallery has an approximate index
  // (GalleryLimits::approximate); knn.approximate tells which search ran.
  absl::StatusOr<GalleryClassification> Classify(const PointCloud& cloud,
                                                 const CloudLimits& limits = {}, int k = 0,
                                                 SearchMode mode = SearchMode::kDefault) const;
  // The same for a descriptor computed elsewhere (describe_time is zero); `features` may
  // hold several query vectors (a descriptor and its pose variants), dimension() floats
  // each. InvalidArgument for a length that is not a positive multiple of dimension() or a
  // non-finite feature.
  absl::StatusOr<GalleryClassification> ClassifyFeatures(
      absl::Span<const float> features, int k = 0, SearchMode mode = SearchMode::kDefault) const;

 private:
  friend class Gallery;

  // An empty snapshot; meta.dimension is the index's.
  GallerySnapshot(GalleryMetadata meta, std::shared_ptr<const Descriptor> descriptor,
                  KnnIndex index)
      : meta_(std::move(meta)), descriptor_(std::move(descriptor)), index_(std::move(index)) {
    meta_.dimension = index_.dimension();
  }
  // Writers build the next snapshot from a copy of the current one; nobody else copies.
  GallerySnapshot(const GallerySnapshot&) = default;
  GallerySnapshot& operator=(const GallerySnapshot&) = delete;

  // The two ways samples change, which keep the index, the provenance and their sizes in
  // step. The provenance is taken by value: a caller done with it moves it in, so that it is
  // shared as it is, never copied.
  absl::Status AddSample(uint64_t id, absl::string_view label, absl::Span<const float> features,
                         SampleProvenance provenance);
  absl::Status AddSample(const StoredSample& sample) {
    return AddSample(sample.id, sample.label, sample.features, sample.provenance);
  }
  absl::Status RemoveSamples(absl::Span<const uint64_t> ids);

  // The gallery's kNN options, with k replaced when `k` > 0.
  KnnOptions KnnFor(int k) const;
  // Applies the reject rule to a kNN result and, when the head answers, the head's label for
  // `queries` (the query's vectors) in place of the vote.
  GalleryClassification Answer(KnnResult knn, absl::Span<const float> queries) const;
  // Sets head_answers_ from head_ and the samples' labels; after any change of either.
  void RefreshHeadAnswers();
  GalleryMetadata meta_;
  std::shared_ptr<const Descriptor> descriptor_;
  KnnIndex index_;
  // Only samples trained with provenance have an entry; shared by copies like the index.
  knn_internal::SharedHashTable<
      absl::flat_hash_map<uint64_t, std::shared_ptr<const SampleProvenance>>>
      provenance_;
  int64_t provenance_bytes_ = 0;                   // ProvenanceBytes over provenance_
  int64_t provenance_memory_ = 0;                  // ProvenanceMemoryBytes over provenance_
  uint64_t next_assigned_id_ = uint64_t{1} << 63;  // kFirstAssignedId
  std::string incompatible_;
  std::shared_ptr<const GalleryHead> head_;
  bool head_answers_ = false;
};

}  // namespace shapeid

#endif  // SHAPEID_CORE_GALLERY_GALLERY_SNAPSHOT_H_
