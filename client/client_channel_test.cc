#include "client/client_channel.h"

#include <fstream>
#include <string>

#include "gmock/gmock.h"
#include "gtest/gtest.h"

namespace shapeid {
namespace {

using ::testing::HasSubstr;

std::string WriteFile(const std::string& name, const std::string& text) {
  const std::string path = ::testing::TempDir() + "client_channel_test_" + name;
  std::ofstream(path) << text;
  return path;
}

void ExpectRefused(const ClientOptions& options, const std::string& says) {
  const absl::StatusOr<std::shared_ptr<grpc::Channel>> channel = MakeChannel(options);
  ASSERT_FALSE(channel.ok()) << says;
  EXPECT_TRUE(absl::IsInvalidArgument(channel.status())) << channel.status();
  EXPECT_THAT(std::string(channel.status().message()), HasSubstr(says));
}

TEST(ClientChannelTest, PlainAndTlsChannelsAreMadeWithoutConnecting) {
  ClientOptions options;
  options.target = "127.0.0.1:1";  // nothing listens: making a channel does not connect
  EXPECT_TRUE(MakeChannel(options).ok());
  options.load_balancing = "pick_first";
  EXPECT_TRUE(MakeChannel(options).ok());
  options.tls = true;  // the system's roots
  EXPECT_TRUE(MakeChannel(options).ok());
}

TEST(ClientChannelTest, EachBadOptionIsNamed) {
  ClientOptions options;
  options.target = "127.0.0.1:1";
  options.load_balancing = "random";
  ExpectRefused(options, "load_balancing must be round_robin or pick_first, got \"random\"");

  options = ClientOptions();
  options.target = "127.0.0.1:1";
  options.tls_server_name = "shapeid.lab";
  ExpectRefused(options, "tls_server_name is set but TLS is off");

  options.tls = true;
  options.tls_server_name.clear();
  options.tls_cert_file = WriteFile("cert.pem", "-----BEGIN CERTIFICATE-----\n");
  ExpectRefused(options, "a client certificate needs its key");

  options.tls_cert_file.clear();
  options.tls_ca_file = "/nonexistent/ca.pem";
  ExpectRefused(options, "cannot read the TLS CA file '/nonexistent/ca.pem'");

  options.tls_ca_file = WriteFile("not_pem.txt", "hello\n");
  ExpectRefused(options, "is not a PEM file");

  options.tls_ca_file.clear();
  options.target = "10.0.0.1:50051,10.0.0.2:50051";  // two hosts, one name to check
  ExpectRefused(options, "set tls_server_name");
}

}  // namespace
}  // namespace shapeid
