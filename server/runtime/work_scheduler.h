#ifndef SHAPEID_SERVER_RUNTIME_WORK_SCHEDULER_H_
#define SHAPEID_SERVER_RUNTIME_WORK_SCHEDULER_H_

// Where the service's work runs: describing, searching and store writes, on threads of its
// own, so that gRPC's threads only move bytes and answer health checks, however heavy the
// calls. gRPC-free.
//
// Work is admitted by its estimated cost into one of three lanes, each with its own threads:
//   cheap  work estimated under WorkSchedulerOptions::heavy_cost (a 1,024-point Classify):
//          never queued behind heavy work;
//   heavy  the rest (a 10-million-point Describe, a search of a huge gallery), on fewer
//          threads than the machine has cores and at a lower OS priority, so that heavy
//          calls cannot take every core from the cheap ones and from gRPC;
//   store  writes that wait on the disk or the database (commits, creations, removals).
// Within a lane, callers are served fairly by cost (start-time fair queuing): a caller with
// a long backlog does not delay another caller's next piece of work by more than about one
// piece of its own. Work whose deadline has passed, or whose call was cancelled, is dropped
// before it starts. Work that needs working memory starts only when the memory budget
// (server/runtime/memory_budget.h) grants it, and holds it while it runs. Work refused by its own
// caller's share never delays other callers' work; when none of that caller's work is
// running to give memory back, it is refused (ResourceExhausted) after a second.

#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "absl/base/thread_annotations.h"
#include "absl/status/status.h"
#include "absl/strings/string_view.h"
#include "absl/time/time.h"
#include "server/runtime/memory_budget.h"

namespace shapeid {

enum class WorkLane { kCheap = 0, kHeavy = 1, kStore = 2 };
inline constexpr int kNumWorkLanes = 3;
const char* WorkLaneName(WorkLane lane);  // "cheap", "heavy", "store"

struct WorkSchedulerOptions {
  // Threads of the cheap lane; 0: the machine's cores, at least 2.
  int cheap_workers = 0;
  // Threads of the heavy lane; 0: three quarters of the cores, at least 1 and always at least
  // one core fewer than the machine has (so 1 on a 2-core machine).
  int heavy_workers = 0;
  // Threads of the store lane: writes mostly wait on fsync or the network, not the CPU.
  int store_workers = 2;
  // The OS priority (nice) of the heavy lane's threads, 0-19: under full load the kernel
  // gives them a small share of a core that gRPC or the cheap lane also wants.
  int heavy_nice = 10;
  // Work estimated to cost this much CPU time or more goes to the heavy lane.
  absl::Duration heavy_cost = absl::Milliseconds(20);
  // Pieces of work waiting in one lane. A lane holding this many admits more only from a
  // caller with fewer waiting there than its fair share (max_queued divided among the callers
  // with work in the lane), and nothing past twice this: a caller that floods a lane is
  // refused (ResourceExhausted) while the others keep their share.
  int64_t max_queued = 4096;
  // Estimated CPU time one caller may have waiting, over all lanes; more is refused, so that
  // one caller cannot queue hours of work ahead of everyone's deadlines.
  absl::Duration max_caller_backlog = absl::Minutes(2);
};

// What the scheduler needs to know of one piece of work.
struct WorkOrder {
  std::string caller;   // who it is for, for fairness: "key:NAME" or the client's host
  absl::Duration cost;  // estimated CPU time
  size_t memory = 0;    // working memory it needs while it runs, taken from the budget
  // Memory the call holds already and keeps while this runs (its cloud): with `memory`, it
  // must fit one caller's share of the budget, or the work could never start.
  size_t held = 0;
  bool store = false;  // waits on the gallery store rather than the CPU: the store lane
  // Dropped (DeadlineExceeded) if not started by then.
  absl::Time deadline = absl::InfiniteFuture();
  // Dropped (Cancelled) if this returns true before it starts; may be empty. Called under
  // the scheduler's lock, so it must be quick and must not call the scheduler.
  std::function<bool()> cancelled;
};

// How a piece of work begins.
struct WorkStart {
  // OK: run. DeadlineExceeded or Cancelled: the work was dropped; do not run it, end the
  // call with this status.
  absl::Status status;
  WorkLane lane = WorkLane::kCheap;
  absl::Duration waited;  // from Submit to now
};

// Thread-safe.
class WorkScheduler {
 public:
  // `budget` may be null: working memory is then not bounded.
  WorkScheduler(WorkSchedulerOptions options, std::shared_ptr<MemoryBudget> budget);
  // Stop(), then waits for the threads.
  ~WorkScheduler();
  WorkScheduler(const WorkScheduler&) = delete;
  WorkScheduler& operator=(const WorkScheduler&) = delete;

  // Queues `work`, to be called exactly once on one of the scheduler's threads: with OK when
  // it may run (its memory granted and held until it returns), or with the status it was
  // dropped with. Refused at once, `work` never called: ResourceExhausted when the caller has
  // its share of the lane's queue (max_queued), its backlog would pass max_caller_backlog, or
  // the memory can never be granted (order.memory + order.held over a caller's share of the
  // budget); each message names the limit and its flag. Unavailable once stopped. The
  // order's cost counts in its caller's backlog from here until the work is started or
  // dropped, exactly once.
  absl::Status Submit(WorkOrder order, std::function<void(const WorkStart&)> work);

