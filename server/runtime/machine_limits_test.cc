#include "server/runtime/machine_limits.h"

#include <thread>

#include "gtest/gtest.h"

namespace shapeid {
namespace {

TEST(MachineLimitsTest, MemoryLimitFileReadsBytesAndTreatsUnlimitedAsNone) {
  EXPECT_EQ(ParseCgroupMemoryLimit("2147483648\n"), size_t{2147483648});
  EXPECT_EQ(ParseCgroupMemoryLimit("max\n"), 0u);
  EXPECT_EQ(ParseCgroupMemoryLimit("9223372036854771712"), 0u);  // cgroup v1's "unlimited"
  EXPECT_EQ(ParseCgroupMemoryLimit(""), 0u);
  EXPECT_EQ(ParseCgroupMemoryLimit("-1"), 0u);
}

TEST(MachineLimitsTest, CpuMaxRoundsTheQuotaUpToWholeCores) {
  EXPECT_EQ(ParseCgroupCpuMax("200000 100000\n"), 2);  // Kubernetes limits.cpu: "2"
  EXPECT_EQ(ParseCgroupCpuMax("50000 100000"), 1);     // limits.cpu: 500m
  EXPECT_EQ(ParseCgroupCpuMax("150000 100000"), 2);    // 1.5 cores: two threads may run
  EXPECT_EQ(ParseCgroupCpuMax("max 100000"), 0);
  EXPECT_EQ(ParseCgroupCpuMax(""), 0);
  EXPECT_EQ(ParseCgroupCpuMax("100000"), 0);
  EXPECT_EQ(ParseCgroupCpuMax("100000 0"), 0);
}

TEST(MachineLimitsTest, ThisProcessGetsAtLeastOneCoreAndNoMoreThanTheMachineHas) {
  const int cores = UsableCores();
  EXPECT_GE(cores, 1);
  const unsigned machine = std::thread::hardware_concurrency();
  if (machine > 0) {
    EXPECT_LE(cores, static_cast<int>(machine));
  }
  EXPECT_GT(MemoryLimitBytes(), size_t{64} << 20);
}

}  // namespace
}  // namespace shapeid
