// Security through a real in-process server and the C++ client: every RPC with no key, a
// wrong key and each scope; TLS and mutual TLS with certificates made by openssl; every
// limit tripping with its error while the server stays healthy.

#include <atomic>
#include <chrono>
#include <functional>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "absl/strings/str_cat.h"
#include "client/client.h"
#include "core/testing/test_clouds.h"
#include "gmock/gmock.h"
#include "grpcpp/grpcpp.h"
#include "gtest/gtest.h"
#include "server/security/api_keys.h"
#include "server/server.h"
#include "shapeid/v1/shapeid.grpc.pb.h"
#include "tests/test_certificates.h"

namespace shapeid {
namespace {

using ::testing::HasSubstr;
using ::testing::Not;
using testing_clouds::ShapeCloud;

constexpr char kReadKey[] = "shapeid_test_read_0123456789abcdef0123";
constexpr char kWriteKey[] = "shapeid_test_write_0123456789abcdef0123";
constexpr char kAdminKey[] = "shapeid_test_admin_0123456789abcdef0123";
constexpr char kWrongKey[] = "shapeid_test_wrong_0123456789abcdef0123";

std::string KeysText() {
  return absl::StrCat("robot read ", Sha256Hex(kReadKey), "; trainer write ", Sha256Hex(kWriteKey),
                      "; ops admin ", Sha256Hex(kAdminKey));
}

std::unique_ptr<ShapeIdServer> StartServer(ServerOptions options) {
  options.listen = "127.0.0.1:0";
  auto server = ShapeIdServer::Start(options);
  EXPECT_TRUE(server.ok()) << server.status();
  return server.ok() ? std::move(server).value() : nullptr;
}

std::unique_ptr<Client> Connect(ClientOptions options) {
  options.max_attempts = 1;  // a refused handshake is UNAVAILABLE: do not wait for retries
  options.deadline = absl::Seconds(20);
  auto client = Client::Connect(options);
  EXPECT_TRUE(client.ok()) << client.status();
  return client.ok() ? std::move(client).value() : nullptr;
}

std::unique_ptr<Client> Connect(const std::string& target, const std::string& key,
                                size_t chunk_points = 16384) {
  ClientOptions options;
  options.target = target;
  options.api_key = key;
  options.chunk_points = chunk_points;
  return Connect(options);
}

absl::Status Train(Client& client, const std::string& gallery, int samples, uint32_t seed = 1) {
  std::vector<PointCloud> clouds;
  for (int i = 0; i < samples; ++i) clouds.push_back(ShapeCloud(i % 3, seed + i, 200));
  std::vector<TrainSample> batch;
  for (int i = 0; i < samples; ++i)
    batch.push_back({"shape" + std::to_string(i % 3), 0, &clouds[i]});
  return client.Train(gallery, batch).status();
}

absl::Status Create(Client& client, const std::string& name) {
  v1::CreateGalleryRequest request;
  request.set_name(name);
  return client.CreateGallery(request).status();
}

// ---------------------------------------------------------------------------------------------
// API keys: every RPC x {no key, wrong key, read, write, admin}.

class ApiKeyTest : public ::testing::Test {
 protected:
  void SetUp() override {
    ServerOptions options;
    options.security.api_keys = KeysText();
    server_ = StartServer(options);
    ASSERT_NE(server_, nullptr);
    admin_ = Connect(server_->address(), kAdminKey);
    ASSERT_TRUE(Create(*admin_, "g").ok());
    ASSERT_TRUE(Train(*admin_, "g", 6).ok());
    ASSERT_TRUE(admin_
                    ->ExportGallery("g",
                                    [this](const v1::GalleryExportChunk& chunk) {
                                      exported_.push_back(chunk);
                                      return absl::OkStatus();
                                    })
                    .ok());
  }

