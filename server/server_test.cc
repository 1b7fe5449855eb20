#include "server/server.h"

#include <unistd.h>

#include <cstdlib>
#include <string>

#include "absl/strings/str_cat.h"
#include "absl/time/clock.h"
#include "client/client.h"
#include "core/gallery/gallery_registry.h"
#include "core/testing/test_clouds.h"
#include "gmock/gmock.h"
#include "grpcpp/grpcpp.h"
#include "gtest/gtest.h"
#include "server/storage/sqlite_gallery_store.h"
#include "server/testing/raw_call.h"

namespace shapeid {
namespace {

using ::testing::HasSubstr;

std::string ScratchDir() {
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  const std::string dir =
      absl::StrCat(::testing::TempDir(), "/server_test_", getpid(), "_", info->name());
  std::system(absl::StrCat("rm -rf '", dir, "'").c_str());
  return dir;
}

// A data directory holding gallery "stored" with 5 samples, written through the store.
void WriteStoredGallery(const std::string& dir) {
  auto store = SqliteGalleryStore::Open({dir, false});
  ASSERT_TRUE(store.ok()) << store.status();
  std::shared_ptr<SqliteGalleryStore> shared = *std::move(store);
  GalleryRegistry registry({}, shared);
  ASSERT_TRUE(registry.LoadFromStore().ok());
  auto gallery = registry.Create("stored", {});
  ASSERT_TRUE(gallery.ok());
  std::vector<LabeledCloud> samples;
  for (uint32_t i = 0; i < 5; ++i) {
    samples.push_back({0, "box", testing_clouds::ShapeCloud(0, i, 200)});
  }
  ASSERT_TRUE((*gallery)->Train(samples).ok());
}

std::unique_ptr<Client> ClientFor(const ShapeIdServer& server) {
  ClientOptions options;
  options.target = server.address();
  options.max_attempts = 1;
  auto client = Client::Connect(options);
  EXPECT_TRUE(client.ok());
  return *std::move(client);
}

// Trains clouds[begin, end) into gallery "lab": cloud i is testing_clouds::ShapeCloud kind
// i % 3, labeled by its shape's name, with id i + 1.
void TrainShapes(Client& client, const std::vector<PointCloud>& clouds, uint32_t begin,
                 uint32_t end) {
  std::vector<TrainSample> samples;
  for (uint32_t i = begin; i < end; ++i) {
    samples.push_back({std::string(testing_clouds::kShapeNames[i % 3]), i + 1, &clouds[i]});
  }
  ASSERT_TRUE(client.Train("lab", samples).ok());
}

TEST(ShapeIdServerTest, NotServingUntilEveryGalleryIsLoaded) {
  const std::string dir = ScratchDir();
  WriteStoredGallery(dir);
  ServerOptions options;
  options.listen = "127.0.0.1:0";
  options.data_dir = dir;
  auto server = ShapeIdServer::Bind(options);
  ASSERT_TRUE(server.ok()) << server.status();
  auto client = ClientFor(**server);

  // Bound, but loading: health says NOT_SERVING and calls are refused, not answered from an
  // empty registry.
  EXPECT_EQ(client->CheckHealth().code(), absl::StatusCode::kUnavailable);
  const auto early = client->ListGalleries();
  EXPECT_EQ(early.status().code(), absl::StatusCode::kUnavailable);
  EXPECT_THAT(early.status().message(), HasSubstr("loading"));
  // The operator's calls answer in every state: stats say why nothing else does.
  const auto loading = client->GetServerStats();
  ASSERT_TRUE(loading.ok()) << loading.status();
  EXPECT_EQ(loading->state(), "loading");
  EXPECT_TRUE(client->SetLogLevel("warning").ok());

  auto report = (*server)->LoadGalleries();
  ASSERT_TRUE(report.ok()) << report.status();
  EXPECT_EQ(report->galleries, 1);
  EXPECT_EQ(report->samples, 5);
  EXPECT_TRUE(report->persistent);
  EXPECT_FALSE(report->read_only);
  EXPECT_TRUE(client->CheckHealth().ok());
  const auto galleries = client->ListGalleries();
  ASSERT_TRUE(galleries.ok()) << galleries.status();
  ASSERT_EQ(galleries->size(), 1u);
  EXPECT_EQ((*galleries)[0].sample_count(), 5u);
  const auto serving = client->GetServerStats();
  ASSERT_TRUE(serving.ok()) << serving.status();
  EXPECT_EQ(serving->state(), "serving");
  EXPECT_EQ(serving->log_level(), "warning");
  EXPECT_EQ(serving->samples(), 5u);
  EXPECT_EQ(serving->store(), dir);
}

// grpc.health.v1 Check of `service`: the status field of the reply (1 SERVING, 2 NOT_SERVING),
// -1 if the call failed (NOT_FOUND for an unknown service).
int HealthOf(const ShapeIdServer& server, const std::string& service) {
  auto channel = grpc::CreateChannel(server.address(), grpc::InsecureChannelCredentials());
  // HealthCheckRequest { string service = 1; }
  const std::string request =
      service.empty() ? std::string()
                      : absl::StrCat(std::string(1, '\x0a'),
                                     std::string(1, static_cast<char>(service.size())), service);
  std::string reply;
  const grpc::Status status =
      testing_raw::RawCall(channel, "/grpc.health.v1.Health/Check", {request}, &reply);
  if (!status.ok()) return -1;
  return reply.size() == 2 && reply[0] == '\x08' ? reply[1] : 0;  // SERVING_STATUS_UNKNOWN
}

TEST(ShapeIdServerTest, LivenessIsServingWhileReadinessIsNot) {
  ServerOptions options;
  options.listen = "127.0.0.1:0";
  auto server = ShapeIdServer::Bind(options);
  ASSERT_TRUE(server.ok()) << server.status();
  // Loading: not ready, but alive (a liveness probe must not restart a server that loads).
  EXPECT_EQ(HealthOf(**server, ""), 2);
  EXPECT_EQ(HealthOf(**server, kLivenessHealthService), 1);
  ASSERT_TRUE((*server)->LoadGalleries().ok());
  EXPECT_EQ(HealthOf(**server, ""), 1);
  EXPECT_EQ(HealthOf(**server, kLivenessHealthService), 1);
}

// The health-only port answers grpc.health.v1 and nothing else: not reflection, which would
// list the service on a port that has neither TLS nor keys.
TEST(ShapeIdServerTest, TheHealthPortAnswersHealthOnly) {
  ServerOptions options;
  options.listen = "127.0.0.1:0";
  options.health_listen = "127.0.0.1:0";
  auto server = ShapeIdServer::Start(options);
  ASSERT_TRUE(server.ok()) << server.status();
  const auto reflection = [](const std::string& address) {
    // ServerReflectionRequest { string list_services = 7; }: "*".
    return testing_raw::RawCall(grpc::CreateChannel(address, grpc::InsecureChannelCredentials()),
                                "/grpc.reflection.v1alpha.ServerReflection/ServerReflectionInfo",
                                {std::string("\x3a\x01*", 3)})
        .error_code();
  };
  EXPECT_EQ(reflection((*server)->address()), grpc::StatusCode::OK);
  EXPECT_EQ(reflection((*server)->health_address()), grpc::StatusCode::UNIMPLEMENTED);
  std::string reply;
  const grpc::Status health = testing_raw::RawCall(
      grpc::CreateChannel((*server)->health_address(), grpc::InsecureChannelCredentials()),
      "/grpc.health.v1.Health/Check", {""}, &reply);
  EXPECT_TRUE(health.ok()) << health.error_message();
  EXPECT_EQ(reply, std::string("\x08\x01", 2));  // SERVING
}

TEST(ShapeIdServerTest, AUnixSocketIsReportedByItsPath) {
  const std::string socket = ScratchDir() + ".sock";
  ServerOptions options;
  options.listen = "unix:" + socket;
  auto server = ShapeIdServer::Start(options);
  ASSERT_TRUE(server.ok()) << server.status();
  EXPECT_EQ((*server)->address(), "unix:" + socket);
  EXPECT_TRUE(ClientFor(**server)->CheckHealth().ok());
  unlink(socket.c_str());
}

TEST(ShapeIdServerTest, ADamagedStoreNeverServes) {
  const std::string dir = ScratchDir();
  WriteStoredGallery(dir);
  ASSERT_EQ(truncate((dir + "/galleries/stored.gallery").c_str(), 1000), 0);
  ServerOptions options;
  options.listen = "127.0.0.1:0";
  options.data_dir = dir;
  auto server = ShapeIdServer::Bind(options);
  ASSERT_TRUE(server.ok()) << server.status();
  auto report = (*server)->LoadGalleries();
  EXPECT_EQ(report.status().code(), absl::StatusCode::kDataLoss);
  EXPECT_THAT(report.status().message(), HasSubstr("stored.gallery"));
  auto client = ClientFor(**server);
  EXPECT_EQ(client->CheckHealth().code(), absl::StatusCode::kUnavailable);
  EXPECT_EQ(ShapeIdServer::Start(options).status().code(), absl::StatusCode::kFailedPrecondition)
      << "the first server still holds the directory's lock";
}

TEST(ShapeIdServerTest, EmptyDataDirMeansMemoryOnly) {
  ServerOptions options;
  options.listen = "127.0.0.1:0";
  auto server = ShapeIdServer::Start(options);
  ASSERT_TRUE(server.ok()) << server.status();
  EXPECT_FALSE((*server)->load_report().persistent);
  EXPECT_TRUE(ClientFor(**server)->CheckHealth().ok());
}

// The approximate index through the whole server: off below --approximate_min_vectors, on
// above it (GetGallery says so, every answer says which search ran), exact on request, and
// rebuilt when the galleries load again.
TEST(ShapeIdServerTest, ApproximateSearchAboveTheThresholdAndExactOnRequest) {
  const std::string dir = ScratchDir();
  ServerOptions options;
  options.listen = "127.0.0.1:0";
  options.data_dir = dir;
  options.gallery_limits.approximate.min_vectors = 96;
  options.gallery_limits.approximate.lists = 2;
  options.gallery_limits.approximate.probes = 1;
  std::vector<PointCloud> clouds;
  for (uint32_t i = 0; i < 150; ++i) clouds.push_back(testing_clouds::ShapeCloud(i % 3, i, 200));
  auto train = [&](Client& client, uint32_t begin, uint32_t end) {
    TrainShapes(client, clouds, begin, end);
  };
  {
    auto server = ShapeIdServer::Start(options);
    ASSERT_TRUE(server.ok()) << server.status();
    auto client = ClientFor(**server);
    v1::CreateGalleryRequest create;
    create.set_name("lab");
    ASSERT_TRUE(client->CreateGallery(create).ok());
    train(*client, 0, 60);
    EXPECT_EQ(client->GetGallery("lab")->approximate_lists(), 0u);  // 60 < 96 vectors
    auto exact = client->Classify("lab", clouds[0]);
    ASSERT_TRUE(exact.ok()) << exact.status();
    EXPECT_FALSE(exact->approximate());

    train(*client, 60, 150);
    // 150 vectors: 128 in whole blocks, 64 per cell at least, so 2 cells.
    EXPECT_EQ(client->GetGallery("lab")->approximate_lists(), 2u);
    auto approximate = client->Classify("lab", clouds[0]);
    ASSERT_TRUE(approximate.ok()) << approximate.status();
    EXPECT_TRUE(approximate->approximate());
    // The cloud's own descriptor lies in the cell its query vector probes first.
    ASSERT_GT(approximate->neighbors_size(), 0);
    EXPECT_EQ(approximate->neighbors(0).sample_id(), 1u);
    EXPECT_EQ(approximate->neighbors(0).distance(), 0.0);

    Client::ClassifyOptions call;
    call.exact = true;
    call.k = 5;
    auto forced = client->Classify("lab", clouds[0], call);
    ASSERT_TRUE(forced.ok()) << forced.status();
    EXPECT_FALSE(forced->approximate());
    EXPECT_EQ(forced->neighbors_size(), 5);
    EXPECT_EQ(forced->label(), approximate->label());
  }
  // Derived state: the lists are not stored; they are rebuilt in the background once the
  // galleries are loaded (the server serves exact searches meanwhile).
  auto server = ShapeIdServer::Start(options);
  ASSERT_TRUE(server.ok()) << server.status();
  auto client = ClientFor(**server);
  for (int i = 0; i < 500 && client->GetGallery("lab")->approximate_lists() == 0; ++i) {
    absl::SleepFor(absl::Milliseconds(10));
  }
  EXPECT_EQ(client->GetGallery("lab")->approximate_lists(), 2u);
  auto again = client->Classify("lab", clouds[0]);
  ASSERT_TRUE(again.ok()) << again.status();
  EXPECT_TRUE(again->approximate());
  EXPECT_EQ(again->neighbors(0).sample_id(), 1u);
}

// --learn: the server fits a trained head once a gallery settles; Classify then answers with it
// and GetGallery shows it. Heads are derived state: a restarted server fits the same one.
TEST(ShapeIdServerTest, ALearningServerFitsAHeadAndFitsTheSameAfterARestart) {
  const std::string dir = ScratchDir();
  ServerOptions options;
  options.listen = "127.0.0.1:0";
  options.data_dir = dir;
  options.learn = true;
  options.learner.settle = absl::Milliseconds(50);
  options.learner.poll = absl::Milliseconds(10);
  options.learner.head.mlp.hidden = {16};
  options.learner.head.mlp.epochs = 10;
  std::vector<PointCloud> clouds;
  for (uint32_t i = 0; i < 30; ++i) clouds.push_back(testing_clouds::ShapeCloud(i % 3, i, 200));
  const auto wait_for_head = [](Client& client) {
    for (int i = 0; i < 3000 && !client.GetGallery("lab")->has_head(); ++i) {
      absl::SleepFor(absl::Milliseconds(10));
    }
    return *client.GetGallery("lab");
  };
  v1::Gallery first;
  {
    auto server = ShapeIdServer::Start(options);
    ASSERT_TRUE(server.ok()) << server.status();
    auto client = ClientFor(**server);
    v1::CreateGalleryRequest create;
    create.set_name("lab");
    ASSERT_TRUE(client->CreateGallery(create).ok());
    TrainShapes(*client, clouds, 0, static_cast<uint32_t>(clouds.size()));
    first = wait_for_head(*client);
    ASSERT_TRUE(first.has_head());
    EXPECT_EQ(first.head().fitted_version(), first.version());
    EXPECT_TRUE(first.head().answers());
    EXPECT_EQ(first.head().fitted_samples() + first.head().holdout_samples(), 30u);
    auto answer = client->Classify("lab", clouds[4]);
    ASSERT_TRUE(answer.ok()) << answer.status();
    EXPECT_TRUE(answer->by_head());
    EXPECT_EQ(answer->label(), testing_clouds::kShapeNames[1]);
    EXPECT_GT(answer->neighbors_size(), 0);
  }
  auto server = ShapeIdServer::Start(options);
  ASSERT_TRUE(server.ok()) << server.status();
  auto client = ClientFor(**server);
  const v1::Gallery again = wait_for_head(*client);
  ASSERT_TRUE(again.has_head());
  // (A data_dir gallery restarts at version 0: SQLite stores no version, PostgreSQL does.)
  EXPECT_EQ(again.head().fitted_version(), again.version());
  EXPECT_EQ(again.head().fitted_samples(), first.head().fitted_samples());
  EXPECT_EQ(again.head().holdout_accuracy(), first.head().holdout_accuracy());
  EXPECT_TRUE(client->Classify("lab", clouds[4])->by_head());
}

TEST(ShapeIdServerTest, RefusesInvalidApproximateOptions) {
  ServerOptions options;
  options.listen = "127.0.0.1:0";
  options.gallery_limits.approximate.probes = -1;
  auto server = ShapeIdServer::Start(options);
  ASSERT_FALSE(server.ok());
  EXPECT_EQ(server.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(std::string(server.status().message()), HasSubstr("probes -1"));
}

}  // namespace
}  // namespace shapeid
