#ifndef SHAPEID_CORE_GALLERY_GALLERY_REGISTRY_H_
#define SHAPEID_CORE_GALLERY_GALLERY_REGISTRY_H_

#include <atomic>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "absl/base/thread_annotations.h"
#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "core/gallery/gallery.h"
#include "core/gallery/gallery_options.h"
#include "core/gallery/gallery_store.h"

namespace shapeid {

// The galleries of one server, by name. All methods are thread-safe. Changes reach the
// store before they are published; a store error fails the call and changes nothing.
//
// A Gallery returned by Create or Get stays usable after Delete (a stream in flight keeps
// its pointer), but its later writes fail NotFound and never reach the store, even if a new
// gallery of the same name is created meanwhile.
class GalleryRegistry {
 public:
  // `store` null means NullGalleryStore (nothing persisted). `catch_up` is given to every
  // gallery: what a write the store refused as stale calls before it retries (null for a
  // store that is never behind; see GalleryStore).
  explicit GalleryRegistry(GalleryLimits limits = {}, std::shared_ptr<GalleryStore> store = {},
                           CatchUpFunction catch_up = nullptr);
  // Stops the background build of approximate indexes (LoadFromStore) and waits for it:
  // within a fraction of a second.
  ~GalleryRegistry();

  GalleryRegistry(const GalleryRegistry&) = delete;
  GalleryRegistry& operator=(const GalleryRegistry&) = delete;

  // Adds every gallery the store holds (call once, before serving), each rebuilt as the
  // store reads it (GalleryStore::Load), so that nothing stored is held twice. Errors: the store's;
  // a stored gallery that no longer validates (prefixed with its name); AlreadyExists if a
  // stored name is already registered. On error nothing is added.
  //
  // Galleries that need an approximate index (GalleryLimits::approximate) are published
  // without it, searched exactly, and get it from a background thread one after another
  // (Gallery::UpdateApproximateIndex): a server with a 10^6-vector gallery serves seconds
  // sooner, at the price of exact (slower) searches until its index is built.
  absl::Status LoadFromStore();

  // Waits until the background build that LoadFromStore started has finished (tests,
  // benchmarks, and a caller that wants approximate search before it serves).
  void WaitForApproximateIndexes();

  // A new, empty gallery. InvalidArgument for a bad name (the message quotes the pattern),
  // options or descriptor spec (the descriptor registry's message); AlreadyExists;
  // ResourceExhausted at max_galleries; the store's error.
  absl::StatusOr<std::shared_ptr<Gallery>> Create(absl::string_view name,
                                                  const GalleryOptions& options);

  // Adds a whole gallery (an import, under stored.name), samples and times as given, in one
  // store write. Errors: Gallery::Restore's; FailedPrecondition if this server cannot
  // compute its descriptors (GallerySnapshot::incompatible()); AlreadyExists;
  // ResourceExhausted over max_galleries or max_samples_per_gallery; the store's error.
  // The gallery gets a fresh incarnation (StoredGallery::incarnation).
  absl::StatusOr<std::shared_ptr<Gallery>> Import(StoredGallery stored);

  // NotFound naming `name` (and no other gallery).
  absl::StatusOr<std::shared_ptr<Gallery>> Get(absl::string_view name) const;

  // Names, sorted.
  std::vector<std::string> List() const;
  // Every gallery, sorted by name, under one lock (List then Get would lock once per gallery
  // and skip those deleted in between).
  std::vector<std::shared_ptr<Gallery>> All() const;

  // NotFound, or the store's error (gallery kept).
  absl::Status Delete(absl::string_view name);

  // Replication, for a store shared by several servers: mirror a change another server has
  // already stored, without writing to the store (see Gallery::ApplyStoredAppend for sample
  // changes).
  //  - ApplyStoredGallery publishes `stored` (created or imported elsewhere, or reloaded after
  //    missed changes), replacing a gallery of that name, whose holders' later writes then
  //    fail NotFound; nothing if the gallery held is that incarnation at that version or
  //    later. Errors: Gallery::Restore's.
  //  - ApplyStoredDelete forgets gallery `name` if it is that incarnation (a gallery made
  //    again under the name since is kept).
  absl::Status ApplyStoredGallery(const StoredGallery& stored);
  void ApplyStoredDelete(absl::string_view name, uint64_t incarnation);

  size_t size() const;
  const GalleryLimits& limits() const { return limits_; }

 private:
  const GalleryLimits limits_;
  const std::shared_ptr<GalleryStore> store_;
  const CatchUpFunction catch_up_;

  // Publishes a validated new gallery: reserves the name, saves it to the store without the
  // lock, then publishes. `verb` and `exists_hint` shape the error messages.
  absl::StatusOr<std::shared_ptr<Gallery>> Add(std::shared_ptr<Gallery> gallery,
                                               const StoredGallery& stored, absl::string_view verb,
                                               absl::string_view exists_hint);

  // std::mutex, not absl::Mutex: see Gallery. Not held while a new gallery is written to the
  // store (pending_ reserves its name); held across a delete's store call, which is a rename.
  mutable std::mutex mu_;
  std::map<std::string, std::shared_ptr<Gallery>, std::less<>> galleries_ ABSL_GUARDED_BY(mu_);
  // Names being created or imported: taken, but not yet published.
  std::set<std::string, std::less<>> pending_ ABSL_GUARDED_BY(mu_);

  // The background build of approximate indexes after LoadFromStore; stop_ cancels it.
  std::atomic<bool> stop_{false};
  std::thread approximate_builder_;
};

}  // namespace shapeid

#endif  // SHAPEID_CORE_GALLERY_GALLERY_REGISTRY_H_
