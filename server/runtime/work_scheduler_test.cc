#include "server/runtime/work_scheduler.h"

#include <atomic>
#include <condition_variable>
#include <future>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "absl/strings/str_cat.h"
#include "absl/synchronization/notification.h"
#include "absl/time/clock.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "server/runtime/memory_budget.h"

namespace shapeid {
namespace {

using ::testing::ElementsAre;
using ::testing::HasSubstr;

WorkOrder Order(std::string caller, absl::Duration cost) {
  WorkOrder order;
  order.caller = std::move(caller);
  order.cost = cost;
  return order;
}

WorkSchedulerOptions OneWorkerEach() {
  WorkSchedulerOptions options;
  options.cheap_workers = 1;
  options.heavy_workers = 1;
  options.store_workers = 1;
  return options;
}

constexpr absl::Duration kCheap = absl::Milliseconds(1);
constexpr absl::Duration kHeavy = absl::Seconds(1);

// Blocks the lane's single worker until released: what a long describe does.
class Blocker {
 public:
  Blocker(WorkScheduler& scheduler, WorkOrder order) {
    EXPECT_TRUE(scheduler
                    .Submit(std::move(order),
                            [this](const WorkStart&) {
                              started_.Notify();
                              release_.WaitForNotification();
                            })
                    .ok());
    started_.WaitForNotification();
  }
  void Release() { release_.Notify(); }

 private:
  absl::Notification started_;
  absl::Notification release_;
};

// The order in which work ran, by name (dropped work with its status code).
class Journal {
 public:
  std::function<void(const WorkStart&)> Entry(std::string name) {
    return [this, name](const WorkStart& start) {
      std::lock_guard<std::mutex> lock(mu_);
      names_.push_back(
          start.status.ok()
              ? name
              : absl::StrCat(name, ":", absl::StatusCodeToString(start.status.code())));
      added_.notify_all();
    };
  }
  // Waits for `count` entries in all.
  std::vector<std::string> WaitFor(size_t count) {
    std::unique_lock<std::mutex> lock(mu_);
    added_.wait(lock, [&] { return names_.size() >= count; });
    return names_;
  }

