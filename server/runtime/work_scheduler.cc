#include "server/runtime/work_scheduler.h"

#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <algorithm>
#include <cassert>
#include <utility>

#include "absl/strings/str_cat.h"
#include "absl/time/clock.h"
#include "server/runtime/machine_limits.h"

namespace shapeid {
namespace {

// How often queued work is checked for passed deadlines and cancelled calls while some is
// waiting.
constexpr absl::Duration kSweepInterval = absl::Milliseconds(20);
// Work that needs at most this much memory may start while an earlier piece of its lane
// waits for the budget (a big piece waits for memory; small ones need not wait behind it).
constexpr size_t kSmallMemory = size_t{1} << 20;
// How long work refused by its own caller's share of the budget, while none of that caller's
// work runs, waits before it is refused (see TakeLocked).
constexpr absl::Duration kOwnShareGrace = absl::Seconds(1);

int Cores() { return UsableCores(); }

int CheapWorkers(const WorkSchedulerOptions& options) {
  return options.cheap_workers > 0 ? options.cheap_workers : std::max(2, Cores());
}

int HeavyWorkers(const WorkSchedulerOptions& options) {
  if (options.heavy_workers > 0) return options.heavy_workers;
  const int cores = Cores();
  return std::max(1, std::min(cores - 1, cores * 3 / 4));
}

}  // namespace

const char* WorkLaneName(WorkLane lane) {
  switch (lane) {
    case WorkLane::kCheap:
      return "cheap";
    case WorkLane::kHeavy:
      return "heavy";
    case WorkLane::kStore:
      return "store";
  }
  return "cheap";
}

WorkScheduler::WorkScheduler(WorkSchedulerOptions options, std::shared_ptr<MemoryBudget> budget)
    : options_(std::move(options)), budget_(std::move(budget)) {
  const int workers[kNumWorkLanes] = {CheapWorkers(options_), HeavyWorkers(options_),
                                      std::max(1, options_.store_workers)};
  {
    std::lock_guard<std::mutex> lock(mu_);
    for (int lane = 0; lane < kNumWorkLanes; ++lane) lanes_[lane].workers = workers[lane];
  }
  for (int lane = 0; lane < kNumWorkLanes; ++lane) {
    for (int i = 0; i < workers[lane]; ++i) {
      threads_.emplace_back([this, lane] { Work(static_cast<WorkLane>(lane)); });
    }
  }
}

WorkScheduler::~WorkScheduler() {
  Stop();
  for (std::thread& thread : threads_) thread.join();
}

void WorkScheduler::Stop() {
  std::lock_guard<std::mutex> lock(mu_);
  stopping_ = true;
  for (Lane& lane : lanes_) lane.ready.notify_all();
}

WorkLane WorkScheduler::LaneFor(const WorkOrder& order) const {
  if (order.store) return WorkLane::kStore;
  return order.cost >= options_.heavy_cost ? WorkLane::kHeavy : WorkLane::kCheap;
}

absl::Status WorkScheduler::ShareRefusalLocked(WorkLane which, absl::string_view caller) const {
  const Lane& lane = lanes_[static_cast<int>(which)];
  const int64_t queued = static_cast<int64_t>(lane.queue.size());
  if (queued < options_.max_queued) return absl::OkStatus();
  const auto found = lane.queued_by_caller.find(caller);
  const int64_t mine = found == lane.queued_by_caller.end() ? 0 : found->second;
  const int64_t callers = static_cast<int64_t>(lane.queued_by_caller.size()) + (mine == 0 ? 1 : 0);
  const int64_t share = std::max<int64_t>(1, options_.max_queued / callers);
  if (mine < share && queued < 2 * options_.max_queued) return absl::OkStatus();
  if (mine < share) {
    return absl::ResourceExhaustedError(
        absl::StrCat("the server has ", queued, " pieces of ", WorkLaneName(which),
                     " work waiting from ", lane.queued_by_caller.size(),
                     " callers, twice its limit (--max_queued_work); retry "
                     "shortly"));
  }
  return absl::ResourceExhaustedError(
      absl::StrCat("this caller has ", mine, " pieces of ", WorkLaneName(which),
                   " work waiting, its share of the lane (", share, " of --max_queued_work ",
                   options_.max_queued, ", shared by ", callers,
                   " callers); wait for answers before sending more"));
}

absl::Status WorkScheduler::Submit(WorkOrder order, std::function<void(const WorkStart&)> work) {
  const WorkLane which = LaneFor(order);
  if (order.memory > 0 && budget_ != nullptr && !budget_->EverFits(order.memory + order.held)) {
    return budget_->Refusal(order.caller, order.memory + order.held,
                            order.held > 0 ? "this call's cloud with its work's working memory"
                                           : "this call's working memory");
  }
  std::lock_guard<std::mutex> lock(mu_);
  if (stopping_)
    return absl::UnavailableError("the server is shutting down; retry on another replica");
  Lane& lane = lanes_[static_cast<int>(which)];
  if (absl::Status refused = ShareRefusalLocked(which, order.caller); !refused.ok()) {
    return refused;
  }
  auto backlog = backlog_.find(order.caller);
  if (backlog != backlog_.end() && backlog->second + order.cost > options_.max_caller_backlog) {
    return absl::ResourceExhaustedError(
        absl::StrCat("this caller already has ",
                     absl::FormatDuration(absl::Trunc(backlog->second, absl::Milliseconds(1))),
                     " of estimated work waiting, more than a caller may have (",
                     absl::FormatDuration(options_.max_caller_backlog),
                     ", --max_caller_backlog_seconds); wait for answers before sending more"));
  }
  const double cost = std::max(absl::ToDoubleSeconds(order.cost), 1e-6);
  double& finish = lane.last_finish[order.caller];
  const double start = std::max(lane.virtual_time, finish);
  finish = start + cost;
  backlog_[order.caller] += order.cost;
  ++lane.queued_by_caller[order.caller];
  lane.queued_cost += order.cost;
  Job job{std::move(order), std::move(work), absl::Now()};
  lane.queue.emplace(Tag{start, next_seq_++}, std::move(job));
  CheckBacklogLocked();
  lane.ready.notify_one();
  if (lane.running >= lane.workers && sleepers_ > 0) {
    // It will wait while this lane's workers are all busy: wake the workers that sleep
    // without a timeout, so that they sweep it (its deadline, its call's cancellation).
    for (Lane& other : lanes_) other.ready.notify_all();
  }
  return absl::OkStatus();
}

WorkScheduler::Job WorkScheduler::UnqueueLocked(Lane& lane, std::map<Tag, Job>::iterator it) {
  Job job = std::move(it->second);
  lane.queue.erase(it);
  const WorkOrder& order = job.order;
  lane.queued_cost -= order.cost;
  if (const auto mine = lane.queued_by_caller.find(order.caller);
      mine != lane.queued_by_caller.end() && --mine->second <= 0) {
    lane.queued_by_caller.erase(mine);
  }
  if (const auto backlog = backlog_.find(order.caller); backlog != backlog_.end()) {
    backlog->second -= order.cost;
    if (backlog->second <= absl::ZeroDuration()) backlog_.erase(backlog);
  }
  // Callers whose last finish tag is behind the virtual time start afresh anyway.
  if (lane.last_finish.size() > 2 * lane.queue.size() + 64) {
    for (auto f = lane.last_finish.begin(); f != lane.last_finish.end();) {
      f = f->second <= lane.virtual_time ? lane.last_finish.erase(f) : std::next(f);
    }
  }
  CheckBacklogLocked();
  return job;
}

void WorkScheduler::CheckBacklogLocked() const {
#ifndef NDEBUG
  absl::Duration backlog;
  for (const auto& [caller, waiting] : backlog_) backlog += waiting;
  absl::Duration queued;
  for (const Lane& lane : lanes_) queued += lane.queued_cost;
  assert(backlog == queued && "a caller's backlog was not released exactly once");
#endif
}

absl::Status WorkScheduler::DropReasonLocked(const WorkOrder& order, absl::Time now) const {
  if (stopping_) {
    return absl::CancelledError("the server is shutting down; retry on another replica");
  }
  if (now >= order.deadline) {
    return absl::DeadlineExceededError(
        "the call's deadline passed while its work waited for a worker");
  }
  if (order.cancelled && order.cancelled()) {
    return absl::CancelledError("the call was cancelled while its work waited");
  }
  return absl::OkStatus();
}

std::map<WorkScheduler::Tag, WorkScheduler::Job>::iterator WorkScheduler::DropLocked(
    WorkLane which, std::map<Tag, Job>::iterator it, absl::Status status, absl::Time now,
    std::vector<Taken>* dropped) {
  Taken& taken = dropped->emplace_back();
  taken.start = WorkStart{std::move(status), which, now - it->second.submitted};
  auto next = std::next(it);
  taken.job = UnqueueLocked(lanes_[static_cast<int>(which)], it);
  return next;
}

void WorkScheduler::SweepLocked(absl::Time now, std::vector<Taken>* dropped) {
  for (int which = 0; which < kNumWorkLanes; ++which) {
    Lane& lane = lanes_[which];
    for (auto it = lane.queue.begin(); it != lane.queue.end();) {
      absl::Status status = DropReasonLocked(it->second.order, now);
      it = status.ok()
               ? std::next(it)
               : DropLocked(static_cast<WorkLane>(which), it, std::move(status), now, dropped);
    }
  }
}

bool WorkScheduler::TakeLocked(WorkLane which, absl::Time now, Taken* taken,
                               std::vector<Taken>* dropped) {
  Lane& lane = lanes_[static_cast<int>(which)];
  bool blocked = false;
  for (auto it = lane.queue.begin(); it != lane.queue.end();) {
    const WorkOrder& order = it->second.order;
    if (absl::Status status = DropReasonLocked(order, now); !status.ok()) {
      it = DropLocked(which, it, std::move(status), now, dropped);
      continue;
    }
    if (order.memory > 0 && budget_ != nullptr) {
      if (blocked && order.memory > kSmallMemory) {
        ++it;
        continue;
      }
      absl::StatusOr<MemoryBudget::Grant> grant =
          budget_->Reserve(order.caller, order.memory, "this call's work");
      if (!grant.ok()) {
        if (!budget_->FitsTotal(order.memory)) {
          blocked = true;  // the server's budget is full: big work waits its turn for it
          ++it;
          continue;
        }
        // Its own caller's share refuses it: others' work need not wait behind it. When none
        // of that caller's work runs, only its other waiting calls hold the share, and they
        // wait for the same memory: after a grace period (an answer being sent also holds
        // some), the call is refused rather than left to wait for its deadline.
        Job& job = it->second;
        if (RunningLocked(order.caller) > 0) {
          job.own_share_blocked_since = absl::InfiniteFuture();
        } else if (job.own_share_blocked_since == absl::InfiniteFuture()) {
          job.own_share_blocked_since = now;
        } else if (now - job.own_share_blocked_since >= kOwnShareGrace) {
          absl::Status refused = grant.status();
          refused = absl::ResourceExhaustedError(
              absl::StrCat(refused.message(),
                           "; none of this caller's work is running to give any back, "
                           "so it would wait for ever: send fewer large calls at once"));
          it = DropLocked(which, it, std::move(refused), now, dropped);
          continue;
        }
        ++it;
        continue;
      }
      taken->grant = *std::move(grant);
    }
    lane.virtual_time = it->first.first;
    taken->start = WorkStart{absl::OkStatus(), which, now - it->second.submitted};
    taken->job = UnqueueLocked(lane, it);
    return true;
  }
  return false;
}

void WorkScheduler::Work(WorkLane which) {
  if (which == WorkLane::kHeavy && options_.heavy_nice > 0) {
    // Linux: a thread's own nice value. Raising it needs no privilege; failure only costs
    // the protection.
    (void)setpriority(PRIO_PROCESS, static_cast<id_t>(syscall(SYS_gettid)),
                      std::min(options_.heavy_nice, 19));
  }
  std::unique_lock<std::mutex> lock(mu_);
  Lane& lane = lanes_[static_cast<int>(which)];
  while (true) {
    const absl::Time now = absl::Now();
    std::vector<Taken> dropped;
    if (stopping_ || now - last_sweep_ >= kSweepInterval) {
      SweepLocked(now, &dropped);
      last_sweep_ = now;
    }
    Taken taken;
    const bool have = !stopping_ && TakeLocked(which, now, &taken, &dropped);
    std::string caller;
    if (have) {
      ++lane.running;
      caller = taken.job.order.caller;
      ++running_by_caller_[caller];
    }
    if (have || !dropped.empty()) {
      lock.unlock();
      for (Taken& drop : dropped) drop.job.work(drop.start);
      dropped.clear();  // destroys what the dropped work captured, outside the lock
      bool freed = false;
      if (have) {
        taken.job.work(taken.start);
        freed = taken.grant.bytes() > 0;
        taken = Taken();  // gives back its memory
      }
      lock.lock();
      if (have) {
        --lane.running;
        if (const auto mine = running_by_caller_.find(caller);
            mine != running_by_caller_.end() && --mine->second <= 0) {
          running_by_caller_.erase(mine);
        }
        // Memory came back: work waiting in another lane may be able to start now. (This
        // worker itself takes its own lane's next work.)
        for (Lane& other : lanes_) {
          if (freed && &other != &lane && !other.queue.empty()) other.ready.notify_one();
        }
      }
      continue;
    }
    if (stopping_) return;
    bool queued = false;
    for (const Lane& any : lanes_) queued = queued || !any.queue.empty();
    // Idle: sleep until work comes. With work waiting (for memory, or in another lane),
    // wake to sweep it and to retry the budget, which calls outside the scheduler free too.
    if (queued) {
      lane.ready.wait_for(lock, absl::ToChronoMilliseconds(kSweepInterval));
    } else {
      ++sleepers_;
      lane.ready.wait(lock);
      --sleepers_;
    }
  }
}

int WorkScheduler::RunningLocked(absl::string_view caller) const {
  const auto found = running_by_caller_.find(caller);
  return found == running_by_caller_.end() ? 0 : found->second;
}

WorkScheduler::LaneStats WorkScheduler::stats(WorkLane which) const {
  std::lock_guard<std::mutex> lock(mu_);
  const Lane& lane = lanes_[static_cast<int>(which)];
  return LaneStats{lane.workers, lane.running, static_cast<int64_t>(lane.queue.size()),
                   lane.queued_cost, static_cast<int64_t>(lane.queued_by_caller.size())};
}

WorkScheduler::BacklogStats WorkScheduler::backlog() const {
  std::lock_guard<std::mutex> lock(mu_);
  BacklogStats stats;
  for (const auto& [caller, waiting] : backlog_) stats.total += waiting;
  stats.callers = static_cast<int64_t>(backlog_.size());
  for (const Lane& lane : lanes_) stats.queued += lane.queued_cost;
  return stats;
}

absl::Duration WorkScheduler::backlog(absl::string_view caller) const {
  std::lock_guard<std::mutex> lock(mu_);
  const auto found = backlog_.find(caller);
  return found == backlog_.end() ? absl::ZeroDuration() : found->second;
}

}  // namespace shapeid