  std::unique_ptr<ShapeIdServer> server_;
  std::unique_ptr<Client> admin_;
  std::vector<v1::GalleryExportChunk> exported_;
};

struct Caller {
  Client* unary;   // clouds in one message: DescribeCloud, ClassifyCloud
  Client* stream;  // 8 points per chunk: every cloud streams through Describe, Classify
};

struct Rpc {
  const char* method;
  Scope needs;
  absl::StatusCode when_allowed;  // what the call answers once past the gate
  std::function<absl::Status(const Caller&, int)> call;
};

TEST_F(ApiKeyTest, EveryRpcGivesTheRightCodeForEveryKey) {
  const PointCloud cloud = ShapeCloud(1, 99, 64);
  const std::vector<v1::GalleryExportChunk>& exported = exported_;
  const std::vector<Rpc> rpcs = {
      {"Describe", Scope::kRead, absl::StatusCode::kOk,
       [&](const Caller& c, int) { return c.stream->Describe(cloud).status(); }},
      {"DescribeCloud", Scope::kRead, absl::StatusCode::kOk,
       [&](const Caller& c, int) { return c.unary->Describe(cloud).status(); }},
      {"Classify", Scope::kRead, absl::StatusCode::kOk,
       [&](const Caller& c, int) { return c.stream->Classify("g", cloud).status(); }},
      {"ClassifyCloud", Scope::kRead, absl::StatusCode::kOk,
       [&](const Caller& c, int) { return c.unary->Classify("g", cloud).status(); }},
      {"GetGallery", Scope::kRead, absl::StatusCode::kOk,
       [&](const Caller& c, int) { return c.unary->GetGallery("g").status(); }},
      {"ListGalleries", Scope::kRead, absl::StatusCode::kOk,
       [&](const Caller& c, int) { return c.unary->ListGalleries().status(); }},
      {"ListDescriptors", Scope::kRead, absl::StatusCode::kOk,
       [&](const Caller& c, int) { return c.unary->ListDescriptors().status(); }},
      {"Train", Scope::kWrite, absl::StatusCode::kOk,
       [&](const Caller& c, int) { return Train(*c.stream, "g", 1); }},
      {"CreateGallery", Scope::kWrite, absl::StatusCode::kOk,
       [&](const Caller& c, int n) { return Create(*c.unary, absl::StrCat("created-", n)); }},
      {"RemoveSamples", Scope::kWrite, absl::StatusCode::kNotFound,
       [&](const Caller& c, int) {
         const uint64_t id = 999999;
         return c.unary->RemoveSamples("g", {&id, 1}, {}).status();
       }},
      {"ImportGallery", Scope::kWrite, absl::StatusCode::kOk,
       [&](const Caller& c, int n) {
         size_t next = 0;
         return c.unary
             ->ImportGallery(
                 [&](v1::GalleryExportChunk* chunk) -> absl::StatusOr<bool> {
                   if (next == exported.size()) return false;
                   *chunk = exported[next++];
                   return true;
                 },
                 absl::StrCat("imported-", n))
             .status();
       }},
      {"ExportGallery", Scope::kWrite, absl::StatusCode::kOk,
       [&](const Caller& c, int) {
         return c.unary->ExportGallery(
             "g", [](const v1::GalleryExportChunk&) { return absl::OkStatus(); });
       }},
      {"DeleteGallery", Scope::kAdmin, absl::StatusCode::kNotFound,
       [&](const Caller& c, int) { return c.unary->DeleteGallery("absent").status(); }},
      {"GetServerStats", Scope::kRead, absl::StatusCode::kOk,
       [&](const Caller& c, int) { return c.unary->GetServerStats().status(); }},
      {"SetLogLevel", Scope::kAdmin, absl::StatusCode::kOk,
       [&](const Caller& c, int) { return c.unary->SetLogLevel("info").status(); }},
  };
  struct Key {
    const char* name;
    std::string key;
    std::optional<Scope> scope;  // nullopt: not a valid key
  };
  const Key keys[] = {{"no key", "", std::nullopt},
                      {"wrong key", kWrongKey, std::nullopt},
                      {"read key", kReadKey, Scope::kRead},
                      {"write key", kWriteKey, Scope::kWrite},
                      {"admin key", kAdminKey, Scope::kAdmin}};
  int n = 0;
  for (const Key& key : keys) {
    std::unique_ptr<Client> unary = Connect(server_->address(), key.key);
    std::unique_ptr<Client> stream = Connect(server_->address(), key.key, /*chunk_points=*/8);
    const Caller caller{unary.get(), stream.get()};
    for (const Rpc& rpc : rpcs) {
      const absl::Status status = rpc.call(caller, n++);
      SCOPED_TRACE(absl::StrCat(rpc.method, " with ", key.name, ": ", status.ToString()));
      if (!key.scope.has_value()) {
        EXPECT_EQ(status.code(), absl::StatusCode::kUnauthenticated);
        EXPECT_THAT(status.message(),
                    HasSubstr(key.key.empty() ? "missing API key" : "unknown API key"));
      } else if (!ScopeAllows(*key.scope, rpc.needs)) {
        EXPECT_EQ(status.code(), absl::StatusCode::kPermissionDenied);
        EXPECT_THAT(status.message(),
                    HasSubstr(absl::StrCat("lacks scope ", ScopeName(rpc.needs))));
      } else {
        EXPECT_EQ(status.code(), rpc.when_allowed);
      }
      EXPECT_THAT(status.message(), Not(HasSubstr("shapeid_test_")));  // never the key
    }
    // Health checks need no key (Kubernetes' gRPC probes cannot send one).
    EXPECT_TRUE(unary->CheckHealth().ok()) << key.name;
  }
  EXPECT_EQ(rpcs.size(), 15u) << "every RPC of the ShapeId service";
}

TEST_F(ApiKeyTest, ScopeDeniedNamesTheKeyNotTheKey) {
  std::unique_ptr<Client> robot = Connect(server_->address(), kReadKey);
  const absl::Status denied = robot->DeleteGallery("g").status();
  EXPECT_EQ(denied.code(), absl::StatusCode::kPermissionDenied);
  EXPECT_THAT(denied.message(), HasSubstr("key 'robot' lacks scope admin"));
  EXPECT_EQ(admin_->GetGallery("g")->sample_count(), 6u) << "nothing was deleted";
}

TEST(ApiKeyClientTest, KeysWithUnsendableCharactersAreRefusedWithoutQuotingThem) {
  ClientOptions options;
  options.api_key = "shapeid_secret_with_newline\n";
  const absl::Status status = Client::Connect(options).status();
  EXPECT_TRUE(absl::IsInvalidArgument(status));
  EXPECT_THAT(status.message(), Not(HasSubstr("shapeid_secret")));
}

// ---------------------------------------------------------------------------------------------
// TLS and mutual TLS.

class TlsTest : public ::testing::Test {
 protected:
  static std::string Cert(const std::string& file) { return TestCertificates::Path(file); }

