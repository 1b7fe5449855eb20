#ifndef SHAPEID_CORE_GALLERY_GALLERY_H_
#define SHAPEID_CORE_GALLERY_GALLERY_H_

#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "absl/base/thread_annotations.h"
#include "absl/container/flat_hash_set.h"
#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "absl/time/time.h"
#include "absl/types/span.h"
#include "core/gallery/gallery_options.h"
#include "core/gallery/gallery_snapshot.h"
#include "core/gallery/gallery_store.h"
#include "core/point_cloud.h"

namespace shapeid {

class Gallery;

// What a gallery stores for one training cloud: its descriptor, then (when `augment` is on)
// those of its synthetic views (AugmentedViews), seeded by the cloud's own bytes so the same
// cloud always gets the same views. Views that cannot be made or described (degenerate
// scans) are left out; the cloud's own errors are Descriptor::Compute's.
absl::StatusOr<std::vector<float>> DescribeForTraining(const Descriptor& descriptor,
                                                       const PointCloud& cloud,
                                                       const AugmentOptions& augment,
                                                       const CloudLimits& limits = {});

// Sample ids. A client picks ids in [1, kFirstAssignedId) or passes 0 to have the gallery
// assign one. Assigned ids count up from kFirstAssignedId, per gallery, and are never reused
// (not even after a removal). Splitting the id space is what makes "assigned ids never
// collide with client ids" true in both directions: a client that mixes its own ids with
// assigned ones can never be refused an id because the gallery handed it out earlier. Client
// ids stay below 2^63, so they fit a signed 64-bit integer (Java, SQL) unchanged.
inline constexpr uint64_t kFirstAssignedId = uint64_t{1} << 63;

struct LabeledCloud {
  uint64_t id = 0;  // 0: the gallery assigns one; else in [1, kFirstAssignedId)
  std::string label;
  PointCloud cloud;
  SampleProvenance provenance = {};  // optional
};

struct CommitResult {
  std::vector<uint64_t> ids;  // final id of each sample, in the order they were added
  uint64_t version = 0;       // version of the snapshot that holds them
};

// One all-or-nothing training batch, filled sample by sample as a stream arrives, then
// committed at once. AddSample describes the cloud immediately (outside any lock), so errors
// surface at the offending sample and the batch keeps only descriptors (d floats per sample),
// never clouds. A batch destroyed without Commit leaves no trace.
//
// Once AddSample has failed the batch is poisoned: later AddSample calls and Commit return
// that first error, so a caller that forgets to check still cannot publish half a batch.
// Not thread-safe: one batch per stream. Keeps its gallery alive.
class TrainBatch {
 public:
  TrainBatch(TrainBatch&&) = default;
  TrainBatch& operator=(TrainBatch&&) = default;

  // Describes `cloud` and keeps its descriptor. `index` in messages is the 0-based position
  // of the sample in this batch. Errors, each prefixed "sample <index>":
  //  - InvalidArgument for an id >= kFirstAssignedId, a bad label (ValidateLabel) or cloud
  //    (the descriptor's message, which names the bad point);
  //  - ResourceExhausted over max_points_per_cloud or when the batch alone would exceed
  //    max_samples_per_gallery;
  //  - AlreadyExists when `id` is nonzero and already in the gallery or in this batch;
  //  - InvalidArgument for provenance over its limits or not UTF-8 (ValidateProvenance;
  //    the metadata is sorted by key here, and a key given twice is refused).
  //
  // With view augmentation (the gallery's GalleryOptions::augment, or the batch's override)
  // the cloud's synthetic views are described too and kept as views of the sample; they are
  // seeded by the cloud's own bytes, so the same cloud always gets the same views. Views
  // that cannot be made or described (degenerate scans) are left out; the cloud itself must
  // pass.
  absl::Status AddSample(uint64_t id, std::string label, const PointCloud& cloud,
                         SampleProvenance provenance = {});

  // Replaces the gallery's view augmentation for the samples added from now on (a Train
  // stream's own setting). InvalidArgument (and the batch fails) for invalid options.
  absl::Status SetAugment(const AugmentOptions& augment);

  // Samples added so far.
  int64_t size() const { return static_cast<int64_t>(samples_.size()); }

