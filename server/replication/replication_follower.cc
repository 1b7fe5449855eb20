#include "server/replication/replication_follower.h"

#include <algorithm>
#include <chrono>
#include <map>
#include <utility>
#include <vector>

#include "absl/strings/str_cat.h"
#include "core/status_macros.h"

namespace shapeid {
namespace {

// Changes read from the log per statement.
constexpr int kChangesPerRead = 1000;

}  // namespace

ReplicationFollower::ReplicationFollower(std::shared_ptr<PostgresGalleryStore> store,
                                         ReplicationFollowerOptions options)
    : store_(std::move(store)),
      options_(std::move(options)),
      logger_(options_.logger != nullptr ? options_.logger : std::make_shared<const Logger>()) {}

ReplicationFollower::~ReplicationFollower() { Stop(); }

void ReplicationFollower::Stop() {
  {
    std::lock_guard<std::mutex> lock(stop_mu_);
    stop_ = true;
  }
  stop_cv_.notify_all();
  if (follower_.joinable()) follower_.join();
}

void ReplicationFollower::Start(GalleryRegistry* registry, std::function<void(bool)> reachable) {
  {
    std::lock_guard<std::mutex> lock(apply_mu_);
    registry_ = registry;
    applied_seq_ = store_->loaded_position();
  }
  reachable_callback_ = std::move(reachable);
  follower_ = std::thread([this] { Follow(); });
}

absl::Status ReplicationFollower::Sync() {
  std::lock_guard<std::mutex> lock(apply_mu_);
  if (registry_ == nullptr) return absl::OkStatus();  // not following: nothing to apply to
  return store_->ReadSnapshot([&](PostgresSnapshot& snapshot) ABSL_NO_THREAD_SAFETY_ANALYSIS {
    return ApplyPending(snapshot);
  });
}

absl::Status ReplicationFollower::ApplyPending(PostgresSnapshot& snapshot) {
  for (;;) {
    SHAPEID_ASSIGN_OR_RETURN(const int64_t floor, snapshot.LogFloor());
    // Rows after ours were pruned (this replica was away longer than the log keeps them):
    // what they said is lost, so every gallery is read again (in this snapshot), and the log
    // is followed from the floor.
    if (floor > applied_seq_) {
      SHAPEID_ASSIGN_OR_RETURN(std::vector<std::string> names, snapshot.GalleryNames());
      std::map<std::string, bool> stored;
      for (std::string& name : names) stored[std::move(name)] = true;
      for (const std::string& held : registry_->List()) {
        if (stored.count(held) == 0) {
          auto gallery = registry_->Get(held);
          if (gallery.ok())
            registry_->ApplyStoredDelete(held, (*gallery)->Snapshot()->incarnation());
        }
      }
      for (const auto& [name, unused] : stored) SHAPEID_RETURN_IF_ERROR(Reload(snapshot, name));
      applied_seq_ = floor;
    }
    SHAPEID_ASSIGN_OR_RETURN(std::vector<LoggedChange> changes,
                             snapshot.ReadChangesAfter(applied_seq_, kChangesPerRead));
    if (changes.empty()) return absl::OkStatus();
    for (const LoggedChange& change : changes) {
      const absl::Status applied = ApplyOne(snapshot, change);
      // Unavailable (PostgreSQL went away) or a failed statement (which aborts the snapshot's
      // transaction, so every later read would fail too): this change is applied on the next
      // attempt. Anything else (a gallery damaged in the store, one this server cannot
      // restore) must not stop the log for every other gallery: said, and passed.
      if (absl::IsUnavailable(applied) || snapshot.failed()) return applied;
      if (!applied.ok()) {
        logger_->Error(
            "a change cannot be applied; this replica's copy may differ from the store until "
            "it restarts",
            {{"gallery", change.gallery}, {"seq", change.seq}, {"error", applied.ToString()}});
      }
      applied_seq_ = change.seq;
    }
  }
}

absl::Status ReplicationFollower::ApplyOne(PostgresSnapshot& snapshot, const LoggedChange& change) {
  absl::StatusOr<std::shared_ptr<Gallery>> held = registry_->Get(change.gallery);
  const bool same =
      held.ok() && (*held)->Snapshot()->incarnation() == static_cast<uint64_t>(change.incarnation);
  if (change.kind == "delete") {
    if (same) {
      registry_->ApplyStoredDelete(change.gallery, static_cast<uint64_t>(change.incarnation));
      store_->DroppedIncarnation(change.gallery, change.incarnation);
      changes_applied_.fetch_add(1);
    }
    return absl::OkStatus();
  }
  if (change.kind == "create") {
    if (same) return absl::OkStatus();  // made here, or already reloaded
    return Reload(snapshot, change.gallery);
  }
  // append / remove: of the gallery this replica holds, else a later change explains it (a
  // delete, a create) or an earlier reload already holds it.
  if (!same) return absl::OkStatus();
  const std::shared_ptr<Gallery>& gallery = *held;
  if (change.version <= gallery->Snapshot()->version()) return absl::OkStatus();  // our own
  absl::Status applied;
  if (change.kind == "append") {
    SHAPEID_ASSIGN_OR_RETURN(std::vector<StoredSample> samples, snapshot.ReadAppended(change));
    // Fewer rows: some were removed by a later change; the whole gallery is read instead.
    if (samples.size() != change.ids.size()) return Reload(snapshot, change.gallery);
    applied = gallery->ApplyStoredAppend(samples, change.updated, change.version);
  } else if (change.kind == "remove") {
    std::vector<uint64_t> ids;
    for (int64_t id : change.ids) ids.push_back(FromPgId(id));
    applied = gallery->ApplyStoredRemove(ids, change.updated, change.version);
  } else {
    return absl::DataLossError(
        absl::StrCat("change ", change.seq, " has unknown kind '", change.kind, "'"));
  }
  if (applied.ok()) {
    changes_applied_.fetch_add(1);
    return applied;
  }
  // Missed changes (a gap in the versions), or a copy that no longer matches the log (a
  // duplicate or absent id): the store is the truth, so read the gallery whole. Never leave
  // the change unapplied: the log would stop here and the replica with it.
  logger_->Warning(
      "a change did not apply; reloading the gallery",
      {{"gallery", change.gallery}, {"seq", change.seq}, {"error", applied.ToString()}});
  return Reload(snapshot, change.gallery);
}

absl::Status ReplicationFollower::Reload(PostgresSnapshot& snapshot, const std::string& name) {
  bool found = false;
  SHAPEID_ASSIGN_OR_RETURN(StoredGallery g, snapshot.ReadGallery(name, &found));
  if (!found) return absl::OkStatus();  // deleted since; its delete change follows
  SHAPEID_RETURN_IF_ERROR(registry_->ApplyStoredGallery(g));
  // After publishing: until now, a write through the copy this replaces fails the store's
  // incarnation check.
  store_->HeldIncarnation(name, static_cast<int64_t>(g.incarnation));
  changes_applied_.fetch_add(1);
  return absl::OkStatus();
}

void ReplicationFollower::SetReachable(bool reachable) {
  if (reachable == reachable_) return;
  reachable_ = reachable;
  reachable_now_.store(reachable);
  if (reachable_callback_) reachable_callback_(reachable);
}

void ReplicationFollower::Follow() {
  std::unique_ptr<PostgresListener> listener;
  absl::Time last_ok = absl::Now();
  absl::Time next_poll = absl::Now();
  absl::Time next_prune = absl::Now() + absl::Minutes(1);
  std::string last_error;
  bool notified_during_sync = false;
  // A stop and the poll deadline are noticed within a tenth of `refresh`.
  const absl::Duration wait = std::max(
      absl::Milliseconds(1), absl::Milliseconds(absl::ToInt64Milliseconds(options_.refresh) / 10));
  for (;;) {
    {
      std::lock_guard<std::mutex> lock(stop_mu_);
      if (stop_) return;
    }
    bool poll_now = absl::Now() >= next_poll || notified_during_sync;
    notified_during_sync = false;
    if (listener == nullptr) {
      absl::StatusOr<std::unique_ptr<PostgresListener>> fresh = store_->Listen();
      if (fresh.ok()) {
        listener = *std::move(fresh);
        poll_now = true;  // whatever was missed while away
      }
    }
    if (listener != nullptr) {
      absl::StatusOr<bool> notified = listener->WaitForNotification(wait);
      if (!notified.ok()) {
        listener.reset();
      } else if (*notified) {
        poll_now = true;
      }
    } else {
      std::unique_lock<std::mutex> lock(stop_mu_);
      stop_cv_.wait_for(lock, std::chrono::milliseconds(absl::ToInt64Milliseconds(wait)));
    }
    if (listener != nullptr && poll_now) {
      absl::Status synced;
      {
        std::lock_guard<std::mutex> lock(apply_mu_);
        synced =
            listener->ReadSnapshot([&](PostgresSnapshot& snapshot) ABSL_NO_THREAD_SAFETY_ANALYSIS {
              return ApplyPending(snapshot);
            });
      }
      // Notifications for changes committed during that read came with its COMMIT's reply.
      notified_during_sync = listener->TakeQueuedNotification();
      if (!synced.ok() && synced.ToString() != last_error) {
        // Once per distinct error: a replica that cannot apply the log says why.
        last_error = synced.ToString();
        logger_->Error("cannot apply other replicas' changes", {{"error", last_error}});
      }
      if (synced.ok()) {
        last_error.clear();
        last_ok = absl::Now();
        last_sync_nanos_.store(absl::ToUnixNanos(last_ok));
        // Twice per bound: a healthy replica always has a success younger than `refresh`, so
        // the check below never flaps between polls.
        next_poll = last_ok + options_.refresh / 2;
        SetReachable(true);
      } else if (!listener->ok()) {
        listener.reset();
      }
      if (synced.ok() && absl::Now() >= next_prune) {
        next_prune = absl::Now() + absl::Minutes(1);
        listener->PruneLog();
      }
    }
    if (absl::Now() - last_ok > options_.refresh) SetReachable(false);
  }
}

}  // namespace shapeid
