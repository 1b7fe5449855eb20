#include "core/parallel_ranges.h"

#include <atomic>
#include <mutex>
#include <set>
#include <thread>
#include <tuple>

#include "gtest/gtest.h"

namespace shapeid {
namespace {

TEST(ParallelPartsTest, SmallJobsStayWhole) {
  EXPECT_EQ(ParallelParts(0, 8, 1000), 1);
  EXPECT_EQ(ParallelParts(1999, 8, 1000), 1);
  EXPECT_EQ(ParallelParts(2000, 8, 1000), 2);
  EXPECT_EQ(ParallelParts(1'000'000, 8, 1000), 8);
  EXPECT_EQ(ParallelParts(1'000'000, 0, 1000), 1);  // no threads asked: the caller's
  EXPECT_EQ(ParallelParts(10, 4, 0), 4);            // a zero minimum counts as one item
}

TEST(ParallelRangesTest, PartsCoverEveryItemOnceInOrder) {
  for (const int64_t count : {0, 1, 999, 1000, 4001, 100'003}) {
    for (const int threads : {1, 2, 3, 7}) {
      std::mutex mutex;
      std::set<std::tuple<int, int64_t, int64_t>> ranges;
      std::set<std::thread::id> callers;
      const int parts = ParallelRanges(count, threads, 1000, [&](int p, int64_t b, int64_t e) {
        std::lock_guard<std::mutex> lock(mutex);
        ranges.emplace(p, b, e);
        callers.insert(std::this_thread::get_id());
      });
      ASSERT_EQ(parts, ParallelParts(count, threads, 1000));
      ASSERT_EQ(ranges.size(), static_cast<size_t>(parts));
      int64_t next = 0;
      int expected_part = 0;
      for (const auto& [p, begin, end] : ranges) {
        EXPECT_EQ(p, expected_part++);
        EXPECT_EQ(begin, next) << count << " items, " << threads << " threads";
        EXPECT_LE(begin, end);
        next = end;
      }
      EXPECT_EQ(next, count);
      EXPECT_EQ(callers.size(), static_cast<size_t>(parts));  // one thread per part
    }
  }
}

TEST(ParallelRangesTest, CallingThreadTakesPartZero) {
  const std::thread::id caller = std::this_thread::get_id();
  std::atomic<bool> zero_on_caller{false};
  ParallelRanges(10'000, 4, 100, [&](int p, int64_t, int64_t) {
    if (p == 0) zero_on_caller = std::this_thread::get_id() == caller;
  });
  EXPECT_TRUE(zero_on_caller);
}

}  // namespace
}  // namespace shapeid