  // Publishes every sample of the batch as one new snapshot, or none. Applies the
  // descriptors to the gallery's then-current snapshot, so concurrent batches on one
  // gallery never lose each other's samples. Rechecks, against that snapshot: duplicate ids
  // (AlreadyExists), max_samples_per_gallery (ResourceExhausted). NotFound if the gallery
  // was deleted meanwhile; the store's error if it fails. An empty batch publishes nothing
  // and returns the current version. A batch commits at most once (FailedPrecondition).
  //
  // Cost: O(batch) plus the store's write, under the gallery's writer lock (readers are never
  // blocked by it, other commits are): the index's blocks are shared with the current
  // snapshot and only the last one is copied (bench/commit_bench, docs/performance.md).
  absl::StatusOr<CommitResult> Commit();

 private:
  friend class Gallery;
  explicit TrainBatch(std::shared_ptr<Gallery> gallery);

  absl::Status Fail(absl::Status status);

  std::shared_ptr<Gallery> gallery_;
  std::shared_ptr<const Descriptor> descriptor_;
  AugmentOptions augment_;
  std::vector<StoredSample> samples_;
  absl::flat_hash_set<uint64_t> client_ids_;
  absl::Status error_;
  bool committed_ = false;
};

// A fresh StoredGallery::incarnation (random, nonzero, below 2^62).
uint64_t NewGalleryIncarnation();

// A named, trained kNN gallery that many threads classify against while others train it.
//
// Concurrency: readers call Snapshot() and work on the immutable snapshot it returns; they
// wait for writers only for the copy of one shared_ptr. Writers (commits, removals) are
// serialized by a second mutex; each builds the next snapshot from the current one, writes
// it to the store, then swaps it in. All methods are thread-safe.
//
// Create galleries through GalleryRegistry; Create and Restore are for the registry and tests.
class Gallery : public std::enable_shared_from_this<Gallery> {
 public:
  // A new, empty gallery. Validates the name (ValidateGalleryName), the options
  // (ValidateGalleryOptions) and the descriptor spec (the registry's InvalidArgument,
  // unchanged), and canonicalises the spec. `store` may be null (nothing persisted). Does
  // not call the store: the registry saves the gallery before publishing it. `catch_up`
  // (null for a private store) is what a write refused as stale calls before it retries.
  static absl::StatusOr<std::shared_ptr<Gallery>> Create(std::string name,
                                                         const GalleryOptions& options,
                                                         const GalleryLimits& limits,
                                                         std::shared_ptr<GalleryStore> store,
                                                         absl::Time created = absl::Now(),
                                                         CatchUpFunction catch_up = nullptr);
  // A gallery rebuilt from what a store saved (or an export held), without writing to the
  // store; the samples keep their order, so answers are bit for bit those before. Assigned
  // ids continue above the largest stored assigned id. A gallery this server cannot compute
  // descriptors for loads all the same, marked GallerySnapshot::incompatible(). Errors, each
  // naming the gallery: a bad name or options (InvalidArgument); a bad label, id or feature
  // vector (InvalidArgument, AlreadyExists; DataLoss for id 0).
  // `approximate` kLater leaves the approximate index (GalleryLimits::approximate) to a
  // later UpdateApproximateIndex, so that a server can load and serve (exactly) at once.
  enum class ApproximateBuild { kNow, kLater };
  static absl::StatusOr<std::shared_ptr<Gallery>> Restore(
      const StoredGallery& stored, const GalleryLimits& limits, std::shared_ptr<GalleryStore> store,
      ApproximateBuild approximate = ApproximateBuild::kNow, CatchUpFunction catch_up = nullptr);

  // Restore one sample at a time, for a store read one sample at a time (GalleryStore::Load):
  // Begin with the stored metadata, Add every sample in training order, Finish. Restore is
  // these three over a StoredGallery; the errors are Restore's, each step's as it comes.
  class Restorer {
   public:
    static absl::StatusOr<Restorer> Begin(const GalleryMetadata& stored);
    // Checks and adds the next sample. The rvalue form takes the sample's provenance into the
    // gallery as it is, where the other copies it; nothing else of `sample` is kept.
    absl::Status Add(const StoredSample& sample) { return AddWith(sample, sample.provenance); }
    absl::Status Add(StoredSample&& sample) {
      return AddWith(sample, std::move(sample.provenance));
    }
    // The gallery of the samples added; the Restorer is spent.
    absl::StatusOr<std::shared_ptr<Gallery>> Finish(
        const GalleryLimits& limits, std::shared_ptr<GalleryStore> store,
        ApproximateBuild approximate = ApproximateBuild::kNow,
        CatchUpFunction catch_up = nullptr) &&;

