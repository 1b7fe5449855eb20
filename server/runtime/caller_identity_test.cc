#include "server/runtime/caller_identity.h"

#include <string>

#include "gmock/gmock.h"
#include "gtest/gtest.h"

namespace shapeid {
namespace {

using ::testing::HasSubstr;

TEST(CallerOfTest, AKeyThenACertificateThenTheHost) {
  EXPECT_EQ(*CallerOf("lab", "robot.lab", "ipv4:10.0.0.7:5555", ""), "key:lab");
  EXPECT_EQ(*CallerOf("", "robot.lab", "ipv4:10.0.0.7:5555", ""), "cert:robot.lab");
  EXPECT_EQ(*CallerOf("", "", "ipv4:10.0.0.7:5555", ""), "10.0.0.7");
  EXPECT_EQ(*CallerOf("", "", "ipv6:[::1]:5555", ""), "::1");
}

TEST(CallerOfTest, AnIdSplitsOnlyCallersKnownByTheirHost) {
  EXPECT_EQ(*CallerOf("", "", "ipv4:127.0.0.1:5555", "arm-left"), "127.0.0.1/arm-left");
  EXPECT_EQ(*CallerOf("", "", "ipv4:127.0.0.1:6666", "arm-right"), "127.0.0.1/arm-right");
  // A key or a certificate is the operator's identity: an invented id cannot multiply it.
  EXPECT_EQ(*CallerOf("lab", "", "ipv4:127.0.0.1:5555", "arm-left"), "key:lab");
  EXPECT_EQ(*CallerOf("", "robot.lab", "ipv4:127.0.0.1:5555", "arm-left"), "cert:robot.lab");
}

TEST(CallerOfTest, RefusesAMalformedId) {
  for (const std::string& id :
       {std::string("has space"), std::string("a/b"), std::string(65, 'x'), std::string("\x01")}) {
    const absl::StatusOr<std::string> caller = CallerOf("", "", "ipv4:127.0.0.1:1", id);
    ASSERT_FALSE(caller.ok()) << id;
    EXPECT_EQ(caller.status().code(), absl::StatusCode::kInvalidArgument);
    EXPECT_THAT(caller.status().message(), HasSubstr("shapeid-caller-id"));
  }
  EXPECT_TRUE(CallerOf("", "", "ipv4:127.0.0.1:1", std::string(64, 'x')).ok());
}

}  // namespace
}  // namespace shapeid
