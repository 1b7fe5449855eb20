#ifndef SHAPEID_CORE_GALLERY_GALLERY_STORE_H_
#define SHAPEID_CORE_GALLERY_GALLERY_STORE_H_

#include <cstdint>
#include <functional>
#include <map>
#include <mutex>
#include <string>
#include <vector>

#include "absl/base/thread_annotations.h"
#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "absl/time/time.h"
#include "absl/types/span.h"
#include "core/gallery/gallery_metadata.h"
#include "core/gallery/gallery_options.h"
#include "core/gallery/sample_provenance.h"

namespace shapeid {

// One trained sample as a store keeps it: the descriptor, not the cloud (clouds are large
// and the descriptor is all a gallery needs; re-describing after a spec change is not a
// goal, since a gallery's spec never changes).
struct StoredSample {
  uint64_t id = 0;
  std::string label;
  // One descriptor (StoredGallery::dimension floats) per view: one for a plain sample, the
  // cloud's and then its synthetic views' in an augmented gallery (GalleryOptions::augment).
  std::vector<float> features;
  // Where the sample came from (validated, metadata sorted); empty when not given.
  SampleProvenance provenance = {};
};

// A gallery as a store or an export holds it: its metadata and every sample. Extends the
// metadata rather than holding it, so that readers say `stored.name`.
struct StoredGallery : GalleryMetadata {
  std::vector<StoredSample> samples;  // in training order (the kNN tie-break order)
};

// What GalleryStore::Load hands a store's galleries to, one sample at a time: for each
// gallery Begin, its samples in training order, then End. A gallery begun and not ended (the
// store found it damaged partway and set it aside) is dropped by the next Begin or, when Load
// returns, by the loader's owner. An error the loader returns ends the load with that error,
// unchanged: it is the loader's, never taken for damage in the store.
class GalleryLoader {
 public:
  virtual ~GalleryLoader() = default;
  virtual absl::Status Begin(const GalleryMetadata& gallery) = 0;
  // The next sample of the gallery begun last. The loader may move anything out of `sample`
  // (its provenance, say); the store fills every field again before the next call.
  virtual absl::Status Add(StoredSample& sample) = 0;
  virtual absl::Status End() = 0;
  // The trained head (GalleryHead::Serialize's bytes) the store kept for the gallery ended
  // last, if it kept one; derived state, checked against the samples by the loader.
  virtual absl::Status Head(absl::string_view bytes) {
    (void)bytes;
    return absl::OkStatus();
  }
};

// Where galleries persist. The registry and the galleries call it BEFORE they publish a
// change, and a store error fails the operation with nothing published; so with a durable
// store, "the call returned OK" means "the change survives a restart".
//
// Calls for one gallery arrive serialized, in the order the changes are published (galleries
// call under their writer lock); calls for different galleries may run concurrently, so an
// implementation must be thread-safe. Errors should be Unavailable / Internal / DataLoss with
// a message naming the gallery; they reach the client as they are.
//
// A store shared by several servers (PostgreSQL) may also answer Aborted: the gallery was
// changed through another server since this server's copy, so the write was built on stale
// state and nothing was written. The gallery then calls its CatchUpFunction, which brings its
// copy up to date, and rebuilds and retries the write (a few times) before the error reaches
// a client.
class GalleryStore {
 public:
  virtual ~GalleryStore() = default;