  std::unique_ptr<ShapeIdServer> StartTls(bool mutual) {
    ServerOptions options;
    options.security.tls_cert_file = Cert("server.pem");
    options.security.tls_key_file = Cert("server.key");
    if (mutual) options.security.tls_client_ca_file = Cert("ca.pem");
    return StartServer(options);
  }

  static ClientOptions TlsClient(const std::string& target, const std::string& ca) {
    ClientOptions options;
    options.target = target;
    options.tls_ca_file = Cert(ca);
    return options;
  }
};

TEST_F(TlsTest, TlsWorksAndPlaintextOrAnUntrustedServerDoesNot) {
  ASSERT_FALSE(TestCertificates::Dir().empty());
  std::unique_ptr<ShapeIdServer> server = StartTls(/*mutual=*/false);
  ASSERT_NE(server, nullptr);
  std::unique_ptr<Client> tls = Connect(TlsClient(server->address(), "ca.pem"));
  EXPECT_TRUE(tls->CheckHealth().ok());
  ASSERT_TRUE(Create(*tls, "over-tls").ok());
  ASSERT_TRUE(Train(*tls, "over-tls", 3).ok());
  EXPECT_TRUE(tls->Classify("over-tls", ShapeCloud(0, 5, 300)).ok());

  // "localhost" is in the certificate too, and a name it lacks fails.
  ClientOptions by_name = TlsClient(server->address(), "ca.pem");
  by_name.tls_server_name = "localhost";
  EXPECT_TRUE(Connect(by_name)->ListGalleries().ok());
  by_name.tls_server_name = "elsewhere.example";
  EXPECT_EQ(Connect(by_name)->ListGalleries().status().code(), absl::StatusCode::kUnavailable);

  ClientOptions plaintext;
  plaintext.target = server->address();
  EXPECT_EQ(Connect(plaintext)->ListGalleries().status().code(), absl::StatusCode::kUnavailable);
  std::unique_ptr<Client> untrusting = Connect(TlsClient(server->address(), "other-ca.pem"));
  EXPECT_EQ(untrusting->ListGalleries().status().code(), absl::StatusCode::kUnavailable);
  EXPECT_TRUE(tls->CheckHealth().ok()) << "still serving";
}

TEST_F(TlsTest, AHealthOnlyPlaintextPortForProbesThatCannotDoTls) {
  ASSERT_FALSE(TestCertificates::Dir().empty());
  ServerOptions options;
  options.security.tls_cert_file = Cert("server.pem");
  options.security.tls_key_file = Cert("server.key");
  options.security.tls_client_ca_file = Cert("ca.pem");
  options.security.api_keys = KeysText();
  options.health_listen = "127.0.0.1:0";
  std::unique_ptr<ShapeIdServer> server = StartServer(options);
  ASSERT_NE(server, nullptr);
  ASSERT_FALSE(server->health_address().empty());
  ClientOptions probe;  // plaintext, no key, no certificate: what a kubelet sends
  probe.target = server->health_address();
  std::unique_ptr<Client> kubelet = Connect(probe);
  EXPECT_TRUE(kubelet->CheckHealth().ok());
  EXPECT_EQ(kubelet->ListGalleries().status().code(), absl::StatusCode::kUnimplemented)
      << "health only";
  server->Shutdown(absl::ZeroDuration());
  EXPECT_FALSE(kubelet->CheckHealth().ok());
}

TEST_F(TlsTest, TlsClientToAPlaintextServerFails) {
  std::unique_ptr<ShapeIdServer> server = StartServer(ServerOptions());
  ASSERT_NE(server, nullptr);
  EXPECT_EQ(Connect(TlsClient(server->address(), "ca.pem"))->ListGalleries().status().code(),
            absl::StatusCode::kUnavailable);
}

TEST_F(TlsTest, MutualTlsNeedsAClientCertificateFromTheRightCa) {
  ASSERT_FALSE(TestCertificates::Dir().empty());
  std::unique_ptr<ShapeIdServer> server = StartTls(/*mutual=*/true);
  ASSERT_NE(server, nullptr);
  ClientOptions with_cert = TlsClient(server->address(), "ca.pem");
  with_cert.tls_cert_file = Cert("client.pem");
  with_cert.tls_key_file = Cert("client.key");
  EXPECT_TRUE(Connect(with_cert)->ListGalleries().ok());

  std::unique_ptr<Client> no_cert = Connect(TlsClient(server->address(), "ca.pem"));
  EXPECT_EQ(no_cert->ListGalleries().status().code(), absl::StatusCode::kUnavailable);

  ClientOptions other_ca = TlsClient(server->address(), "ca.pem");
  other_ca.tls_cert_file = Cert("other-client.pem");
  other_ca.tls_key_file = Cert("other-client.key");
  EXPECT_EQ(Connect(other_ca)->ListGalleries().status().code(), absl::StatusCode::kUnavailable);

  EXPECT_TRUE(Connect(with_cert)->CheckHealth().ok()) << "still serving";
}

TEST_F(TlsTest, ClientTlsOptionsAreChecked) {
  ClientOptions half = TlsClient("127.0.0.1:1", "ca.pem");
  half.tls_cert_file = Cert("client.pem");  // no key
  EXPECT_THAT(Client::Connect(half).status().message(), HasSubstr("give both TLS files"));
  ClientOptions missing = TlsClient("127.0.0.1:1", "absent.pem");
  EXPECT_THAT(Client::Connect(missing).status().message(),
              HasSubstr("cannot read the TLS CA file"));
  ClientOptions name_only;
  name_only.tls_server_name = "localhost";
  EXPECT_TRUE(absl::IsInvalidArgument(Client::Connect(name_only).status()));
}

TEST(ExposureTest, ANetworkAddressWithoutTlsOrKeysIsRefusedBeforeBinding) {
  ServerOptions options;
  options.listen = "0.0.0.0:0";
  const absl::Status refused = ShapeIdServer::Bind(options).status();
  EXPECT_TRUE(absl::IsFailedPrecondition(refused));
  EXPECT_THAT(refused.message(), HasSubstr("refusing to listen on 0.0.0.0:0"));
}

// ---------------------------------------------------------------------------------------------
// Limits: each trips with its error, and the server goes on serving.

class LimitsTest : public ::testing::Test {
 protected:
  void SetUp() override {
    ServerOptions options;
    options.gallery_limits.max_points_per_cloud = 1000;
    options.max_message_bytes = 8 << 10;
    options.service.max_samples_per_train = 3;
    options.gallery_limits.max_samples_per_gallery = 5;
    options.gallery_limits.max_galleries = 3;
    options.service.max_streams_per_client = 2;
    server_ = StartServer(options);
    ASSERT_NE(server_, nullptr);
    client_ = Connect(server_->address(), "", /*chunk_points=*/256);
    ASSERT_TRUE(Create(*client_, "g").ok());
    ASSERT_TRUE(Train(*client_, "g", 3).ok());
  }

