// From SecurityOptions to credentials, keys and the start-up rule, without a running server.

#include "server/security/security.h"

#include <cstdio>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "absl/strings/str_cat.h"
#include "core/io/io_testing.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "tests/test_certificates.h"

namespace shapeid {
namespace {

using ::testing::HasSubstr;
using ::testing::Not;

TEST(SecurityTest, LoopbackAddresses) {
  for (const char* listen : {"127.0.0.1:50051", "127.1.2.3:0", "localhost:50051", "[::1]:50051",
                             "[::ffff:127.0.0.1]:1", "unix:/run/shapeid.sock"}) {
    EXPECT_TRUE(IsLoopbackAddress(listen)) << listen;
  }
  for (const char* listen : {"0.0.0.0:50051", "[::]:50051", ":50051", "10.0.0.5:50051",
                             "recognizer.lab:50051", "[2001:db8::1]:50051", "128.0.0.1:1"}) {
    EXPECT_FALSE(IsLoopbackAddress(listen)) << listen;
  }
}

// A resolver that knows a few names, and fails the test when asked about anything else (a
// literal address or a Unix socket must not be resolved at all).
HostResolver FakeHosts(std::map<std::string, std::vector<std::string>> hosts) {
  return [hosts = std::move(hosts)](
             const std::string& host) -> absl::StatusOr<std::vector<std::string>> {
    const auto it = hosts.find(host);
    if (it == hosts.end()) {
      ADD_FAILURE() << "resolved " << host;
      return absl::NotFoundError(absl::StrCat("cannot resolve ", host, ": unknown"));
    }
    if (it->second.empty()) return absl::NotFoundError(absl::StrCat("cannot resolve ", host));
    return it->second;
  };
}

TEST(SecurityTest, LiteralsAndSocketsAreClassifiedWithoutResolving) {
  const HostResolver none = FakeHosts({});
  for (const char* listen :
       {"127.0.0.1:50051", "127.255.0.9:1", "[::1]:50051", "::1", "[::ffff:127.1.2.3]:1",
        "unix:/run/shapeid.sock", "unix:///run/shapeid.sock", "unix-abstract:shapeid"}) {
    EXPECT_TRUE(IsLoopbackAddress(listen, none)) << listen;
  }
  for (const char* listen :
       {"0.0.0.0:50051", "[::]:50051", "::", ":50051", "", "[]:1", "10.0.0.5:50051",
        "[::ffff:10.0.0.5]:1", "[::127.0.0.1]:1", "126.255.255.255:1"}) {
    EXPECT_FALSE(IsLoopbackAddress(listen, none)) << listen;
  }
}

// A name is local only if every address it resolves to is loopback: gRPC listens on all of
// them. So a "localhost" that /etc/hosts maps to a LAN address is refused, as is a name that
// does not resolve; "127.1" (a number inet_pton does not read) is resolved like a name.
TEST(SecurityTest, NamesAreLocalOnlyIfEveryAddressIsLoopback) {
  const HostResolver hosts = FakeHosts({{"localhost", {"127.0.0.1", "::1"}},
                                        {"robot", {"127.0.1.1"}},
                                        {"127.1", {"127.0.0.1"}},
                                        {"moved", {"10.0.0.5"}},
                                        {"both", {"127.0.0.1", "10.0.0.5"}},
                                        {"v6", {"::1", "2001:db8::1"}},
                                        {"nowhere", {}}});
  for (const char* listen : {"localhost:50051", "robot:1", "127.1:1", "[localhost]:1"}) {
    EXPECT_TRUE(IsLoopbackAddress(listen, hosts)) << listen;
  }
  for (const char* listen : {"moved:50051", "both:1", "v6:1", "nowhere:1"}) {
    EXPECT_FALSE(IsLoopbackAddress(listen, hosts)) << listen;
  }

  SecurityOptions open;
  EXPECT_TRUE(CheckExposure("localhost:50051", open, /*has_keys=*/false, hosts).ok());
  const absl::Status both = CheckExposure("both:50051", open, false, hosts);
  EXPECT_TRUE(absl::IsFailedPrecondition(both));
  EXPECT_THAT(both.message(), HasSubstr("refusing to listen on both:50051 (both resolves to "
                                        "127.0.0.1, 10.0.0.5; a name counts as local only if "
                                        "every address it resolves to is loopback) with neither"));
  EXPECT_EQ(std::string(both.message()).find('\n'), std::string::npos) << "one line";
  EXPECT_THAT(CheckExposure("nowhere:1", open, false, hosts).message(),
              HasSubstr("(cannot resolve nowhere; a name counts as local"));
  // With keys, TLS or --insecure nothing needs resolving.
  EXPECT_TRUE(CheckExposure("elsewhere:1", open, /*has_keys=*/true, FakeHosts({})).ok());
}

TEST(SecurityTest, TheSystemResolverReadsHostsAndNumbers) {
  absl::StatusOr<std::vector<std::string>> localhost = ResolveListenHost("localhost");
  ASSERT_TRUE(localhost.ok()) << localhost.status();
  EXPECT_THAT(*localhost, Not(::testing::IsEmpty()));
  absl::StatusOr<std::vector<std::string>> number = ResolveListenHost("127.1");
  ASSERT_TRUE(number.ok()) << number.status();
  EXPECT_THAT(*number, ::testing::ElementsAre("127.0.0.1"));
  EXPECT_TRUE(IsLoopbackAddress("127.1:50051"));
}

TEST(SecurityTest, AnOpenServerOnTheNetworkMustBeAskedFor) {
  SecurityOptions open;
  EXPECT_TRUE(CheckExposure("127.0.0.1:50051", open, /*has_keys=*/false).ok());
  const absl::Status refused = CheckExposure("0.0.0.0:50051", open, false);
  EXPECT_TRUE(absl::IsFailedPrecondition(refused));
  EXPECT_THAT(refused.message(), HasSubstr("refusing to listen on 0.0.0.0:50051 with neither TLS "
                                           "nor API keys"));
  EXPECT_THAT(refused.message(), HasSubstr("--insecure"));
  EXPECT_EQ(std::string(refused.message()).find('\n'), std::string::npos) << "one line";
  EXPECT_TRUE(CheckExposure("0.0.0.0:50051", open, /*has_keys=*/true).ok());
  SecurityOptions tls;
  tls.tls_cert_file = "server.pem";
  tls.tls_key_file = "server.key";
  EXPECT_TRUE(CheckExposure("0.0.0.0:50051", tls, false).ok());
  SecurityOptions insecure;
  insecure.insecure = true;
  EXPECT_TRUE(CheckExposure("0.0.0.0:50051", insecure, false).ok());
}

TEST(SecurityTest, WarningsForWeakButAllowedSetUps) {
  const ApiKeyStore none;
  auto keys = ApiKeyStore::Create({{"ops", Scope::kAdmin, Sha256("shapeid_0123456789abcdefghij")}});
  ASSERT_TRUE(keys.ok());
  SecurityOptions plain;
  EXPECT_TRUE(SecurityWarnings("127.0.0.1:50051", plain, none).empty());
  EXPECT_THAT(SecurityWarnings("0.0.0.0:50051", plain, *keys),
              ::testing::ElementsAre(HasSubstr("API keys cross the network in plaintext")));
  SecurityOptions tls;
  tls.tls_cert_file = "server.pem";
  EXPECT_TRUE(SecurityWarnings("0.0.0.0:50051", tls, *keys).empty());
  EXPECT_THAT(SecurityWarnings("0.0.0.0:50051", tls, none),
              ::testing::ElementsAre(HasSubstr("no API keys on 0.0.0.0:50051")));
  tls.tls_client_ca_file = "ca.pem";
  EXPECT_TRUE(SecurityWarnings("0.0.0.0:50051", tls, none).empty()) << "client certificates";
}

TEST(SecurityTest, KeysFromFileAndInlineTogether) {
  SecurityOptions security;
  const std::string admin = "shapeid_admin_0123456789abcdefgh";
  security.api_keys_file = WriteTempFile("keys.txt", "ops admin " + Sha256Hex(admin) + "\n");
  security.api_keys = "robot read " + Sha256Hex("shapeid_read_0123456789abcdefgh");
  auto keys = LoadApiKeys(security);
  ASSERT_TRUE(keys.ok()) << keys.status();
  EXPECT_EQ((*keys)->size(), 2u);
  ASSERT_NE((*keys)->Find(admin), nullptr);

  const std::string line = DescribeSecurity(security, **keys);
  EXPECT_EQ(line,
            "plaintext (no TLS), 2 API keys (1 read, 0 write, 1 admin); health checks "
            "and reflection need none");
  EXPECT_THAT(line, Not(HasSubstr(Sha256Hex(admin).substr(0, 8))));

  SecurityOptions none;
  ASSERT_TRUE(LoadApiKeys(none).ok());
  EXPECT_TRUE((*LoadApiKeys(none))->empty());
}

TEST(SecurityTest, KeyErrorsNameTheSource) {
  SecurityOptions missing;
  missing.api_keys_file = "/nonexistent/keys.txt";
  EXPECT_TRUE(absl::IsNotFound(LoadApiKeys(missing).status()));
  EXPECT_THAT(LoadApiKeys(missing).status().message(),
              HasSubstr("cannot read the API keys file '/nonexistent/keys.txt'"));

  SecurityOptions empty;
  empty.api_keys_file = WriteTempFile("empty-keys.txt", "# nobody yet\n");
  EXPECT_THAT(LoadApiKeys(empty).status().message(), HasSubstr("holds no API key"));

  SecurityOptions twice;  // the same name in the file and inline
  twice.api_keys_file = WriteTempFile("k.txt", "a read " + Sha256Hex("k1_0123456789abcdefghij"));
  twice.api_keys = "a write " + Sha256Hex("k2_0123456789abcdefghij");
  EXPECT_THAT(LoadApiKeys(twice).status().message(), HasSubstr("two keys are named 'a'"));

  SecurityOptions bad;
  bad.api_keys = "a read notahash";
  EXPECT_THAT(LoadApiKeys(bad).status().message(),
              HasSubstr("--api_keys (SHAPEID_API_KEYS) line 1: key 'a' needs the SHA-256"));
}

TEST(SecurityTest, TlsFilesAreCheckedAtStartUp) {
  const std::string& dir = TestCertificates::Dir();
  ASSERT_FALSE(dir.empty());
  SecurityOptions security;
  ASSERT_TRUE(ListeningCredentials(security).ok()) << "no TLS: insecure credentials";

  security.tls_cert_file = dir + "/server.pem";
  security.tls_key_file = dir + "/server.key";
  EXPECT_TRUE(ListeningCredentials(security).ok());
  security.tls_client_ca_file = dir + "/ca.pem";
  EXPECT_TRUE(ListeningCredentials(security).ok());
  EXPECT_EQ(DescribeSecurity(security, ApiKeyStore()),
            "TLS with client certificates (mutual TLS), no API keys: every caller may call "
            "everything");

  struct Case {
    std::string cert, key, client_ca, message;
  } cases[] = {
      {dir + "/server.pem", dir + "/client.key", "", "does not match the certificate"},
      {dir + "/server.key", dir + "/server.key", "", "holds no PEM certificate"},
      {dir + "/server.pem", dir + "/server.pem", "", "holds no PEM private key"},
      {dir + "/server.pem", "", "", "give both --tls_cert and --tls_key"},
      {"", "", dir + "/ca.pem", "--tls_client_ca needs --tls_cert and --tls_key"},
      {dir + "/server.pem", dir + "/server.key", dir + "/ca.key", "holds no PEM certificate"},
      {dir + "/nope.pem", dir + "/server.key", "", "cannot read the TLS certificate file"},
  };
  for (const Case& c : cases) {
    SecurityOptions wrong;
    wrong.tls_cert_file = c.cert;
    wrong.tls_key_file = c.key;
    wrong.tls_client_ca_file = c.client_ca;
    const absl::Status status = ListeningCredentials(wrong).status();
    EXPECT_FALSE(status.ok()) << c.message;
    EXPECT_THAT(status.message(), HasSubstr(c.message));
  }
}

}  // namespace
}  // namespace shapeid