  // A new gallery with its first samples (none for CreateGallery, all of them for an
  // import), all or nothing. Called once per name between DeleteGallery calls.
  virtual absl::Status SaveGallery(const StoredGallery& gallery) = 0;
  virtual absl::Status DeleteGallery(absl::string_view name) = 0;
  // One committed training batch, all or nothing; ids are final (assigned ones filled in).
  // `version` is the gallery's version after the change (the one before it + 1).
  virtual absl::Status AppendSamples(absl::string_view name, absl::Span<const StoredSample> batch,
                                     absl::Time updated, uint64_t version) = 0;
  // Every id is present in the gallery; no duplicates.
  virtual absl::Status RemoveSamples(absl::string_view name, absl::Span<const uint64_t> ids,
                                     absl::Time updated, uint64_t version) = 0;
  // Keeps a gallery's trained head (GalleryHead::Serialize's bytes) in place of the one kept
  // before, to be handed back by Load after its samples. Derived state: a store may keep none
  // (the default), and a gallery then fits its head again after a restart. The write is
  // atomic: a crash leaves the old head or the new one. DeleteGallery drops it.
  virtual absl::Status SaveHead(absl::string_view name, absl::string_view bytes) {
    (void)name;
    (void)bytes;
    return absl::OkStatus();
  }
  // Everything saved, whole, sorted by name (tests, tools).
  virtual absl::StatusOr<std::vector<StoredGallery>> LoadAll() = 0;
  // Everything saved, handed to `loader` a sample at a time: what GalleryRegistry::
  // LoadFromStore reads at start-up. A store that reads one sample at a time holds each only
  // until the loader has it, so a start-up never holds its galleries twice (a whole copy would
  // double the memory at start-up, and glibc keeps the freed copy's pages: docs/persistence.md).
  // The default hands over LoadAll()'s galleries, freeing each once handed over.
  virtual absl::Status Load(GalleryLoader& loader);
};

// Hands `galleries` to `loader` as GalleryStore::Load does: each begun, its samples added,
// ended, then its trained head where `heads` (by gallery name) keeps one; each freed once
// handed over. For stores that read their galleries whole.
absl::Status HandOverGalleries(std::vector<StoredGallery> galleries,
                               const std::map<std::string, std::string, std::less<>>& heads,
                               GalleryLoader& loader);

// What `store`.Load hands over, collected whole: LoadAll for a store that reads through Load.
// A gallery begun and not ended is left out.
absl::StatusOr<std::vector<StoredGallery>> CollectGalleries(GalleryStore& store);

// Brings this server's copy of gallery `name` up to date with a store shared by several
// servers (after it answered Aborted): returns once this server's galleries hold every change
// the store held when it was called. Set by the server to its replication follower's; null
// for a private store, which is never behind.
using CatchUpFunction = std::function<absl::Status(absl::string_view name)>;

// Persists nothing: the server's store until persistence lands (a later issue).
class NullGalleryStore final : public GalleryStore {
 public:
  absl::Status SaveGallery(const StoredGallery&) override { return absl::OkStatus(); }
  absl::Status DeleteGallery(absl::string_view) override { return absl::OkStatus(); }
  absl::Status AppendSamples(absl::string_view, absl::Span<const StoredSample>, absl::Time,
                             uint64_t) override {
    return absl::OkStatus();
  }
  absl::Status RemoveSamples(absl::string_view, absl::Span<const uint64_t>, absl::Time,
                             uint64_t) override {
    return absl::OkStatus();
  }
  absl::StatusOr<std::vector<StoredGallery>> LoadAll() override {
    return std::vector<StoredGallery>{};
  }
};

// Keeps a copy of everything in memory, for tests: it lets them check what a durable store
// would have received, restore a registry from it, and inject failures.
class InMemoryGalleryStore final : public GalleryStore {
 public:
  absl::Status SaveGallery(const StoredGallery& gallery) override;
  absl::Status DeleteGallery(absl::string_view name) override;
  absl::Status AppendSamples(absl::string_view name, absl::Span<const StoredSample> batch,
                             absl::Time updated, uint64_t version) override;
  absl::Status RemoveSamples(absl::string_view name, absl::Span<const uint64_t> ids,
                             absl::Time updated, uint64_t version) override;
  absl::StatusOr<std::vector<StoredGallery>> LoadAll() override;
  absl::Status SaveHead(absl::string_view name, absl::string_view bytes) override;
  absl::Status Load(GalleryLoader& loader) override;

  // Every later call fails with `status` (until called again with OkStatus()).
  void SetFailure(absl::Status status);
  // Samples stored for `name`; -1 if the gallery is not stored.
  int64_t NumSamples(absl::string_view name) const;

 private:
  mutable std::mutex mu_;
  absl::Status failure_ ABSL_GUARDED_BY(mu_);
  std::map<std::string, StoredGallery, std::less<>> galleries_ ABSL_GUARDED_BY(mu_);
  std::map<std::string, std::string, std::less<>> heads_ ABSL_GUARDED_BY(mu_);
};

}  // namespace shapeid

#endif  // SHAPEID_CORE_GALLERY_GALLERY_STORE_H_