  // Serving: health, a read and a classification still answer.
  void ExpectHealthy() {
    EXPECT_TRUE(client_->CheckHealth().ok());
    EXPECT_TRUE(client_->GetGallery("g").ok());
    EXPECT_TRUE(client_->Classify("g", ShapeCloud(1, 7, 500)).ok());
  }

  std::unique_ptr<ShapeIdServer> server_;
  std::unique_ptr<Client> client_;
};

TEST_F(LimitsTest, PointsPerCloud) {
  const absl::Status status = client_->Classify("g", ShapeCloud(1, 7, 1001)).status();
  EXPECT_EQ(status.code(), absl::StatusCode::kResourceExhausted);
  EXPECT_THAT(status.message(), HasSubstr("1001 points, more than the limit of 1000 "
                                          "(max_points_per_cloud)"));
  ExpectHealthy();
}

TEST_F(LimitsTest, BytesPerMessage) {
  // 700 points in one message: 8,400 bytes of points, over the 8 KiB limit.
  std::unique_ptr<Client> one_message = Connect(server_->address(), "", /*chunk_points=*/1000);
  const absl::Status status = one_message->Describe(ShapeCloud(1, 7, 700)).status();
  EXPECT_EQ(status.code(), absl::StatusCode::kResourceExhausted);
  EXPECT_THAT(status.message(), HasSubstr("8192"));
  ExpectHealthy();
}

TEST_F(LimitsTest, SamplesPerTrainStream) {
  const absl::Status status = Train(*client_, "g", 4);
  EXPECT_EQ(status.code(), absl::StatusCode::kResourceExhausted);
  EXPECT_THAT(status.message(),
              HasSubstr("more than 3 samples, the limit per stream (max_samples_per_train)"));
  EXPECT_EQ(client_->GetGallery("g")->sample_count(), 3u) << "all or nothing";
  ExpectHealthy();
}

TEST_F(LimitsTest, SamplesPerGallery) {
  ASSERT_TRUE(Train(*client_, "g", 2).ok());
  const absl::Status status = Train(*client_, "g", 1);
  EXPECT_EQ(status.code(), absl::StatusCode::kResourceExhausted);
  EXPECT_THAT(status.message(), HasSubstr("max_samples_per_gallery = 5"));
  ExpectHealthy();
}

TEST_F(LimitsTest, NumberOfGalleriesAndTheirNames) {
  ASSERT_TRUE(Create(*client_, "g2").ok());
  ASSERT_TRUE(Create(*client_, "g3").ok());
  const absl::Status full = Create(*client_, "g4");
  EXPECT_EQ(full.code(), absl::StatusCode::kResourceExhausted);
  EXPECT_THAT(full.message(), HasSubstr("3 galleries exist, the limit (max_galleries) is 3"));
  const absl::Status bad_name = Create(*client_, "../etc");
  EXPECT_EQ(bad_name.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(bad_name.message(), HasSubstr("[A-Za-z0-9]"));
  ExpectHealthy();
}

TEST_F(LimitsTest, ConcurrentStreamsPerClient) {
  // Two Train streams held open (header sent, never closed), then a third is refused.
  auto channel = grpc::CreateChannel(server_->address(), grpc::InsecureChannelCredentials());
  auto stub = v1::ShapeId::NewStub(channel);
  struct Open {
    grpc::ClientContext context;
    v1::TrainResponse response;
    std::unique_ptr<grpc::ClientWriter<v1::TrainRequest>> writer;
  };
  const auto open = [&](Open* s) {
    s->context.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(20));
    s->writer = stub->Train(&s->context, &s->response);
    v1::TrainRequest header;
    header.mutable_header()->set_gallery("g");
    return s->writer->Write(header);
  };
  Open first, second;
  ASSERT_TRUE(open(&first));
  ASSERT_TRUE(open(&second));
  // Both are admitted once the server has got to them, and the fixture's Train, answered,
  // has been let go (its OnDone can trail its status under load): two calls in flight.
  for (int i = 0; i < 500 && server_->calls_in_flight() != 2; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  ASSERT_EQ(server_->calls_in_flight(), 2);
  const PointCloud cloud = ShapeCloud(1, 7, 500);  // 500 > 256 points: a Classify stream
  const absl::Status refused = client_->Classify("g", cloud).status();
  EXPECT_EQ(refused.code(), absl::StatusCode::kResourceExhausted);
  EXPECT_THAT(refused.message(),
              HasSubstr("client 127.0.0.1 has 2 streams open, the limit (max_streams_per_client) "
                        "is 2"));
  // Unary calls are not streams: still served.
  EXPECT_TRUE(client_->GetGallery("g").ok());

  first.writer->WritesDone();
  EXPECT_EQ(first.writer->Finish().error_code(), grpc::StatusCode::INVALID_ARGUMENT);  // no sample
  // Its slot is free before its answer is sent: the next stream gets it at once.
  EXPECT_TRUE(client_->Classify("g", ShapeCloud(1, 7, 500)).ok());
  second.context.TryCancel();
  second.writer->Finish();
  ExpectHealthy();
}

TEST(CallCeilingTest, AStreamPastTheCeilingIsEndedAndItsSlotFreed) {
  ServerOptions options;
  options.service.max_call = absl::Milliseconds(300);
  options.service.max_streams_per_client = 1;
  std::unique_ptr<ShapeIdServer> server = StartServer(options);
  ASSERT_NE(server, nullptr);
  std::unique_ptr<Client> client = Connect(server->address(), "", /*chunk_points=*/64);
  ASSERT_TRUE(Create(*client, "g").ok());
  ASSERT_TRUE(Train(*client, "g", 3).ok()) << "a stream that ends in time is not affected";

  // A Train stream with no deadline that never ends.
  auto stub = v1::ShapeId::NewStub(
      grpc::CreateChannel(server->address(), grpc::InsecureChannelCredentials()));
  grpc::ClientContext context;
  v1::TrainResponse response;
  const auto start = std::chrono::steady_clock::now();
  auto writer = stub->Train(&context, &response);
  v1::TrainRequest header;
  header.mutable_header()->set_gallery("g");
  writer->Write(header);
  const grpc::Status cut = writer->Finish();  // waits for the server's answer
  const auto took = std::chrono::steady_clock::now() - start;
  EXPECT_EQ(cut.error_code(), grpc::StatusCode::DEADLINE_EXCEEDED);
  EXPECT_THAT(cut.error_message(), HasSubstr("this server's limit per call (max_call_seconds)"));
  EXPECT_GE(took, std::chrono::milliseconds(250));
  EXPECT_LT(took, std::chrono::seconds(10));
  EXPECT_EQ(client->GetGallery("g")->sample_count(), 3u);

  // Its slot, the client's only one, is free again: the next stream gets it at once.
  EXPECT_TRUE(client->Classify("g", ShapeCloud(1, 7, 500)).ok());  // a stream: 500 > 64 points
  EXPECT_TRUE(client->CheckHealth().ok());
}

TEST(CallCeilingTest, AnExportPastTheCeilingStopsBeforeItsNextChunk) {
  ServerOptions options;
  options.service.max_call = absl::Nanoseconds(1);  // past before the first chunk
  std::unique_ptr<ShapeIdServer> server = StartServer(options);
  ASSERT_NE(server, nullptr);
  std::unique_ptr<Client> client = Connect(server->address(), "");
  ASSERT_TRUE(Create(*client, "g").ok());
  int chunks = 0;
  const absl::Status status = client->ExportGallery("g", [&](const v1::GalleryExportChunk&) {
    ++chunks;
    return absl::OkStatus();
  });
  EXPECT_EQ(status.code(), absl::StatusCode::kDeadlineExceeded);
  EXPECT_THAT(status.message(), HasSubstr("max_call_seconds"));
  EXPECT_EQ(chunks, 0);
  EXPECT_TRUE(client->GetGallery("g").ok()) << "unary calls have no ceiling";
  EXPECT_TRUE(client->CheckHealth().ok());
}

}  // namespace
}  // namespace shapeid
