#ifndef SHAPEID_SERVER_STORAGE_POSTGRES_GALLERY_STORE_H_
#define SHAPEID_SERVER_STORAGE_POSTGRES_GALLERY_STORE_H_

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "absl/base/thread_annotations.h"
#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/time/time.h"
#include "core/gallery/gallery_registry.h"
#include "core/gallery/gallery_store.h"
#include "server/logger.h"
#include "server/storage/pg_connection.h"

namespace shapeid {

struct PostgresGalleryStoreOptions {
  // libpq connection string: "postgres://user@host:5432/db?sslmode=require" or
  // "host=... dbname=...". The password is best left to PGPASSWORD or ~/.pgpass (a Secret),
  // out of flags and process listings. Never logged or put in an error message by shapeid.
  std::string conninfo;
  // How stale a replica may get. Changes arrive at once by LISTEN/NOTIFY; the change log is
  // also read every `refresh`, which bounds the delay if a notification is lost, and the
  // connection is checked as often: a replica that cannot reach PostgreSQL for longer stops
  // serving (see StartFollowing).
  absl::Duration refresh = absl::Seconds(1);
  // Connections for writes and catch-up reads (the follower has its own); at least 2.
  int pool_size = 4;
  // Where the follower reports changes it could not apply and lost connections; null: a
  // text logger on stderr.
  std::shared_ptr<const Logger> logger;
};

// Galleries in PostgreSQL, shared by any number of shapeid-server replicas (issue 11). Each
// replica keeps every gallery in memory for Classify, exactly as with the embedded store;
// PostgreSQL is the truth and the channel between replicas.
//
// Tables (created if missing; names prefixed shapeid_):
//   galleries  one row per gallery: options, versions, times, and `incarnation`, a number
//              drawn afresh each time the name is created, so a gallery deleted and made
//              again under the same name is never mistaken for the old one;
//   samples    one row per sample: incarnation, id, label, features (float32 bytes), CRC-32,
//              and a global position that keeps training order;
//   changes    the change log: one row per committed change (create, append, remove,
//              delete), with the gallery's version after it.
//
// Durability: every call is one transaction, committed (PostgreSQL's synchronous_commit) before
// it returns OK, so the embedded store's contract holds: "the call returned OK" means "the
// change survives a restart" (of any replica, or of PostgreSQL).
//
// Consistency between replicas: a write locks its gallery's row and is refused Aborted when
// this replica's copy is not at the stored version (another replica wrote since); the gallery
// then catches up (CatchUp) and retries (Gallery::RetryIfStale), so concurrent writers through
// different replicas never lose or duplicate samples, and assigned ids never collide. Change
// log rows are appended under one advisory lock, so their sequence numbers are in commit order
// and a reader never skips a change that commits late.
//
// Errors: Unavailable when PostgreSQL cannot be reached (the call changed nothing, or, if the
// connection died during COMMIT, may have: PostgreSQL cannot say); AlreadyExists for a name
// taken by another replica meanwhile; Internal for anything else PostgreSQL reports; DataLoss
// for a stored row whose checksum does not match.
class PostgresGalleryStore final : public GalleryStore {
 public:
  // Connects and creates the tables if needed. Unavailable if PostgreSQL cannot be reached.
  static absl::StatusOr<std::unique_ptr<PostgresGalleryStore>> Open(
      PostgresGalleryStoreOptions options);
  ~PostgresGalleryStore() override;  // stops following

  absl::Status SaveGallery(const StoredGallery& gallery) override;
  absl::Status DeleteGallery(absl::string_view name) override;
  absl::Status AppendSamples(absl::string_view name, absl::Span<const StoredSample> batch,
                             absl::Time updated, uint64_t version) override;
  absl::Status RemoveSamples(absl::string_view name, absl::Span<const uint64_t> ids,
                             absl::Time updated, uint64_t version) override;
  // Every gallery, in one snapshot of the database; remembers where the change log stood, so
  // following starts from there.
  absl::StatusOr<std::vector<StoredGallery>> LoadAll() override;
  bool shared() const override { return true; }
  absl::Status CatchUp(absl::string_view name) override;

