#include "core/gallery/gallery.h"

#include <algorithm>
#include <mutex>
#include <random>
#include <utility>

#include "absl/strings/escaping.h"
#include "absl/strings/str_cat.h"
#include "absl/time/clock.h"
#include "core/descriptor_registry.h"
#include "core/status_macros.h"
#include "core/version.h"

namespace shapeid {

namespace {

absl::Status Prefixed(absl::string_view prefix, const absl::Status& status) {
  return absl::Status(status.code(), absl::StrCat(prefix, status.message()));
}

}  // namespace

absl::StatusOr<std::vector<float>> DescribeForTraining(const Descriptor& descriptor,
                                                       const PointCloud& cloud,
                                                       const AugmentOptions& augment,
                                                       const CloudLimits& limits) {
  SHAPEID_ASSIGN_OR_RETURN(std::vector<float> features, descriptor.Compute(cloud, limits));
  if (!augment.enabled()) return features;
  // Seeded by the cloud's bytes, not by a sample id (which may not be assigned yet) or a
  // position in a stream: retraining the same cloud gives the same views.
  const absl::string_view bytes(reinterpret_cast<const char*>(cloud.data()),
                                cloud.size() * 3 * sizeof(float));
  absl::StatusOr<std::vector<PointCloud>> views =
      AugmentedViews(cloud, augment, DeriveSeed(0, bytes));
  // A cloud the scan simulator cannot view (degenerate in a way the descriptor accepts)
  // simply gets no views: augmentation helps recognition, it is not a check on the input.
  if (!views.ok()) return features;
  std::vector<float> view_features;
  for (const PointCloud& view : *views) {
    if (descriptor.Compute(view, &view_features).ok()) {
      features.insert(features.end(), view_features.begin(), view_features.end());
    }
  }
  return features;
}

// ---------------------------------------------------------------------------------------
// TrainBatch

TrainBatch::TrainBatch(std::shared_ptr<Gallery> gallery)
    : gallery_(std::move(gallery)),
      descriptor_(gallery_->Snapshot()->shared_descriptor()),
      augment_(gallery_->Snapshot()->options().augment) {}

absl::Status TrainBatch::SetAugment(const AugmentOptions& augment) {
  if (!error_.ok()) return error_;
  if (absl::Status s = ValidateAugmentOptions(augment); !s.ok()) return Fail(s);
  augment_ = augment;
  return absl::OkStatus();
}

absl::Status TrainBatch::Fail(absl::Status status) {
  error_ = status;
  return status;
}

absl::Status TrainBatch::AddSample(uint64_t id, std::string label, const PointCloud& cloud,
                                   SampleProvenance provenance) {
  if (!error_.ok()) return error_;
  if (committed_) return absl::FailedPreconditionError("batch was already committed");
  if (descriptor_ == nullptr) {
    return Fail(absl::FailedPreconditionError(gallery_->Snapshot()->incompatible()));
  }
  const std::string where = absl::StrCat("sample ", samples_.size(), ": ");
  const GalleryLimits& limits = gallery_->limits();
  if (size() + 1 > limits.max_samples_per_gallery) {
    return Fail(absl::ResourceExhaustedError(absl::StrCat(
        where, "batch has more samples than gallery '", gallery_->name(),
        "' may hold (max_samples_per_gallery = ", limits.max_samples_per_gallery, ")")));
  }
  if (absl::Status s = ValidateLabel(label); !s.ok()) return Fail(Prefixed(where, s));
  if (absl::Status s = NormalizeMetadata(provenance.metadata); !s.ok()) {
    return Fail(Prefixed(where, s));
  }
  if (absl::Status s = ValidateProvenance(provenance); !s.ok()) return Fail(Prefixed(where, s));
  if (id >= kFirstAssignedId) {
    return Fail(absl::InvalidArgumentError(
        absl::StrCat(where, "sample id ", id, " is reserved: client ids are 1 to ",
                     kFirstAssignedId - 1, ", and 0 asks the gallery to assign one")));
  }
  if (id != 0) {
    if (client_ids_.contains(id)) {
      return Fail(absl::AlreadyExistsError(
          absl::StrCat(where, "sample id ", id, " appears twice in this batch")));
    }
    // Early check for a friendly error at the offending sample; Commit checks again.
    if (gallery_->Snapshot()->Contains(id)) {
      return Fail(absl::AlreadyExistsError(absl::StrCat(
          where, "sample id ", id, " is already in gallery '", gallery_->name(), "'")));
    }
  }
  absl::StatusOr<std::vector<float>> features =
      DescribeForTraining(*descriptor_, cloud, augment_, limits.cloud_limits());
  if (!features.ok()) return Fail(Prefixed(where, features.status()));
  if (id != 0) client_ids_.insert(id);
  samples_.push_back(
      StoredSample{id, std::move(label), *std::move(features), std::move(provenance)});
  return absl::OkStatus();
}

absl::StatusOr<CommitResult> TrainBatch::Commit() {
  if (!error_.ok()) return error_;
  if (committed_) return absl::FailedPreconditionError("batch was already committed");
  committed_ = true;
  absl::StatusOr<CommitResult> result = gallery_->CommitBatch(samples_);
  samples_.clear();
  samples_.shrink_to_fit();
  return result;
}

// ---------------------------------------------------------------------------------------
// Gallery

Gallery::Gallery(std::string name, GalleryLimits limits, std::shared_ptr<GalleryStore> store,
                 CatchUpFunction catch_up, std::shared_ptr<const GallerySnapshot> initial)
    : name_(std::move(name)),
      limits_(limits),
      store_(std::move(store)),
      catch_up_(std::move(catch_up)),
      snapshot_(std::move(initial)) {}

absl::StatusOr<std::unique_ptr<GallerySnapshot>> Gallery::EmptySnapshot(
    std::string name, const GalleryOptions& options, absl::Time created) {
  SHAPEID_RETURN_IF_ERROR(ValidateGalleryName(name));
  SHAPEID_RETURN_IF_ERROR(ValidateGalleryOptions(options));
  SHAPEID_ASSIGN_OR_RETURN(std::unique_ptr<Descriptor> descriptor,
                           CreateDescriptor(options.descriptor_spec));
  GalleryOptions canonical = options;
  canonical.descriptor_spec = descriptor->spec().ToString();
  SHAPEID_ASSIGN_OR_RETURN(KnnIndex index,
                           KnnIndex::Create(static_cast<int>(descriptor->dimension())));
  const DescriptorKind* kind = FindDescriptorKind(descriptor->spec().kind);
  GalleryMetadata meta;
  meta.name = std::move(name);
  meta.options = std::move(canonical);
  meta.created = created;
  meta.updated = created;
  meta.descriptor_version = kind != nullptr ? kind->version : 0;
  meta.software_version = kShapeidVersion;
  return std::unique_ptr<GallerySnapshot>(new GallerySnapshot(
      std::move(meta), std::shared_ptr<const Descriptor>(std::move(descriptor)), std::move(index)));
}

absl::StatusOr<std::unique_ptr<GallerySnapshot>> Gallery::StoredSnapshot(
    const GalleryMetadata& stored) {
  SHAPEID_RETURN_IF_ERROR(ValidateGalleryName(stored.name));
  SHAPEID_RETURN_IF_ERROR(ValidateGalleryOptions(stored.options));
  absl::StatusOr<std::unique_ptr<Descriptor>> descriptor =
      CreateDescriptor(stored.options.descriptor_spec);
  std::string incompatible;
  if (!descriptor.ok()) {
    incompatible =
        absl::StrCat("gallery '", stored.name, "' was made with descriptor spec '",
                     stored.options.descriptor_spec, "' by shapeid ", stored.software_version,
                     ", which this server (shapeid ", kShapeidVersion,
                     ") cannot compute: ", descriptor.status().message(),
                     ". Export it to a server that can, or retrain it");
  } else {
    const DescriptorKind* kind = FindDescriptorKind((*descriptor)->spec().kind);
    const uint32_t ours = kind != nullptr ? kind->version : 0;
    if (ours != stored.descriptor_version) {
      incompatible = absl::StrCat(
          "gallery '", stored.name, "' holds descriptors of ", (*descriptor)->spec().kind,
          " version ", stored.descriptor_version, " (made by shapeid ", stored.software_version,
          "); this server (shapeid ", kShapeidVersion, ") computes version ", ours,
          ", and the two are not comparable. Classify on a server running shapeid ",
          stored.software_version, ", or retrain the gallery");
    } else if (static_cast<int>((*descriptor)->dimension()) != stored.dimension) {
      incompatible =
          absl::StrCat("gallery '", stored.name, "' stores ", stored.dimension,
                       " features per sample but its spec '", stored.options.descriptor_spec,
                       "' computes ", (*descriptor)->dimension(), " here. Retrain the gallery");
    }
  }
  SHAPEID_ASSIGN_OR_RETURN(KnnIndex index, KnnIndex::Create(stored.dimension));
  GalleryMetadata meta = stored;
  std::shared_ptr<const Descriptor> shared;
  if (incompatible.empty()) {
    // Same kind version: the stored spec and today's canonical spelling (which may list a
    // parameter added since, at a default that reproduces the old output) are one descriptor.
    meta.options.descriptor_spec = (*descriptor)->spec().ToString();
    shared = *std::move(descriptor);
  }
  auto snapshot = std::unique_ptr<GallerySnapshot>(
      new GallerySnapshot(std::move(meta), std::move(shared), std::move(index)));
  snapshot->incompatible_ = std::move(incompatible);
  return snapshot;
}

uint64_t NewGalleryIncarnation() {
  static std::mutex mu;
  // Seeded with 256 bits: replicas started together must not draw the same sequence.
  static std::mt19937_64 engine = [] {
    std::random_device device;
    std::seed_seq seed{device(), device(), device(), device(),
                       device(), device(), device(), device()};
    return std::mt19937_64(seed);
  }();
  std::lock_guard<std::mutex> lock(mu);
  // 62 bits: positive in any signed 64-bit column, and never 0.
  return (engine() >> 2) | 1;
}

absl::StatusOr<std::shared_ptr<Gallery>> Gallery::Create(
    std::string name, const GalleryOptions& options, const GalleryLimits& limits,
    std::shared_ptr<GalleryStore> store, absl::Time created, CatchUpFunction catch_up) {
  SHAPEID_ASSIGN_OR_RETURN(std::unique_ptr<GallerySnapshot> snapshot,
                           EmptySnapshot(name, options, created));
  snapshot->meta_.incarnation = NewGalleryIncarnation();
  return std::shared_ptr<Gallery>(new Gallery(std::move(name), limits, std::move(store),
                                              std::move(catch_up), std::move(snapshot)));
}

absl::StatusOr<std::shared_ptr<Gallery>> Gallery::Restore(const StoredGallery& stored,
                                                          const GalleryLimits& limits,
                                                          std::shared_ptr<GalleryStore> store,
                                                          ApproximateBuild approximate,
                                                          CatchUpFunction catch_up) {
  SHAPEID_ASSIGN_OR_RETURN(Restorer restorer, Restorer::Begin(stored));
  for (const StoredSample& sample : stored.samples) SHAPEID_RETURN_IF_ERROR(restorer.Add(sample));
  return std::move(restorer).Finish(limits, std::move(store), approximate, std::move(catch_up));
}

absl::StatusOr<Gallery::Restorer> Gallery::Restorer::Begin(const GalleryMetadata& stored) {
  std::string where = absl::StrCat("restoring gallery '", stored.name, "': ");
  absl::StatusOr<std::unique_ptr<GallerySnapshot>> empty = StoredSnapshot(stored);
  if (!empty.ok()) return Prefixed(where, empty.status());
  return Restorer(std::move(where), *std::move(empty));
}

absl::Status Gallery::Restorer::AddWith(const StoredSample& sample, SampleProvenance provenance) {
  if (sample.id == 0) {
    return absl::DataLossError(absl::StrCat(where_, "a sample has id 0, which is never stored"));
  }
  if (absl::Status s = ValidateLabel(sample.label); !s.ok()) return Prefixed(where_, s);
  if (absl::Status s = ValidateProvenance(provenance); !s.ok()) {
    return Prefixed(absl::StrCat(where_, "sample id ", sample.id, ": "), s);
  }
  if (absl::Status s =
          snapshot_->AddSample(sample.id, sample.label, sample.features, std::move(provenance));
      !s.ok()) {
    return Prefixed(absl::StrCat(where_, "sample id ", sample.id, ": "), s);
  }
  if (sample.id >= kFirstAssignedId) next_assigned_ = std::max(next_assigned_, sample.id + 1);
  return absl::OkStatus();
}

absl::StatusOr<std::shared_ptr<Gallery>> Gallery::Restorer::Finish(
    const GalleryLimits& limits, std::shared_ptr<GalleryStore> store, ApproximateBuild approximate,
    CatchUpFunction catch_up) && {
  if (approximate == ApproximateBuild::kNow) {
    if (absl::Status s = snapshot_->index_.UpdateApproximate(limits.approximate,
                                                             snapshot_->options().knn.scaling);
        !s.ok()) {
      return Prefixed(where_, s);
    }
  }
  snapshot_->next_assigned_id_ = next_assigned_;
  std::string name = snapshot_->name();
  return std::shared_ptr<Gallery>(new Gallery(std::move(name), limits, std::move(store),
                                              std::move(catch_up), std::move(snapshot_)));
}

std::shared_ptr<const GallerySnapshot> Gallery::Snapshot() const {
  std::lock_guard<std::mutex> lock(snapshot_mu_);
  return snapshot_;
}

void Gallery::Publish(std::shared_ptr<const GallerySnapshot> next) {
  std::shared_ptr<const GallerySnapshot> old;
  {
    std::lock_guard<std::mutex> lock(snapshot_mu_);
    old = std::exchange(snapshot_, std::move(next));
  }
  // `old` is released here, outside the lock: freeing a large index takes a while.
}

TrainBatch Gallery::NewBatch() { return TrainBatch(shared_from_this()); }

absl::StatusOr<CommitResult> Gallery::Train(absl::Span<const LabeledCloud> samples) {
  TrainBatch batch = NewBatch();
  for (const LabeledCloud& sample : samples) {
    SHAPEID_RETURN_IF_ERROR(
        batch.AddSample(sample.id, sample.label, sample.cloud, sample.provenance));
  }
  return batch.Commit();
}

absl::Status Gallery::DeletedError() const {
  return absl::NotFoundError(
      absl::StrCat("gallery '", name_, "' was deleted; nothing was changed"));
}

absl::Status Gallery::MarkDeleted(const std::function<absl::Status()>& forget) {
  std::lock_guard<std::mutex> lock(writer_mu_);
  if (deleted_) return DeletedError();
  SHAPEID_RETURN_IF_ERROR(forget());
  deleted_ = true;
  return absl::OkStatus();
}

absl::StatusOr<CommitResult> Gallery::CommitBatch(std::vector<StoredSample>& samples) {
  // An attempt fills in assigned ids; a retry must choose them afresh from the caught-up
  // snapshot (another server may have handed out the same ones meanwhile).
  std::vector<size_t> to_assign;
  for (size_t i = 0; i < samples.size(); ++i) {
    if (samples[i].id == 0) to_assign.push_back(i);
  }
  return RetryIfStale<CommitResult>([&] {
    for (size_t i : to_assign) samples[i].id = 0;
    return CommitBatchOnce(samples);
  });
}

template <typename T>
absl::StatusOr<T> Gallery::RetryIfStale(const std::function<absl::StatusOr<T>()>& write) {
  bool caught_up_for_not_found = false;
  for (int attempt = 1;; ++attempt) {
    absl::StatusOr<T> result = write();
    if (catch_up_ == nullptr || attempt == kStaleAttempts) return result;
    // NotFound (an id or label to remove) may only mean that another server's change has not
    // reached this one yet: catch up and look once more, so a client that trained through
    // one replica can remove through another at once.
    const bool stale = absl::IsAborted(result.status()) ||
                       (absl::IsNotFound(result.status()) && !caught_up_for_not_found);
    if (!stale) return result;
    if (absl::IsNotFound(result.status())) caught_up_for_not_found = true;
    if (absl::IsAborted(result.status()) && attempt > 1) {
      // Lost again to a writer on another replica. Writers there are never stale for their
      // own changes, so a steady stream of them would win every time: a random pause, growing
      // with the attempts (up to 50 ms), lets this one in.
      thread_local std::mt19937 jitter(std::random_device{}());
      const int cap_ms = std::min(50, 1 << std::min(attempt, 6));
      absl::SleepFor(absl::Milliseconds(std::uniform_int_distribution<int>(0, cap_ms)(jitter)));
    }
    // A shared store found this server's copy behind: apply what the others wrote, then
    // rebuild the change on top of it (outside the writer lock, which catching up needs).
    SHAPEID_RETURN_IF_ERROR(catch_up_(name_));
  }
}

Gallery::Origin Gallery::Origin::Local(Persist persist) {
  Origin origin(Kind::kLocal);
  origin.persist_ = std::move(persist);
  return origin;
}

Gallery::Origin Gallery::Origin::Stored(uint64_t version, absl::Time updated) {
  Origin origin(Kind::kStored);
  origin.version_ = version;
  origin.updated_ = updated;
  return origin;
}

Gallery::Origin Gallery::Origin::Derived(const std::atomic<bool>* cancel) {
  Origin origin(Kind::kDerived);
  origin.cancel_ = cancel;
  return origin;
}

absl::StatusOr<std::shared_ptr<const GallerySnapshot>> Gallery::Mutate(const Origin& origin,
                                                                       const Check& check,
                                                                       const Change& change) {
  std::lock_guard<std::mutex> lock(writer_mu_);
  std::shared_ptr<const GallerySnapshot> current = Snapshot();
  if (deleted_) {
    if (origin.kind_ == Origin::Kind::kDerived) return current;
    return DeletedError();
  }
  const uint64_t version = current->version();
  if (origin.kind_ == Origin::Kind::kStored) {
    if (origin.version_ <= version) return current;  // held already
    if (origin.version_ > version + 1) {
      return absl::FailedPreconditionError(absl::StrCat(
          "gallery '", name_, "' is at version ", version, "; a stored change to version ",
          origin.version_, " cannot apply (changes missed)"));
    }
  }
  if (check != nullptr) {
    SHAPEID_ASSIGN_OR_RETURN(const bool needed, check(*current));
    if (!needed) return current;
  }
  // The copy shares the index's blocks (O(blocks)); readers keep using `current` meanwhile.
  std::shared_ptr<GallerySnapshot> next(new GallerySnapshot(*current));
  if (change != nullptr) SHAPEID_RETURN_IF_ERROR(change(*next));
  next->RefreshHeadAnswers();
  // Seconds when the index has to be built; readers meanwhile use `current`.
  SHAPEID_RETURN_IF_ERROR(next->index_.UpdateApproximate(
      limits_.approximate, next->options().knn.scaling, origin.cancel_));
  GalleryMetadata& meta = next->meta_;
  switch (origin.kind_) {
    case Origin::Kind::kLocal:
      meta.version = version + 1;
      meta.updated = std::max(absl::Now(), current->updated());
      if (store_ != nullptr) {
        SHAPEID_RETURN_IF_ERROR(origin.persist_(*store_, meta.updated, meta.version));
      }
      break;
    case Origin::Kind::kStored:
      meta.version = origin.version_;
      meta.updated = origin.updated_;
      break;
    case Origin::Kind::kDerived:
      break;
  }
  current = std::move(next);
  Publish(current);
  return current;
}

absl::StatusOr<CommitResult> Gallery::CommitBatchOnce(std::vector<StoredSample>& samples) {
  const Check check = [&](const GallerySnapshot& current) -> absl::StatusOr<bool> {
    // Never mix descriptors of another version into a gallery.
    SHAPEID_RETURN_IF_ERROR(current.CheckCompatible());
    if (samples.empty()) return false;
    const int64_t total = current.num_samples() + static_cast<int64_t>(samples.size());
    if (total > limits_.max_samples_per_gallery) {
      return absl::ResourceExhaustedError(absl::StrCat(
          "gallery '", name_, "' holds ", current.num_samples(), " samples; adding ",
          samples.size(),
          " would exceed max_samples_per_gallery = ", limits_.max_samples_per_gallery));
    }
    // Client ids: checked again here, since other batches may have committed since AddSample.
    for (size_t i = 0; i < samples.size(); ++i) {
      const uint64_t id = samples[i].id;
      if (id != 0 && current.Contains(id)) {
        return absl::AlreadyExistsError(
            absl::StrCat("sample ", i, ": sample id ", id, " is already in gallery '", name_, "'"));
      }
    }
    return true;
  };
  const Change add = [&](GallerySnapshot& next) -> absl::Status {
    for (StoredSample& sample : samples) {
      // Assigned ids live above every client id (kFirstAssignedId), so they cannot collide.
      if (sample.id == 0) sample.id = next.next_assigned_id_++;
      // Cannot fail for validated descriptors and labels; if it does, nothing is published.
      SHAPEID_RETURN_IF_ERROR(next.AddSample(sample));
    }
    return absl::OkStatus();
  };
  const Origin origin =
      Origin::Local([&](GalleryStore& store, absl::Time updated, uint64_t version) {
        return store.AppendSamples(name_, samples, updated, version);
      });
  SHAPEID_ASSIGN_OR_RETURN(const std::shared_ptr<const GallerySnapshot> after,
                           Mutate(origin, check, add));
  CommitResult result;
  result.version = after->version();
  for (const StoredSample& sample : samples) result.ids.push_back(sample.id);
  return result;
}

absl::Status Gallery::UpdateApproximateIndex(const std::atomic<bool>* cancel) {
  const Check out_of_step = [&](const GallerySnapshot& current) -> absl::StatusOr<bool> {
    return !current.index_.ApproximateInStep(limits_.approximate, current.options().knn.scaling);
  };
  return Mutate(Origin::Derived(cancel), out_of_step, nullptr).status();
}

absl::Status Gallery::SetHead(std::shared_ptr<const GalleryHead> head, KeepHead keep) {
  absl::Status kept;
  const Change set = [&](GallerySnapshot& next) {
    next.head_ = head;
    // Under the writer lock, so a delete cannot come between and leave a head behind.
    if (keep == KeepHead::kInStore && head != nullptr && store_ != nullptr) {
      kept = store_->SaveHead(name_, head->Serialize());
    }
    return absl::OkStatus();
  };
  SHAPEID_RETURN_IF_ERROR(Mutate(Origin::Derived(nullptr), nullptr, set).status());
  return kept;
}

absl::StatusOr<int64_t> Gallery::RemoveSamples(absl::Span<const uint64_t> ids,
                                               absl::Span<const std::string> labels) {
  return RetryIfStale<int64_t>([&] { return RemoveSamplesOnce(ids, labels); });
}

absl::StatusOr<int64_t> Gallery::RemoveSamplesOnce(absl::Span<const uint64_t> ids,
                                                   absl::Span<const std::string> labels) {
  // Resolved against the snapshot the removal is made on.
  std::vector<uint64_t> unique;
  const Check resolve = [&](const GallerySnapshot& current) -> absl::StatusOr<bool> {
    absl::flat_hash_set<uint64_t> seen;
    for (const std::string& label : labels) {
      const std::vector<uint64_t> labeled = current.IdsWithLabel(label);
      if (labeled.empty()) {
        return absl::NotFoundError(absl::StrCat("gallery '", name_, "' has no samples labeled '",
                                                absl::CHexEscape(label), "'; nothing was removed"));
      }
      for (uint64_t id : labeled) {
        if (seen.insert(id).second) unique.push_back(id);
      }
    }
    for (uint64_t id : ids) {
      if (!seen.insert(id).second) continue;
      if (!current.Contains(id)) {
        return absl::NotFoundError(absl::StrCat("sample id ", id, " is not in gallery '", name_,
                                                "'; nothing was removed"));
      }
      unique.push_back(id);
    }
    return !unique.empty();
  };
  const Change remove = [&](GallerySnapshot& next) { return next.RemoveSamples(unique); };
  const Origin origin =
      Origin::Local([&](GalleryStore& store, absl::Time updated, uint64_t version) {
        return store.RemoveSamples(name_, unique, updated, version);
      });
  SHAPEID_RETURN_IF_ERROR(Mutate(origin, resolve, remove).status());
  return static_cast<int64_t>(unique.size());
}

absl::Status Gallery::ApplyStoredAppend(absl::Span<const StoredSample> samples, absl::Time updated,
                                        uint64_t version) {
  const Change add = [&](GallerySnapshot& next) -> absl::Status {
    for (const StoredSample& sample : samples) {
      SHAPEID_RETURN_IF_ERROR(ValidateProvenance(sample.provenance));
      SHAPEID_RETURN_IF_ERROR(next.AddSample(sample));
      if (sample.id >= kFirstAssignedId) {
        next.next_assigned_id_ = std::max(next.next_assigned_id_, sample.id + 1);
      }
    }
    return absl::OkStatus();
  };
  return Mutate(Origin::Stored(version, updated), nullptr, add).status();
}

absl::Status Gallery::ApplyStoredRemove(absl::Span<const uint64_t> ids, absl::Time updated,
                                        uint64_t version) {
  const Change remove = [&](GallerySnapshot& next) { return next.RemoveSamples(ids); };
  return Mutate(Origin::Stored(version, updated), nullptr, remove).status();
}

absl::Status Gallery::AdoptStored(const Gallery& stored) {
  std::lock_guard<std::mutex> lock(writer_mu_);
  if (deleted_) return DeletedError();
  std::shared_ptr<const GallerySnapshot> next = stored.Snapshot();
  if (next->version() <= Snapshot()->version()) return absl::OkStatus();
  Publish(std::move(next));
  return absl::OkStatus();
}

}  // namespace shapeid
