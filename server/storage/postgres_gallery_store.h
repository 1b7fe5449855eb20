#ifndef SHAPEID_SERVER_STORAGE_POSTGRES_GALLERY_STORE_H_
#define SHAPEID_SERVER_STORAGE_POSTGRES_GALLERY_STORE_H_

#include <atomic>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "absl/base/thread_annotations.h"
#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "absl/time/time.h"
#include "core/gallery/gallery_store.h"
#include "server/storage/pg_connection.h"

namespace shapeid {

struct PostgresGalleryStoreOptions {
  // libpq connection string: "postgres://user@host:5432/db?sslmode=require" or
  // "host=... dbname=...". The password is best left to PGPASSWORD or ~/.pgpass (a Secret),
  // out of flags and process listings. Never logged or put in an error message by shapeid.
  std::string conninfo;
  // Connections for writes and catch-up reads (a listener has its own); at least 2.
  int pool_size = 4;
};

// One row of the change log: a committed change to a gallery, with its version after it.
struct LoggedChange {
  int64_t seq = 0;
  std::string gallery;
  int64_t incarnation = 0;
  uint64_t version = 0;
  std::string kind;  // create, append, remove, delete
  std::vector<int64_t> ids;
  absl::Time updated;
};

// Reads of the store inside one REPEATABLE READ snapshot, so that a gallery read whole and a
// position in the log agree even while other replicas write. Valid only inside the callback
// of PostgresGalleryStore::ReadSnapshot or PostgresListener::ReadSnapshot.
class PostgresSnapshot {
 public:
  explicit PostgresSnapshot(PgConnection& connection) : c_(connection) {}

  // The last sequence number pruned from the log (0 if none): a position below it has
  // missed changes that can no longer be read.
  absl::StatusOr<int64_t> LogFloor();
  // Names of every stored gallery.
  absl::StatusOr<std::vector<std::string>> GalleryNames();
  // Up to `limit` changes after `position`, in log order.
  absl::StatusOr<std::vector<LoggedChange>> ReadChangesAfter(int64_t position, int limit);
  // Gallery `name` whole (*found false: not stored).
  absl::StatusOr<StoredGallery> ReadGallery(absl::string_view name, bool* found);
  // The samples an append stored, in training order; fewer than `append.ids` when some were
  // removed since. DataLoss for a checksum mismatch.
  absl::StatusOr<std::vector<StoredSample>> ReadAppended(const LoggedChange& append);
  // A statement failed: every later read of this snapshot fails too.
  bool failed() const { return c_.InFailedTransaction(); }

 private:
  PgConnection& c_;
};

// A connection of its own that LISTENs for the store's change notifications. Not
// thread-safe (one follower thread).
class PostgresListener {
 public:
  explicit PostgresListener(std::unique_ptr<PgConnection> connection)
      : connection_(std::move(connection)) {}

  // Waits up to `timeout` for a notification: true if one came, false on timeout;
  // Unavailable if the connection broke.
  absl::StatusOr<bool> WaitForNotification(absl::Duration timeout);
  // True if notifications arrived with the last statement's reply (those sit in libpq's
  // queue, where WaitForNotification's poll cannot see them).
  bool TakeQueuedNotification();
  // `read` inside one snapshot on this connection, then COMMIT (ROLLBACK on error).
  absl::Status ReadSnapshot(const std::function<absl::Status(PostgresSnapshot&)>& read);
  // Deletes log rows older than the retention and raises the floor (best effort).
  void PruneLog();
  bool ok() const { return connection_->ok(); }

 private:
  const std::unique_ptr<PgConnection> connection_;
};

// Galleries in PostgreSQL, shared by any number of shapeid-server replicas. Each
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
// then catches up (its CatchUpFunction, the replication follower's) and retries
// (Gallery::RetryIfStale), so concurrent writers through different replicas never lose or
// duplicate samples, and assigned ids never collide. Change log rows are appended under one
// advisory lock, so their sequence numbers are in commit order and a reader never skips a
// change that commits late. Applying the log to a replica's galleries is not the store's job:
// server/replication/replication_follower.h reads it through ReadSnapshot and Listen.
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

  absl::Status SaveGallery(const StoredGallery& gallery) override;
  absl::Status DeleteGallery(absl::string_view name) override;
  absl::Status AppendSamples(absl::string_view name, absl::Span<const StoredSample> batch,
                             absl::Time updated, uint64_t version) override;
  absl::Status RemoveSamples(absl::string_view name, absl::Span<const uint64_t> ids,
                             absl::Time updated, uint64_t version) override;
  // Every gallery, in one snapshot of the database; remembers where the change log stood
  // (loaded_position), so following starts from there.
  absl::StatusOr<std::vector<StoredGallery>> LoadAll() override;
  // LoadAll's galleries, each followed by its trained head where one is kept.
  absl::Status Load(GalleryLoader& loader) override;
  // Keeps the head in shapeid_heads, by the gallery's incarnation; DeleteGallery drops it.
  absl::Status SaveHead(absl::string_view name, absl::string_view bytes) override;

  // The log position the last LoadAll read its galleries at (0 before).
  int64_t loaded_position() const { return loaded_position_.load(); }

  // `read` inside one snapshot on a pooled connection.
  absl::Status ReadSnapshot(const std::function<absl::Status(PostgresSnapshot&)>& read);
  // A new connection listening for change notifications; Unavailable if it cannot connect.
  absl::StatusOr<std::unique_ptr<PostgresListener>> Listen();

  // What this replica holds, for the write check: a follower that publishes a gallery read
  // from the store calls HeldIncarnation after publishing it; one that applies a delete calls
  // DroppedIncarnation (which forgets the name only if it still is that incarnation).
  void HeldIncarnation(absl::string_view name, int64_t incarnation);
  void DroppedIncarnation(absl::string_view name, int64_t incarnation);

 private:
  PostgresGalleryStore(PostgresGalleryStoreOptions options, std::unique_ptr<PgConnectionPool> pool);

  // `work` in one transaction on a pooled connection, opened with `begin`.
  template <typename F>
  absl::Status WithConnection(absl::string_view what, const F& work, const char* begin = "BEGIN");

  // The write path of AppendSamples and RemoveSamples: checks incarnation and version under
  // the gallery's row lock, runs `change`, logs it, commits.
  absl::Status ChangeSamples(absl::string_view name, absl::string_view what, absl::Time updated,
                             uint64_t version, absl::string_view kind,
                             absl::Span<const int64_t> ids,
                             const std::function<absl::Status(PgConnection&, int64_t)>& change);

  const PostgresGalleryStoreOptions options_;
  const std::unique_ptr<PgConnectionPool> pool_;

  // Incarnation of each gallery this replica holds, for the write check.
  mutable std::mutex incarnations_mu_;
  std::map<std::string, int64_t, std::less<>> incarnations_ ABSL_GUARDED_BY(incarnations_mu_);
  std::atomic<int64_t> loaded_position_{0};
};

}  // namespace shapeid

#endif  // SHAPEID_SERVER_STORAGE_POSTGRES_GALLERY_STORE_H_
