#include "server/runtime/stream_limiter.h"

#include <utility>
#include <vector>

#include "gmock/gmock.h"
#include "gtest/gtest.h"

namespace shapeid {
namespace {

using ::testing::HasSubstr;

TEST(ClientOfPeerTest, HostWithoutPort) {
  EXPECT_EQ(ClientOfPeer("ipv4:10.1.2.3:5555"), "10.1.2.3");
  EXPECT_EQ(ClientOfPeer("ipv6:[::1]:5555"), "::1");
  EXPECT_EQ(ClientOfPeer("ipv6:%5B2001:db8::7%5D:443"), "2001:db8::7");
  EXPECT_EQ(ClientOfPeer("unix:/run/shapeid.sock"), "unix:/run/shapeid.sock");
}

TEST(StreamLimiterTest, CountsPerClientAndReleases) {
  StreamLimiter limiter(2);
  std::vector<StreamLimiter::Slot> held;
  for (int i = 0; i < 2; ++i) {
    auto slot = limiter.Acquire("10.0.0.1");
    ASSERT_TRUE(slot.ok());
    held.push_back(std::move(slot).value());
  }
  const auto third = limiter.Acquire("10.0.0.1");
  ASSERT_TRUE(absl::IsResourceExhausted(third.status()));
  EXPECT_THAT(third.status().message(), HasSubstr("client 10.0.0.1 has 2 streams open, the limit "
                                                  "(max_streams_per_client) is 2"));
  EXPECT_TRUE(limiter.Acquire("10.0.0.2").ok()) << "another client has its own count";
  EXPECT_EQ(limiter.open("10.0.0.2"), 0) << "the temporary slot was released";

  StreamLimiter::Slot moved = std::move(held.back());
  held.pop_back();
  EXPECT_EQ(limiter.open("10.0.0.1"), 2) << "moving a slot keeps it";
  moved = StreamLimiter::Slot();
  EXPECT_EQ(limiter.open("10.0.0.1"), 1);
  EXPECT_TRUE(limiter.Acquire("10.0.0.1").ok());
}

TEST(StreamLimiterTest, ZeroMeansNoLimit) {
  StreamLimiter limiter(0);
  std::vector<StreamLimiter::Slot> held;
  for (int i = 0; i < 1000; ++i) held.push_back(*limiter.Acquire("x"));
  EXPECT_EQ(limiter.open("x"), 0);
}

}  // namespace
}  // namespace shapeid
