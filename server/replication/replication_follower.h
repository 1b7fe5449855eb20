#ifndef SHAPEID_SERVER_REPLICATION_REPLICATION_FOLLOWER_H_
#define SHAPEID_SERVER_REPLICATION_REPLICATION_FOLLOWER_H_

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>

#include "absl/base/thread_annotations.h"
#include "absl/status/status.h"
#include "absl/strings/string_view.h"
#include "absl/time/time.h"
#include "core/gallery/gallery_registry.h"
#include "server/ops/logger.h"
#include "server/storage/postgres_gallery_store.h"

namespace shapeid {

struct ReplicationFollowerOptions {
  // How stale a replica may get. Changes arrive at once by LISTEN/NOTIFY; the change log is
  // also read every `refresh`, which bounds the delay if a notification is lost, and the
  // connection is checked as often: a replica that cannot reach PostgreSQL for longer stops
  // serving (see Start). Positive.
  absl::Duration refresh = absl::Seconds(1);
  // Where changes that could not be applied and lost connections are reported; null: a text
  // logger on stderr.
  std::shared_ptr<const Logger> logger;
};

// Keeps a registry loaded from a shared PostgreSQL store in step with the other replicas'
// writes: it reads the store's change log from the position the registry was loaded at and
// applies each change (GalleryRegistry::ApplyStored*, Gallery::ApplyStored*), reloading a
// gallery whole when a change does not apply. The only writer into the registry from outside.
//
// Thread-safe. One applier at a time: the follower's thread and CatchUp share a mutex.
class ReplicationFollower {
 public:
  ReplicationFollower(std::shared_ptr<PostgresGalleryStore> store,
                      ReplicationFollowerOptions options);
  ~ReplicationFollower();  // stops following

  ReplicationFollower(const ReplicationFollower&) = delete;
  ReplicationFollower& operator=(const ReplicationFollower&) = delete;

  // Follows from a thread of its own, from the position `registry` was loaded at (call once,
  // after registry->LoadFromStore()), until Stop. `registry` outlives the follower or Stop.
  // `reachable(false)` is called when PostgreSQL has not been reachable for `refresh` (the
  // replica's copy may then be stale; the server stops serving), `reachable(true)` once it is
  // back and every change missed meanwhile has been applied.
  void Start(GalleryRegistry* registry, std::function<void(bool)> reachable);
  // Stops following and waits for the thread (within about refresh / 10). Idempotent; Sync
  // and CatchUp still work afterwards.
  void Stop();

  // Applies every change logged so far. OK and nothing done before Start.
  absl::Status Sync();
  // The registry's CatchUpFunction: after a write of gallery `name` was refused as stale.
  absl::Status CatchUp(absl::string_view /*name*/) { return Sync(); }

  // Changes applied from other replicas (tests, metrics).
  int64_t changes_applied() const { return changes_applied_.load(); }
  // Whether the follower reaches PostgreSQL within the bound, and when it last read the log
  // to its end (metrics: how stale this replica may be). Before Start: true, construction.
  bool reachable() const { return reachable_now_.load(); }
  absl::Time last_sync() const { return absl::FromUnixNanos(last_sync_nanos_.load()); }

 private:
  // Reads the change log past applied_seq_ in `snapshot` and applies it, in order.
  absl::Status ApplyPending(PostgresSnapshot& snapshot) ABSL_EXCLUSIVE_LOCKS_REQUIRED(apply_mu_);
  absl::Status ApplyOne(PostgresSnapshot& snapshot, const LoggedChange& change)
      ABSL_EXCLUSIVE_LOCKS_REQUIRED(apply_mu_);
  // Re-reads gallery `name` whole and publishes it (a create, or changes missed).
  absl::Status Reload(PostgresSnapshot& snapshot, const std::string& name)
      ABSL_EXCLUSIVE_LOCKS_REQUIRED(apply_mu_);

  void Follow();
  void SetReachable(bool reachable);

  const std::shared_ptr<PostgresGalleryStore> store_;
  const ReplicationFollowerOptions options_;
  const std::shared_ptr<const Logger> logger_;

  std::mutex apply_mu_;
  int64_t applied_seq_ ABSL_GUARDED_BY(apply_mu_) = 0;
  GalleryRegistry* registry_ ABSL_GUARDED_BY(apply_mu_) = nullptr;  // set by Start

  std::function<void(bool)> reachable_callback_;
  bool reachable_ = true;  // follower thread only
  std::atomic<int64_t> changes_applied_{0};
  std::atomic<bool> reachable_now_{true};
  std::atomic<int64_t> last_sync_nanos_{absl::ToUnixNanos(absl::Now())};

  std::mutex stop_mu_;
  std::condition_variable stop_cv_;
  bool stop_ ABSL_GUARDED_BY(stop_mu_) = false;
  std::thread follower_;
};

}  // namespace shapeid

#endif  // SHAPEID_SERVER_REPLICATION_REPLICATION_FOLLOWER_H_