   private:
    Restorer(std::string where, std::unique_ptr<GallerySnapshot> snapshot)
        : where_(std::move(where)), snapshot_(std::move(snapshot)) {}
    absl::Status AddWith(const StoredSample& sample, SampleProvenance provenance);

    std::string where_;  // "restoring gallery 'NAME': "
    std::unique_ptr<GallerySnapshot> snapshot_;
    uint64_t next_assigned_ = kFirstAssignedId;
  };

  Gallery(const Gallery&) = delete;
  Gallery& operator=(const Gallery&) = delete;

  const std::string& name() const { return name_; }
  const GalleryLimits& limits() const { return limits_; }

  // The current snapshot; never null.
  std::shared_ptr<const GallerySnapshot> Snapshot() const;

  // An empty batch for this gallery.
  TrainBatch NewBatch();
  // NewBatch, AddSample for each, Commit.
  absl::StatusOr<CommitResult> Train(absl::Span<const LabeledCloud> samples);

  // Removes the samples with these ids and those labeled with one of `labels` (their
  // union; duplicates ignored), resolved against the gallery as it is when the removal runs,
  // and returns how many were removed. All or nothing: NotFound naming the first label with
  // no sample or the first absent id. O(num_samples * dimension): remove in batches.
  absl::StatusOr<int64_t> RemoveSamples(absl::Span<const uint64_t> ids,
                                        absl::Span<const std::string> labels = {});

  // Brings the approximate index in step with limits().approximate when it is not (a gallery
  // restored with ApproximateBuild::kLater): publishes a snapshot with the same samples and
  // version and the index built. Readers keep the old snapshot meanwhile; writers wait (it
  // holds the writer lock). Costs a copy of the index, O(samples * dimension), and the build
  // (seconds at 10^6 vectors). Cancelled, with nothing published, if `cancel` (may be null)
  // turns true meanwhile.
  absl::Status UpdateApproximateIndex(const std::atomic<bool>* cancel = nullptr);

  // Publishes a snapshot with the same samples and version that holds `head` (null: none).
  // Derived state: nothing to do once deleted. With `keep`, the store also keeps the head
  // (GalleryStore::SaveHead) so that a restart need not fit it again; the head is published
  // even if the store fails, whose error is then returned.
  enum class KeepHead { kNo, kInStore };
  absl::Status SetHead(std::shared_ptr<const GalleryHead> head, KeepHead keep = KeepHead::kNo);

  // Replication, for a store shared by several servers: apply a change another server has
  // already stored, without writing to the store. `version` is the gallery's version after
  // the change. A change this gallery already holds (version <= its own) is skipped;
  // FailedPrecondition if changes are missing before it (version > own + 1): reload the
  // gallery instead (GalleryRegistry::ApplyStoredGallery). NotFound after a Delete.
  absl::Status ApplyStoredAppend(absl::Span<const StoredSample> samples, absl::Time updated,
                                 uint64_t version);
  absl::Status ApplyStoredRemove(absl::Span<const uint64_t> ids, absl::Time updated,
                                 uint64_t version);
  // Takes `stored`'s current snapshot (a reload of this same gallery from the store), unless
  // this gallery is already at that version or later. Streams holding this gallery go on.
  absl::Status AdoptStored(const Gallery& stored);

 private:
  friend class TrainBatch;
  friend class GalleryRegistry;

  Gallery(std::string name, GalleryLimits limits, std::shared_ptr<GalleryStore> store,
          CatchUpFunction catch_up, std::shared_ptr<const GallerySnapshot> initial);