 private:
  std::mutex mu_;
  std::condition_variable added_;
  std::vector<std::string> names_;
};

TEST(WorkSchedulerTest, SendsWorkToTheLaneItsCostAndKindSay) {
  WorkScheduler scheduler(OneWorkerEach(), nullptr);
  EXPECT_EQ(scheduler.LaneFor(Order("a", kCheap)), WorkLane::kCheap);
  EXPECT_EQ(scheduler.LaneFor(Order("a", scheduler.options().heavy_cost)), WorkLane::kHeavy);
  WorkOrder store = Order("a", kHeavy);
  store.store = true;
  EXPECT_EQ(scheduler.LaneFor(store), WorkLane::kStore);

  std::promise<WorkStart> ran;
  ASSERT_TRUE(
      scheduler.Submit(Order("a", kHeavy), [&](const WorkStart& s) { ran.set_value(s); }).ok());
  const WorkStart start = ran.get_future().get();
  EXPECT_TRUE(start.status.ok());
  EXPECT_EQ(start.lane, WorkLane::kHeavy);
  EXPECT_GE(start.waited, absl::ZeroDuration());
}

TEST(WorkSchedulerTest, CheapWorkIsNotQueuedBehindHeavyWork) {
  WorkScheduler scheduler(OneWorkerEach(), nullptr);
  Blocker heavy(scheduler, Order("abuser", kHeavy));
  Journal journal;
  for (int i = 0; i < 3; ++i) {
    ASSERT_TRUE(scheduler.Submit(Order("abuser", kHeavy), journal.Entry("heavy")).ok());
  }
  ASSERT_TRUE(scheduler.Submit(Order("lab", kCheap), journal.Entry("cheap")).ok());
  // The heavy lane's only worker is still busy, yet the cheap work ran.
  EXPECT_THAT(journal.WaitFor(1), ElementsAre("cheap"));
  EXPECT_EQ(scheduler.stats(WorkLane::kHeavy).queued, 3);
  EXPECT_EQ(scheduler.stats(WorkLane::kHeavy).running, 1);
  heavy.Release();
  EXPECT_EQ(journal.WaitFor(4).size(), 4u);
}

TEST(WorkSchedulerTest, CallersShareALaneFairlyByCost) {
  WorkScheduler scheduler(OneWorkerEach(), nullptr);
  Blocker first(scheduler, Order("a", kHeavy));
  Journal journal;
  for (int i = 0; i < 4; ++i) {
    ASSERT_TRUE(scheduler.Submit(Order("a", kHeavy), journal.Entry("a")).ok());
  }
  // b arrives behind four of a's pieces, and a second, cheaper caller c with two small ones.
  ASSERT_TRUE(scheduler.Submit(Order("b", kHeavy), journal.Entry("b")).ok());
  ASSERT_TRUE(scheduler.Submit(Order("c", kHeavy / 2), journal.Entry("c")).ok());
  ASSERT_TRUE(scheduler.Submit(Order("c", kHeavy / 2), journal.Entry("c")).ok());
  first.Release();
  // a has run one piece (the blocker): b and c come before a's backlog; c's two half-pieces
  // cost what one of b's does.
  EXPECT_THAT(journal.WaitFor(7), ElementsAre("b", "c", "c", "a", "a", "a", "a"));
}

TEST(WorkSchedulerTest, DropsWorkWhoseDeadlinePassedOrWhoseCallWasCancelled) {
  WorkScheduler scheduler(OneWorkerEach(), nullptr);
  Blocker busy(scheduler, Order("a", kHeavy));
  Journal journal;
  WorkOrder late = Order("b", kHeavy);
  late.deadline = absl::Now() + absl::Milliseconds(30);
  ASSERT_TRUE(scheduler.Submit(late, journal.Entry("late")).ok());
  std::atomic<bool> cancelled{false};
  WorkOrder gone = Order("c", kHeavy);
  gone.cancelled = [&cancelled] { return cancelled.load(); };
  ASSERT_TRUE(scheduler.Submit(gone, journal.Entry("gone")).ok());
  ASSERT_TRUE(scheduler.Submit(Order("d", kHeavy), journal.Entry("kept")).ok());
  cancelled = true;
  // Both are dropped while the only worker is still busy: their calls end at once.
  EXPECT_THAT(journal.WaitFor(2),
              testing::UnorderedElementsAre("late:DEADLINE_EXCEEDED", "gone:CANCELLED"));
  busy.Release();
  EXPECT_THAT(journal.WaitFor(3).back(), "kept");
}

TEST(WorkSchedulerTest, WorkWaitsForItsMemoryAndHoldsItWhileItRuns) {
  auto budget = std::make_shared<MemoryBudget>(MemoryBudgetOptions{1000, 1.0});
  WorkScheduler scheduler(OneWorkerEach(), budget);
  absl::StatusOr<MemoryBudget::Grant> held = budget->Reserve("stream", 700);
  ASSERT_TRUE(held.ok());
  std::promise<size_t> seen;
  WorkOrder order = Order("a", kCheap);
  order.memory = 600;
  ASSERT_TRUE(scheduler
                  .Submit(order,
                          [&](const WorkStart& start) {
                            EXPECT_TRUE(start.status.ok());
                            seen.set_value(budget->held_bytes());
                          })
                  .ok());
  absl::SleepFor(absl::Milliseconds(50));
  EXPECT_EQ(scheduler.stats(WorkLane::kCheap).queued, 1);  // 700 + 600 > 1000: it waits
  held->Release();
  EXPECT_EQ(seen.get_future().get(), 600u);
}

TEST(WorkSchedulerTest, RefusesWhatCanNeverFitOrWouldQueueTooMuch) {
  auto budget = std::make_shared<MemoryBudget>(MemoryBudgetOptions{size_t{1} << 30, 0.5});
  WorkSchedulerOptions options = OneWorkerEach();
  options.max_queued = 2;
  options.max_caller_backlog = absl::Seconds(3);
  WorkScheduler scheduler(options, budget);
  const auto never = [](const WorkStart&) { ADD_FAILURE() << "refused work ran"; };

  WorkOrder huge = Order("a", kCheap);
  huge.memory = size_t{600} << 20;
  const absl::Status too_big = scheduler.Submit(huge, never);
  EXPECT_EQ(too_big.code(), absl::StatusCode::kResourceExhausted);
  EXPECT_THAT(too_big.message(), HasSubstr("--memory_budget_mib"));

  Blocker busy(scheduler, Order("a", kHeavy));
  Journal journal;
  ASSERT_TRUE(scheduler.Submit(Order("a", kHeavy * 2), journal.Entry("a")).ok());
  const absl::Status backlog = scheduler.Submit(Order("a", kHeavy * 2), never);
  EXPECT_EQ(backlog.code(), absl::StatusCode::kResourceExhausted);
  EXPECT_THAT(backlog.message(), HasSubstr("--max_caller_backlog_seconds"));
  ASSERT_TRUE(scheduler.Submit(Order("b", kHeavy), journal.Entry("b")).ok());
  // The lane holds its limit (a's and b's): a newcomer still gets its share, one piece...
  ASSERT_TRUE(scheduler.Submit(Order("c", kHeavy), journal.Entry("c")).ok());
  const absl::Status share = scheduler.Submit(Order("c", kHeavy), never);
  EXPECT_EQ(share.code(), absl::StatusCode::kResourceExhausted);
  EXPECT_THAT(share.message(), HasSubstr("its share of the lane"));
  EXPECT_THAT(share.message(), HasSubstr("--max_queued_work"));
  // ...and nothing passes twice the limit.
  ASSERT_TRUE(scheduler.Submit(Order("d", kHeavy), journal.Entry("d")).ok());
  const absl::Status full = scheduler.Submit(Order("e", kHeavy), never);
  EXPECT_EQ(full.code(), absl::StatusCode::kResourceExhausted);
  EXPECT_THAT(full.message(), HasSubstr("twice its limit (--max_queued_work)"));
  busy.Release();
  EXPECT_EQ(journal.WaitFor(4).size(), 4u);
}

TEST(WorkSchedulerTest, ACallerThatFillsALaneIsRefusedItselfWhileOthersKeepTheirShare) {
  WorkSchedulerOptions options = OneWorkerEach();
  options.max_queued = 8;
  WorkScheduler scheduler(options, nullptr);
  Blocker busy(scheduler, Order("flooder", kCheap));
  std::atomic<int> ran{0};
  const auto count = [&ran](const WorkStart& start) {
    if (start.status.ok()) ran.fetch_add(1);
  };
  int flooder_admitted = 0;
  while (scheduler.Submit(Order("flooder", kCheap), count).ok()) ++flooder_admitted;
  EXPECT_EQ(flooder_admitted, 8);
  // Another caller gets half the lane (two callers share it), the flooder nothing more.
  int lab_admitted = 0;
  while (scheduler.Submit(Order("lab", kCheap), count).ok()) ++lab_admitted;
  EXPECT_EQ(lab_admitted, 4);
  EXPECT_EQ(scheduler.Submit(Order("flooder", kCheap), count).code(),
            absl::StatusCode::kResourceExhausted);
  const WorkScheduler::LaneStats cheap = scheduler.stats(WorkLane::kCheap);
  EXPECT_EQ(cheap.queued, 12);
  EXPECT_EQ(cheap.queued_callers, 2);
  EXPECT_EQ(cheap.queued_cost, 12 * kCheap);
  busy.Release();
  while (ran.load() < 12) absl::SleepFor(absl::Milliseconds(1));
}

// What locked every loopback client out for good: the backlog of work that had started was
// never given back, so it piled up over a long run until every call was refused.
TEST(WorkSchedulerTest, ACallerMayRunFarMoreThanItsBacklogBoundOneAfterAnother) {
  WorkSchedulerOptions options = OneWorkerEach();
  options.max_caller_backlog = absl::Milliseconds(10);
  WorkScheduler scheduler(options, nullptr);
  for (int i = 0; i < 2000; ++i) {  // 2 s of estimated work through a 10 ms bound
    std::promise<void> done;
    ASSERT_TRUE(
        scheduler.Submit(Order("robot", kCheap), [&](const WorkStart&) { done.set_value(); }).ok())
        << "refused after " << i << " pieces";
    done.get_future().wait();
  }
  const WorkScheduler::BacklogStats backlog = scheduler.backlog();
  EXPECT_EQ(backlog.total, absl::ZeroDuration());
  EXPECT_EQ(backlog.queued, absl::ZeroDuration());
  EXPECT_EQ(backlog.callers, 0);
}

TEST(WorkSchedulerTest, BacklogIsGivenBackExactlyOnceWhateverEndsTheWork) {
  auto scheduler = std::make_unique<WorkScheduler>(OneWorkerEach(), nullptr);
  Blocker busy(*scheduler, Order("other", kHeavy));
  Journal journal;
  WorkOrder late = Order("robot", kHeavy);
  late.deadline = absl::Now() + absl::Milliseconds(20);
  ASSERT_TRUE(scheduler->Submit(late, journal.Entry("late")).ok());
  std::atomic<bool> cancelled{false};
  WorkOrder gone = Order("robot", kHeavy);
  gone.cancelled = [&cancelled] { return cancelled.load(); };
  ASSERT_TRUE(scheduler->Submit(gone, journal.Entry("gone")).ok());
  ASSERT_TRUE(scheduler->Submit(Order("robot", kHeavy), journal.Entry("stopped")).ok());
  ASSERT_TRUE(scheduler->Submit(Order("robot", kCheap), journal.Entry("ran")).ok());
  EXPECT_GE(scheduler->backlog("robot"), 3 * kHeavy);  // the cheap one may have run already
  EXPECT_EQ(scheduler->backlog().total, scheduler->backlog().queued);
  cancelled = true;
  journal.WaitFor(3);  // dropped for its deadline, dropped as cancelled, and the cheap one ran
  EXPECT_EQ(scheduler->backlog("robot"), kHeavy);
  scheduler->Stop();
  EXPECT_THAT(journal.WaitFor(4).back(), "stopped:CANCELLED");
  EXPECT_EQ(scheduler->backlog("robot"), absl::ZeroDuration());
  EXPECT_EQ(scheduler->backlog().total, absl::ZeroDuration());
  busy.Release();
  scheduler.reset();
}

TEST(WorkSchedulerTest, RefusesAtOnceWorkThatWithItsCloudCouldNeverFitACallersShare) {
  auto budget = std::make_shared<MemoryBudget>(MemoryBudgetOptions{1000, 0.5});
  WorkScheduler scheduler(OneWorkerEach(), budget);
  WorkOrder order = Order("a", kCheap);
  order.memory = 300;
  order.held = 300;  // 600 > the 500 one caller may hold: it would wait for ever
  const absl::Status refused =
      scheduler.Submit(order, [](const WorkStart&) { ADD_FAILURE() << "refused work ran"; });
  EXPECT_EQ(refused.code(), absl::StatusCode::kResourceExhausted);
  EXPECT_THAT(refused.message(), HasSubstr("--memory_budget_mib"));
  order.held = 200;
  std::promise<void> ran;
  ASSERT_TRUE(scheduler.Submit(order, [&](const WorkStart&) { ran.set_value(); }).ok());
  ran.get_future().wait();
}

// Two large calls of one caller whose clouds fill its share: neither's work can ever get its
// memory. It must neither hold up another caller's large work nor wait for its deadline.
TEST(WorkSchedulerTest, WorkThatOnlyItsOwnCallersOtherCallsBlockIsRefusedAndBlocksNoOne) {
  constexpr size_t kMiB = size_t{1} << 20;
  auto budget = std::make_shared<MemoryBudget>(MemoryBudgetOptions{64 * kMiB, 0.5});
  WorkScheduler scheduler(OneWorkerEach(), budget);
  absl::StatusOr<MemoryBudget::Grant> cloud1 = budget->Reserve("robot", 12 * kMiB);
  absl::StatusOr<MemoryBudget::Grant> cloud2 = budget->Reserve("robot", 12 * kMiB);
  ASSERT_TRUE(cloud1.ok() && cloud2.ok());
  WorkOrder stuck = Order("robot", kCheap);
  stuck.memory = 10 * kMiB;  // with its own cloud 22 MiB: fits the 32 a caller may hold...
  stuck.held = 12 * kMiB;    // ...but not beside the other call's 12
  std::promise<absl::Status> refused;
  const absl::Time submitted = absl::Now();
  ASSERT_TRUE(scheduler
                  .Submit(stuck,
                          [&](const WorkStart& start) {
                            // A fresh Status, not a copy: Debian's Abseil is not built for TSan,
                            // which then cannot see the atomic count of a shared Status's message.
                            refused.set_value(absl::Status(start.status.code(),
                                                           std::string(start.status.message())));
                          })
                  .ok());
  WorkOrder other = Order("lab", kCheap);
  other.memory = 8 * kMiB;
  std::promise<void> ran;
  ASSERT_TRUE(scheduler.Submit(other, [&](const WorkStart&) { ran.set_value(); }).ok());
  ran.get_future().wait();  // not behind the robot's
  const absl::Status status = refused.get_future().get();
  EXPECT_EQ(status.code(), absl::StatusCode::kResourceExhausted);
  EXPECT_THAT(status.message(), HasSubstr("send fewer large calls at once"));
  EXPECT_LT(absl::Now() - submitted, absl::Seconds(10));
  EXPECT_EQ(scheduler.backlog().total, absl::ZeroDuration());
}

TEST(WorkSchedulerTest, StopDropsQueuedWorkAndRefusesNewWork) {
  auto scheduler = std::make_unique<WorkScheduler>(OneWorkerEach(), nullptr);
  Blocker busy(*scheduler, Order("a", kHeavy));
  Journal journal;
  ASSERT_TRUE(scheduler->Submit(Order("b", kHeavy), journal.Entry("queued")).ok());
  scheduler->Stop();
  EXPECT_THAT(journal.WaitFor(1), ElementsAre("queued:CANCELLED"));
  EXPECT_EQ(scheduler->Submit(Order("c", kCheap), journal.Entry("late")).code(),
            absl::StatusCode::kUnavailable);
  busy.Release();
  scheduler.reset();  // joins; the running work finished
}

TEST(WorkSchedulerTest, EveryPieceRunsExactlyOnceFromManyThreads) {
  auto budget = std::make_shared<MemoryBudget>(MemoryBudgetOptions{1 << 20, 0.5});
  WorkSchedulerOptions options;
  options.cheap_workers = 3;
  options.heavy_workers = 2;
  options.store_workers = 2;
  WorkScheduler scheduler(options, budget);
  constexpr int kThreads = 8, kEach = 300;
  std::atomic<int> ran{0}, dropped{0}, refused{0};
  std::vector<std::thread> threads;
  for (int t = 0; t < kThreads; ++t) {
    threads.emplace_back([&, t] {
      for (int i = 0; i < kEach; ++i) {
        WorkOrder order = Order(absl::StrCat("caller", t % 3), i % 7 == 0 ? kHeavy / 100 : kCheap);
        order.store = i % 11 == 0;
        order.memory = (i % 5) * 1000;
        if (i % 13 == 0) order.deadline = absl::Now();
        const absl::Status s = scheduler.Submit(order, [&](const WorkStart& start) {
          (start.status.ok() ? ran : dropped).fetch_add(1);
        });
        if (!s.ok()) refused.fetch_add(1);
      }
    });
  }
  for (std::thread& thread : threads) thread.join();
  while (ran + dropped + refused < kThreads * kEach) absl::SleepFor(absl::Milliseconds(5));
  EXPECT_EQ(ran + dropped + refused, kThreads * kEach);
  EXPECT_GT(dropped.load(), 0);
  EXPECT_EQ(budget->held_bytes(), 0u);
}

}  // namespace
}  // namespace shapeid
