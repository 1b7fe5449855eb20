#include "server/runtime/memory_budget.h"

#include <thread>
#include <vector>

#include "gmock/gmock.h"
#include "gtest/gtest.h"

namespace shapeid {
namespace {

using ::testing::HasSubstr;

constexpr size_t kMiB = size_t{1} << 20;

TEST(MemoryBudgetTest, GrantsHoldMemoryUntilTheyAreGone) {
  MemoryBudget budget({100 * kMiB, 1.0});
  {
    absl::StatusOr<MemoryBudget::Grant> a = budget.Reserve("a", 30 * kMiB);
    ASSERT_TRUE(a.ok());
    EXPECT_EQ(budget.held_bytes(), 30 * kMiB);
    ASSERT_TRUE(a->Grow(20 * kMiB).ok());
    EXPECT_EQ(a->bytes(), 50 * kMiB);
    EXPECT_EQ(budget.held_bytes("a"), 50 * kMiB);
    MemoryBudget::Grant moved = *std::move(a);
    EXPECT_EQ(budget.held_bytes(), 50 * kMiB);
  }
  EXPECT_EQ(budget.held_bytes(), 0u);
  EXPECT_EQ(budget.held_bytes("a"), 0u);
  EXPECT_EQ(budget.peak_bytes(), 50 * kMiB);
}

TEST(MemoryBudgetTest, RefusesOverTheTotalNamingTheFlag) {
  MemoryBudget budget({100 * kMiB, 1.0});
  absl::StatusOr<MemoryBudget::Grant> a = budget.Reserve("a", 80 * kMiB);
  ASSERT_TRUE(a.ok());
  const absl::StatusOr<MemoryBudget::Grant> b = budget.Reserve("b", 30 * kMiB, "the cloud");
  ASSERT_EQ(b.status().code(), absl::StatusCode::kResourceExhausted);
  EXPECT_THAT(b.status().message(), HasSubstr("the cloud needs 30 MiB"));
  EXPECT_THAT(b.status().message(), HasSubstr("100 MiB (--memory_budget_mib)"));
  EXPECT_FALSE(budget.Fits("b", 30 * kMiB));
  EXPECT_TRUE(budget.Fits("b", 20 * kMiB));
  // A failed Grow keeps what the grant held.
  const absl::Status grow = a->Grow(21 * kMiB);
  EXPECT_EQ(grow.code(), absl::StatusCode::kResourceExhausted);
  EXPECT_THAT(grow.message(), HasSubstr("80 MiB held so far"));
  EXPECT_EQ(a->bytes(), 80 * kMiB);
}

TEST(MemoryBudgetTest, OneCallerMayHoldOnlyItsShare) {
  MemoryBudget budget({100 * kMiB, 0.5});
  EXPECT_EQ(budget.caller_bytes(), 50 * kMiB);
  absl::StatusOr<MemoryBudget::Grant> a = budget.Reserve("abuser", 40 * kMiB);
  ASSERT_TRUE(a.ok());
  const absl::StatusOr<MemoryBudget::Grant> more = budget.Reserve("abuser", 20 * kMiB);
  ASSERT_EQ(more.status().code(), absl::StatusCode::kResourceExhausted);
  EXPECT_THAT(more.status().message(), HasSubstr("this caller's calls already hold 40 MiB"));
  // Another caller still has room.
  EXPECT_TRUE(budget.Reserve("lab", 50 * kMiB).ok());
  // More than a share can never be granted, and says so.
  EXPECT_FALSE(budget.EverFits(51 * kMiB));
  EXPECT_THAT(budget.Refusal("lab", 60 * kMiB, "describing").message(),
              HasSubstr("more than one caller may hold (50 MiB"));
}

TEST(MemoryBudgetTest, ZeroTotalBoundsNothingButCounts) {
  MemoryBudget budget({0, 0.5});
  absl::StatusOr<MemoryBudget::Grant> a = budget.Reserve("a", size_t{1} << 40);
  ASSERT_TRUE(a.ok());
  EXPECT_TRUE(budget.EverFits(size_t{1} << 50));
  EXPECT_EQ(budget.held_bytes(), size_t{1} << 40);
}

TEST(MemoryBudgetTest, TheDefaultIsHalfOfWhatTheProcessMayUse) {
  const size_t budget = DefaultMemoryBudgetBytes();
  EXPECT_GT(budget, size_t{64} << 20);
  EXPECT_LT(budget, size_t{1} << 50);
}

TEST(MemoryBudgetTest, ConcurrentGrantsBalance) {
  MemoryBudget budget({1000 * kMiB, 0.5});
  std::vector<std::thread> threads;
  for (int t = 0; t < 8; ++t) {
    threads.emplace_back([&budget, t] {
      for (int i = 0; i < 2000; ++i) {
        absl::StatusOr<MemoryBudget::Grant> g = budget.Reserve(t % 2 ? "a" : "b", kMiB);
        if (g.ok()) (void)g->Grow(kMiB);
      }
    });
  }
  for (std::thread& thread : threads) thread.join();
  EXPECT_EQ(budget.held_bytes(), 0u);
  EXPECT_LE(budget.peak_bytes(), 1000 * kMiB);
}

}  // namespace
}  // namespace shapeid