  static absl::StatusOr<std::unique_ptr<GallerySnapshot>> EmptySnapshot(
      std::string name, const GalleryOptions& options, absl::Time created);
  // An empty snapshot with the stored options and versions, marked incompatible() when this
  // server cannot compute the stored spec's descriptors identically.
  static absl::StatusOr<std::unique_ptr<GallerySnapshot>> StoredSnapshot(
      const GalleryMetadata& stored);

  // Writes retry when a shared store answers Aborted (it found this server's copy behind):
  // catch_up_, then the write again, up to kStaleAttempts in all. NotFound is retried once
  // after a catch-up too (see RetryIfStale).
  static constexpr int kStaleAttempts = 20;
  template <typename T>
  absl::StatusOr<T> RetryIfStale(const std::function<absl::StatusOr<T>()>& write);

  // Where a change comes from, which fixes its version, its time and whether it is stored.
  // Made only by these three, so a local change always has its store write.
  class Origin {
   public:
    using Persist =
        std::function<absl::Status(GalleryStore&, absl::Time updated, uint64_t version)>;
    // Made here: version + 1, updated now (never before the last change), written to the
    // store by `persist` (with that time and version) before it is published.
    static Origin Local(Persist persist);
    // Another server's change, already stored, to `version` at `updated`: skipped if this
    // gallery holds it, FailedPrecondition if changes are missing before it.
    static Origin Stored(uint64_t version, absl::Time updated);
    // Derived state only (the approximate index): same version and time, nothing stored,
    // nothing to do once deleted. `cancel` (may be null) cancels the index build.
    static Origin Derived(const std::atomic<bool>* cancel);

   private:
    friend class Gallery;
    enum class Kind { kLocal, kStored, kDerived };
    explicit Origin(Kind kind) : kind_(kind) {}

    Kind kind_;
    Persist persist_;                            // kLocal
    uint64_t version_ = 0;                       // kStored
    absl::Time updated_;                         // kStored
    const std::atomic<bool>* cancel_ = nullptr;  // kDerived
  };
  // Reads the current snapshot under the writer lock: an error, or false when there is
  // nothing to change (nothing is then copied, stored or published).
  using Check = std::function<absl::StatusOr<bool>(const GallerySnapshot& current)>;
  // Edits the copy that becomes the next snapshot.
  using Change = std::function<absl::Status(GallerySnapshot& next)>;

  // The one way a gallery changes. Under the writer lock (NotFound once deleted): `check`,
  // then `change` on a copy of the current snapshot, the approximate index brought in step,
  // version and time set and the store written as `origin` says, then the copy published.
  // Returns the snapshot published, or the current one when there was nothing to do; an
  // error at any step publishes nothing. `check` and `change` may be null.
  absl::StatusOr<std::shared_ptr<const GallerySnapshot>> Mutate(const Origin& origin,
                                                                const Check& check,
                                                                const Change& change);

  absl::StatusOr<CommitResult> CommitBatch(std::vector<StoredSample>& samples);
  absl::StatusOr<CommitResult> CommitBatchOnce(std::vector<StoredSample>& samples);
  absl::StatusOr<int64_t> RemoveSamplesOnce(absl::Span<const uint64_t> ids,
                                            absl::Span<const std::string> labels);
  void Publish(std::shared_ptr<const GallerySnapshot> next);
  // Runs `forget` (the store's delete) under the writer lock and, if it succeeds, makes every
  // later write fail NotFound.
  absl::Status MarkDeleted(const std::function<absl::Status()>& forget);
  absl::Status DeletedError() const;

  const std::string name_;
  const GalleryLimits limits_;
  const std::shared_ptr<GalleryStore> store_;  // may be null
  const CatchUpFunction catch_up_;             // null: the store is never behind

  // std::mutex rather than absl::Mutex: Debian's Abseil is not built with TSan
  // instrumentation, so absl::Mutex makes ThreadSanitizer report false races.
  // Lock order: writer_mu_ before snapshot_mu_ (and the registry's mutex before both).
  mutable std::mutex snapshot_mu_;
  std::shared_ptr<const GallerySnapshot> snapshot_ ABSL_GUARDED_BY(snapshot_mu_);
  std::mutex writer_mu_;
  bool deleted_ ABSL_GUARDED_BY(writer_mu_) = false;
};

}  // namespace shapeid

#endif  // SHAPEID_CORE_GALLERY_GALLERY_H_