  // Keeps `registry` (loaded from this store) in step with the other replicas' writes, from a
  // thread of its own, until the store is destroyed (destroy the store before the registry).
  // `reachable(false)` is called when PostgreSQL has not been reachable for `refresh` (the
  // replica's copy may then be stale; the server stops serving), `reachable(true)` once it is
  // back and every change missed meanwhile has been applied. Call once, after LoadAll.
  void StartFollowing(GalleryRegistry* registry, std::function<void(bool)> reachable);

  // Stops following and waits for the thread (within about refresh / 10). Before the
  // registry goes; the destructor calls it too.
  void StopFollowing();

  // Applies every change logged so far (tests; the follower does it on its own).
  absl::Status Sync();

  // Changes applied from other replicas, and the last time a change was applied or the log
  // was found up to date (tests, metrics).
  int64_t changes_applied() const { return changes_applied_.load(); }
  // Whether the follower reaches PostgreSQL within the bound, and when it last read the log
  // to its end (metrics: how stale this replica may be). Before StartFollowing: true, now.
  bool reachable() const { return reachable_now_.load(); }
  absl::Time last_sync() const { return absl::FromUnixNanos(last_sync_nanos_.load()); }

 private:
  struct Change;
  class Pool;

  PostgresGalleryStore(PostgresGalleryStoreOptions options, std::unique_ptr<Pool> pool);

  // `work` in one transaction on a pooled connection, opened with `begin`.
  template <typename F>
  absl::Status WithConnection(absl::string_view what, const F& work,
                              const char* begin = "BEGIN");

  // The write path of AppendSamples and RemoveSamples: checks incarnation and version under
  // the gallery's row lock, runs `change`, logs it, commits.
  absl::Status ChangeSamples(absl::string_view name, absl::string_view what, absl::Time updated,
                             uint64_t version, absl::string_view kind,
                             absl::Span<const int64_t> ids,
                             const std::function<absl::Status(PgConnection&, int64_t)>& change);

  // Reads the change log past applied_seq_ and applies it to registry_, in order. Holds
  // apply_mu_ (one applier at a time; CatchUp and the follower share it).
  absl::Status ApplyPending(PgConnection& connection) ABSL_EXCLUSIVE_LOCKS_REQUIRED(apply_mu_);
  absl::Status ApplyOne(PgConnection& connection, const Change& change)
      ABSL_EXCLUSIVE_LOCKS_REQUIRED(apply_mu_);
  // Re-reads gallery `name` whole and publishes it (a create, or changes missed).
  absl::Status Reload(PgConnection& connection, const std::string& name)
      ABSL_EXCLUSIVE_LOCKS_REQUIRED(apply_mu_);
  // Gallery `name` whole (*found false: not stored). Call inside one snapshot (REPEATABLE
  // READ): its row and its samples are two statements.
  absl::StatusOr<StoredGallery> ReadGallery(PgConnection& connection, absl::string_view name,
                                            bool* found);

  void Follow();
  void SetReachable(bool reachable);

  const PostgresGalleryStoreOptions options_;
  const std::unique_ptr<Pool> pool_;

  // Incarnation of each gallery this replica holds, for the write check.
  mutable std::mutex incarnations_mu_;
  std::map<std::string, int64_t, std::less<>> incarnations_ ABSL_GUARDED_BY(incarnations_mu_);

  std::mutex apply_mu_;
  int64_t applied_seq_ ABSL_GUARDED_BY(apply_mu_) = 0;
  GalleryRegistry* registry_ = nullptr;  // set once by StartFollowing

  std::function<void(bool)> reachable_callback_;
  bool reachable_ = true;  // follower thread only
  std::atomic<int64_t> changes_applied_{0};
  std::atomic<bool> reachable_now_{true};
  std::atomic<int64_t> last_sync_nanos_{absl::ToUnixNanos(absl::Now())};
  std::shared_ptr<const Logger> logger_;

  std::mutex stop_mu_;
  std::condition_variable stop_cv_;
  bool stop_ ABSL_GUARDED_BY(stop_mu_) = false;
  std::thread follower_;
};

}  // namespace shapeid

#endif  // SHAPEID_SERVER_STORAGE_POSTGRES_GALLERY_STORE_H_
