// API keys, scopes and the scope table: the gRPC-free half of the security checks.

#include "server/security/api_keys.h"

#include <algorithm>
#include <string>
#include <vector>

#include "gmock/gmock.h"
#include "google/protobuf/descriptor.h"
#include "gtest/gtest.h"
#include "server/security/authorization.h"
#include "shapeid/v1/shapeid.pb.h"

namespace shapeid {
namespace {

using ::testing::HasSubstr;
using ::testing::Not;

constexpr char kReadKey[] = "shapeid_read_key_0123456789abcdef";
constexpr char kWriteKey[] = "shapeid_write_key_0123456789abcdef";
constexpr char kAdminKey[] = "shapeid_admin_key_0123456789abcdef";

std::string KeysText() {
  return "# name scope sha256\n"
         "robot  read  " +
         Sha256Hex(kReadKey) +
         "\n"
         "\n"
         "trainer\twrite\t" +
         Sha256Hex(kWriteKey) +
         "   # a comment\n"
         "ops admin " +
         Sha256Hex(kAdminKey) + "\n";
}

ApiKeyStore Store() {
  auto keys = ParseApiKeys(KeysText(), "keys.txt");
  EXPECT_TRUE(keys.ok()) << keys.status();
  auto store = ApiKeyStore::Create(*keys);
  EXPECT_TRUE(store.ok()) << store.status();
  return *store;
}

TEST(ApiKeysTest, Sha256MatchesTheStandardVector) {
  EXPECT_EQ(Sha256Hex("abc"), "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
}

TEST(ApiKeysTest, ScopesImplyTheSmallerOnes) {
  EXPECT_TRUE(ScopeAllows(Scope::kAdmin, Scope::kWrite));
  EXPECT_TRUE(ScopeAllows(Scope::kAdmin, Scope::kRead));
  EXPECT_TRUE(ScopeAllows(Scope::kWrite, Scope::kRead));
  EXPECT_FALSE(ScopeAllows(Scope::kWrite, Scope::kAdmin));
  EXPECT_FALSE(ScopeAllows(Scope::kRead, Scope::kWrite));
  EXPECT_EQ(*ParseScope("write"), Scope::kWrite);
  EXPECT_TRUE(absl::IsInvalidArgument(ParseScope("root").status()));
}

TEST(ApiKeysTest, ParsesLinesCommentsAndSemicolons) {
  const ApiKeyStore store = Store();
  ASSERT_EQ(store.size(), 3u);
  EXPECT_EQ(store.CountWithScope(Scope::kWrite), 1u);
  ASSERT_NE(store.Find(kWriteKey), nullptr);
  EXPECT_EQ(store.Find(kWriteKey)->name, "trainer");
  EXPECT_EQ(store.Find(kAdminKey)->scope, Scope::kAdmin);
  EXPECT_EQ(store.Find("shapeid_nobody_0123456789abcdef"), nullptr);
  EXPECT_EQ(store.Find(Sha256Hex(kReadKey)), nullptr);  // the digest is not the key

  // One line, as an environment variable carries it.
  auto inline_keys = ParseApiKeys("a read " + Sha256Hex("k1-0123456789abcdefgh") + "; b admin " +
                                      Sha256Hex("k2-0123456789abcdefgh"),
                                  "SHAPEID_API_KEYS");
  ASSERT_TRUE(inline_keys.ok()) << inline_keys.status();
  EXPECT_EQ(inline_keys->size(), 2u);
}

TEST(ApiKeysTest, ErrorsNameTheLineAndNeverQuoteADigestOrKey) {
  const std::string digest = Sha256Hex(kReadKey);
  struct Case {
    std::string text;
    std::string message;
  } cases[] = {
      {"robot read\n", "keys.txt line 1: expected NAME SCOPE SHA256-HEX, found 2 fields"},
      {"# c\nrobot root " + digest, "keys.txt line 2: unknown scope 'root'"},
      {"robot read " + std::string(kReadKey), "key 'robot' needs the SHA-256 of the key"},
      {"robot read " + digest.substr(1), "key 'robot' needs the SHA-256"},
      {"bad/name read " + digest, "keys.txt line 1: the key name must be"},
      {"a read " + digest + "\nb write " + digest, "key 'b' has the same digest as another key"},
      {"a read " + digest + "\na write " + Sha256Hex(kWriteKey), "two keys are named 'a'"},
      {"a read " + digest + "; b read", "keys.txt line 1 entry 2: expected NAME SCOPE"},
  };
  for (const Case& c : cases) {
    const absl::StatusOr<std::vector<ApiKeyEntry>> keys = ParseApiKeys(c.text, "keys.txt");
    ASSERT_FALSE(keys.ok()) << c.text;
    EXPECT_TRUE(absl::IsInvalidArgument(keys.status()));
    EXPECT_THAT(keys.status().message(), HasSubstr(c.message));
    EXPECT_THAT(keys.status().message(), Not(HasSubstr(digest.substr(0, 16))));
    EXPECT_THAT(keys.status().message(), Not(HasSubstr(kReadKey)));
  }
}

TEST(ApiKeysTest, NewKeysAreLongRandomAndDistinct) {
  const absl::StatusOr<std::string> a = NewApiKey();
  const absl::StatusOr<std::string> b = NewApiKey();
  ASSERT_TRUE(a.ok() && b.ok());
  EXPECT_EQ(a->size(), 8u + 64u);
  EXPECT_EQ(a->rfind("shapeid_", 0), 0u);
  EXPECT_NE(*a, *b);
}

TEST(AuthorizationTest, EveryShapeIdMethodIsInTheScopeTable) {
  // A method the table forgot would silently need admin; this says which one.
  const google::protobuf::ServiceDescriptor* service =
      v1::DescribeRequest::descriptor()->file()->FindServiceByName("ShapeId");
  ASSERT_NE(service, nullptr);
  const std::vector<std::string> read = {"Describe",       "DescribeCloud",  "Classify",
                                         "ClassifyCloud",  "RecognizeScene", "RecognizeSceneCloud",
                                         "GetGallery",     "ListGalleries",  "ListDescriptors",
                                         "GetServerStats", "ListSamples"};
  const std::vector<std::string> write = {"Train", "CreateGallery", "RemoveSamples",
                                          "ImportGallery", "ExportGallery"};
  for (int i = 0; i < service->method_count(); ++i) {
    const std::string name = service->method(i)->name();
    const std::string full = "/shapeid.v1.ShapeId/" + name;
    Scope expected = Scope::kAdmin;
    if (std::find(read.begin(), read.end(), name) != read.end()) expected = Scope::kRead;
    if (std::find(write.begin(), write.end(), name) != write.end()) expected = Scope::kWrite;
    ASSERT_TRUE(RequiredScope(full).has_value()) << full;
    EXPECT_EQ(*RequiredScope(full), expected) << full;
  }
  EXPECT_EQ(service->method_count(), 18) << "a new RPC: decide its scope in authorization.cc";
  EXPECT_FALSE(RequiredScope("/grpc.health.v1.Health/Check").has_value());
  EXPECT_FALSE(RequiredScope("/grpc.health.v1.Health/Watch").has_value());
  EXPECT_EQ(*RequiredScope("/shapeid.v1.ShapeId/Unknown"), Scope::kAdmin);
  EXPECT_EQ(*RequiredScope("/other.Service/Method"), Scope::kAdmin);
}

TEST(AuthorizationTest, DecisionsAndMessages) {
  const ApiKeyStore store = Store();
  const std::string train = "/shapeid.v1.ShapeId/Train";
  const std::string bearer_read = std::string("Bearer ") + kReadKey;
  EXPECT_TRUE(Authorize(ApiKeyStore(), train, std::nullopt).ok()) << "no keys: open";
  EXPECT_TRUE(Authorize(store, "/grpc.health.v1.Health/Check", std::nullopt).ok());

  const absl::Status missing = Authorize(store, train, std::nullopt);
  EXPECT_TRUE(absl::IsUnauthenticated(missing));
  EXPECT_THAT(missing.message(), HasSubstr("missing API key"));

  const absl::Status unknown = Authorize(store, train, "Bearer shapeid_wrong_0123456789abcdef");
  EXPECT_TRUE(absl::IsUnauthenticated(unknown));
  EXPECT_EQ(unknown.message(), "unknown API key");
  EXPECT_TRUE(absl::IsUnauthenticated(Authorize(store, train, kWriteKey)));  // no scheme
  EXPECT_TRUE(absl::IsUnauthenticated(Authorize(store, train, "Basic abc")));
  EXPECT_TRUE(absl::IsUnauthenticated(Authorize(store, train, "Bearer ")));

  const absl::Status denied = Authorize(store, train, bearer_read);
  EXPECT_TRUE(absl::IsPermissionDenied(denied));
  EXPECT_THAT(denied.message(), HasSubstr("key 'robot' lacks scope write"));
  EXPECT_THAT(denied.message(), Not(HasSubstr(kReadKey)));

  EXPECT_TRUE(Authorize(store, "/shapeid.v1.ShapeId/Classify", bearer_read).ok());
  EXPECT_TRUE(Authorize(store, train, std::string("bearer  ") + kWriteKey).ok());
  EXPECT_TRUE(Authorize(store, train, std::string("Bearer ") + kAdminKey).ok());
  EXPECT_TRUE(absl::IsPermissionDenied(
      Authorize(store, "/shapeid.v1.ShapeId/DeleteGallery", std::string("Bearer ") + kWriteKey)));
  EXPECT_TRUE(
      Authorize(store, "/shapeid.v1.ShapeId/DeleteGallery", std::string("Bearer ") + kAdminKey)
          .ok());
}

}  // namespace
}  // namespace shapeid