  // The lane `order` would go to.
  WorkLane LaneFor(const WorkOrder& order) const;

  // Drops everything queued (Cancelled: "shutting down") and refuses new work. Work already
  // running finishes. Idempotent.
  void Stop();

  struct LaneStats {
    int workers = 0;
    int running = 0;
    int64_t queued = 0;          // pieces
    absl::Duration queued_cost;  // their estimated CPU time
    int64_t queued_callers = 0;  // callers with work waiting in the lane
  };
  LaneStats stats(WorkLane lane) const;

  // The callers' backlogs: estimated work admitted and not yet started or dropped. `total`
  // (the sum over callers) always equals `queued` (the sum over the lanes' queues); debug
  // builds assert it after every change. Both return to zero when the server is idle.
  struct BacklogStats {
    absl::Duration total;
    absl::Duration queued;
    int64_t callers = 0;  // callers with a backlog
  };
  BacklogStats backlog() const;
  // One caller's backlog (zero when it has none).
  absl::Duration backlog(absl::string_view caller) const;
  const WorkSchedulerOptions& options() const { return options_; }

 private:
  struct Job {
    WorkOrder order;
    std::function<void(const WorkStart&)> work;
    absl::Time submitted;
    // Since when its memory has been refused by its own caller's share while none of that
    // caller's work ran; InfiniteFuture: not so.
    absl::Time own_share_blocked_since = absl::InfiniteFuture();
  };
  // Queued in the order of their start tags (start-time fair queuing), then of arrival.
  using Tag = std::pair<double, uint64_t>;
  struct Lane {
    int workers = 0;
    int running = 0;
    double virtual_time = 0;  // the start tag of the work dispatched last, in seconds
    std::map<std::string, double, std::less<>> last_finish;  // per caller
    std::map<Tag, Job> queue;
    absl::Duration queued_cost;                                    // the sum of the queue's costs
    std::map<std::string, int64_t, std::less<>> queued_by_caller;  // pieces in `queue`
    std::condition_variable ready;
  };
  // A job taken out of the queue, with what it needs to run or be told it was dropped.
  struct Taken {
    Job job;
    WorkStart start;
    MemoryBudget::Grant grant;
  };

  void Work(WorkLane lane);
  // Why queued work must not start (past its deadline, cancelled, stopping), or OK.
  absl::Status DropReasonLocked(const WorkOrder& order, absl::Time now) const
      ABSL_EXCLUSIVE_LOCKS_REQUIRED(mu_);
  // Moves the job at `it` to `dropped` with `status`; returns the next one.
  std::map<Tag, Job>::iterator DropLocked(WorkLane lane, std::map<Tag, Job>::iterator it,
                                          absl::Status status, absl::Time now,
                                          std::vector<Taken>* dropped)
      ABSL_EXCLUSIVE_LOCKS_REQUIRED(mu_);
  // Moves every job that must not start to `dropped`.
  void SweepLocked(absl::Time now, std::vector<Taken>* dropped) ABSL_EXCLUSIVE_LOCKS_REQUIRED(mu_);
  // The next job of `lane` that may start now, with its memory granted, if any; jobs it
  // finds that must not start go to `dropped`.
  bool TakeLocked(WorkLane lane, absl::Time now, Taken* taken, std::vector<Taken>* dropped)
      ABSL_EXCLUSIVE_LOCKS_REQUIRED(mu_);
  // Removes the job at `it` from its lane and releases its caller's backlog and share: the
  // one place queued work leaves the queue, whatever ends it.
  Job UnqueueLocked(Lane& lane, std::map<Tag, Job>::iterator it) ABSL_EXCLUSIVE_LOCKS_REQUIRED(mu_);
  // Debug builds: the sum of the callers' backlogs equals the queued work.
  void CheckBacklogLocked() const ABSL_EXCLUSIVE_LOCKS_REQUIRED(mu_);
  // Pieces of `caller`'s work running now, in every lane.
  int RunningLocked(absl::string_view caller) const ABSL_EXCLUSIVE_LOCKS_REQUIRED(mu_);
  // ResourceExhausted when `caller` may not queue more in `lane` (see max_queued).
  absl::Status ShareRefusalLocked(WorkLane lane, absl::string_view caller) const
      ABSL_EXCLUSIVE_LOCKS_REQUIRED(mu_);

  const WorkSchedulerOptions options_;
  const std::shared_ptr<MemoryBudget> budget_;

  mutable std::mutex mu_;
  Lane lanes_[kNumWorkLanes] ABSL_GUARDED_BY(mu_);
  std::map<std::string, absl::Duration, std::less<>> backlog_ ABSL_GUARDED_BY(mu_);
  std::map<std::string, int, std::less<>> running_by_caller_ ABSL_GUARDED_BY(mu_);
  uint64_t next_seq_ ABSL_GUARDED_BY(mu_) = 0;
  bool stopping_ ABSL_GUARDED_BY(mu_) = false;
  int sleepers_ ABSL_GUARDED_BY(mu_) = 0;  // workers waiting without a timeout
  absl::Time last_sweep_ ABSL_GUARDED_BY(mu_) = absl::InfinitePast();
  std::vector<std::thread> threads_;
};

}  // namespace shapeid

#endif  // SHAPEID_SERVER_RUNTIME_WORK_SCHEDULER_H_
