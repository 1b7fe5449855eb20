// shapeid::Client against an in-process ShapeIdServer on a loopback port: every call, chunking
// of a big cloud, export and import, error codes, retries with backoff, deadlines, concurrent
// use.

#include "client/client.h"

#include <atomic>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include "absl/strings/str_cat.h"
#include "gmock/gmock.h"
#include "grpcpp/grpcpp.h"
#include "gtest/gtest.h"
#include "server/server.h"

namespace shapeid {
namespace {

using ::testing::HasSubstr;

PointCloud Shape(int kind, uint32_t seed, size_t n = 600) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  PointCloud cloud;
  for (size_t i = 0; i < n; ++i) {
    if (kind == 0) {
      cloud.Add(2 * u(rng), 1.5f * u(rng), 0.1f * u(rng));
    } else {
      cloud.Add(3 * u(rng), 0.05f * u(rng), 0.05f * u(rng));
    }
  }
  return cloud;
}

class ClientTest : public ::testing::Test {
 protected:
  void SetUp() override {
    ServerOptions server_options;
    server_options.listen = "127.0.0.1:0";
    auto server = ShapeIdServer::Start(server_options);
    ASSERT_TRUE(server.ok()) << server.status();
    server_ = std::move(server).value();
    ClientOptions options;
    options.target = server_->address();
    options.chunk_points = 1000;  // small clouds still span several chunks
    auto client = Client::Connect(options);
    ASSERT_TRUE(client.ok()) << client.status();
    client_ = std::move(client).value();
  }

  void CreateTrained(const std::string& name) {
    v1::CreateGalleryRequest request;
    request.set_name(name);
    ASSERT_TRUE(client_->CreateGallery(request).ok());
    std::vector<PointCloud> clouds;
    for (int i = 0; i < 6; ++i) clouds.push_back(Shape(i % 2, 100 + i));
    std::vector<TrainSample> samples;
    for (int i = 0; i < 6; ++i) {
      samples.push_back({i % 2 == 0 ? "box" : "rod", static_cast<uint64_t>(i + 1), &clouds[i]});
    }
    auto trained = client_->Train(name, samples);
    ASSERT_TRUE(trained.ok()) << trained.status();
    EXPECT_EQ(trained->sample_ids_size(), 6);
    EXPECT_EQ(trained->gallery_sample_count(), 6u);
  }

  std::unique_ptr<ShapeIdServer> server_;
  std::unique_ptr<Client> client_;
};

TEST(ClientConnectTest, RejectsBadOptions) {
  ClientOptions options;
  options.max_attempts = 0;
  EXPECT_TRUE(absl::IsInvalidArgument(Client::Connect(options).status()));
  options = ClientOptions();
  options.target = "";
  EXPECT_TRUE(absl::IsInvalidArgument(Client::Connect(options).status()));
  options = ClientOptions();
  options.chunk_points = 0;
  EXPECT_TRUE(absl::IsInvalidArgument(Client::Connect(options).status()));
}

TEST_F(ClientTest, EveryCallRoundTrips) {
  EXPECT_TRUE(client_->CheckHealth().ok());

  auto descriptors = client_->ListDescriptors();
  ASSERT_TRUE(descriptors.ok()) << descriptors.status();
  EXPECT_FALSE(descriptors->empty());

  auto described = client_->Describe(Shape(0, 1), "rphsd");
  ASSERT_TRUE(described.ok()) << described.status();
  EXPECT_EQ(described->num_points(), 600u);
  EXPECT_FALSE(described->values().empty());

  CreateTrained("parts");
  auto gallery = client_->GetGallery("parts");
  ASSERT_TRUE(gallery.ok()) << gallery.status();
  EXPECT_EQ(gallery->sample_count(), 6u);

  auto classified = client_->Classify("parts", Shape(1, 999), 3);
  ASSERT_TRUE(classified.ok()) << classified.status();
  EXPECT_EQ(classified->label(), "rod");
  EXPECT_EQ(classified->num_points(), 600u);

  auto list = client_->ListGalleries();
  ASSERT_TRUE(list.ok()) << list.status();
  ASSERT_EQ(list->size(), 1u);
  EXPECT_EQ((*list)[0].name(), "parts");

  const uint64_t ids[] = {1};
  const std::string labels[] = {"rod"};
  auto removed = client_->RemoveSamples("parts", ids, labels);
  ASSERT_TRUE(removed.ok()) << removed.status();
  EXPECT_EQ(removed->removed(), 4u);
  EXPECT_EQ(removed->remaining(), 2u);

  auto deleted = client_->DeleteGallery("parts");
  ASSERT_TRUE(deleted.ok()) << deleted.status();
  EXPECT_EQ(*deleted, 2u);
}

TEST_F(ClientTest, ClassifyInOneMessageOrStreamedGivesTheSameAnswer) {
  CreateTrained("parts");
  // 1,500 points: over this client's chunk_points (1,000), so it streams; a client with the
  // default 16,384 sends the same cloud in one ClassifyCloud message.
  const PointCloud cloud = Shape(0, 77, 1500);
  auto streamed = client_->Classify("parts", cloud, 3);
  ASSERT_TRUE(streamed.ok()) << streamed.status();
  ClientOptions options;
  options.target = server_->address();
  auto one_message_client = Client::Connect(options);
  ASSERT_TRUE(one_message_client.ok());
  auto one_message = (*one_message_client)->Classify("parts", cloud, 3);
  ASSERT_TRUE(one_message.ok()) << one_message.status();
  EXPECT_EQ(one_message->label(), "box");
  EXPECT_EQ(one_message->label(), streamed->label());
  ASSERT_EQ(one_message->neighbors_size(), streamed->neighbors_size());
  for (int i = 0; i < streamed->neighbors_size(); ++i) {
    EXPECT_EQ(one_message->neighbors(i).sample_id(), streamed->neighbors(i).sample_id());
    EXPECT_EQ(one_message->neighbors(i).distance(), streamed->neighbors(i).distance());
  }
  // Errors keep their code on the one-message path too.
  EXPECT_TRUE(absl::IsNotFound((*one_message_client)->Classify("missing", cloud).status()));
}

// Reads a client stream to its end, then answers OK (the response is set beforehand).
template <typename Request>
class DrainReactor final : public grpc::ServerReadReactor<Request> {
 public:
  DrainReactor() { this->StartRead(&request_); }
  void OnReadDone(bool ok) override {
    if (ok) {
      this->StartRead(&request_);
    } else {
      this->Finish(grpc::Status::OK);
    }
  }
  void OnDone() override { delete this; }

 private:
  Request request_;
};

// A server from before DescribeCloud and ClassifyCloud: only the streaming calls, which
// answer "streamed".
class StreamOnlyService final : public v1::ShapeId::CallbackService {
 public:
  std::atomic<int> streams{0};

  grpc::ServerReadReactor<v1::DescribeRequest>* Describe(grpc::CallbackServerContext* /*context*/,
                                                         v1::DescribeResponse* response) override {
    ++streams;
    response->set_descriptor_spec("streamed");
    return new DrainReactor<v1::DescribeRequest>();
  }

  grpc::ServerReadReactor<v1::ClassifyRequest>* Classify(grpc::CallbackServerContext* /*context*/,
                                                         v1::ClassifyResponse* response) override {
    ++streams;
    response->set_label("streamed");
    return new DrainReactor<v1::ClassifyRequest>();
  }
};

TEST(ClientFallbackTest, AnOlderServerWithoutOneMessageCallsGetsTheStream) {
  StreamOnlyService service;
  grpc::ServerBuilder builder;
  int port = 0;
  builder.AddListeningPort("127.0.0.1:0", grpc::InsecureServerCredentials(), &port);
  builder.RegisterService(&service);
  std::unique_ptr<grpc::Server> server = builder.BuildAndStart();
  ASSERT_NE(server, nullptr);
  ClientOptions options;
  options.target = absl::StrCat("127.0.0.1:", port);
  auto client = Client::Connect(options);
  ASSERT_TRUE(client.ok());
  for (int call = 1; call <= 3; ++call) {
    auto answer = (*client)->Classify("parts", Shape(0, 5));
    ASSERT_TRUE(answer.ok()) << answer.status();
    EXPECT_EQ(answer->label(), "streamed");
    EXPECT_EQ(service.streams, call);
  }
  auto described = (*client)->Describe(Shape(0, 6));
  ASSERT_TRUE(described.ok()) << described.status();
  EXPECT_EQ(described->descriptor_spec(), "streamed");
  EXPECT_EQ(service.streams, 4);
  // A fresh client whose first call is a Describe finds out the same way.
  auto fresh = Client::Connect(options);
  ASSERT_TRUE(fresh.ok());
  described = (*fresh)->Describe(Shape(0, 6));
  ASSERT_TRUE(described.ok()) << described.status();
  EXPECT_EQ(described->descriptor_spec(), "streamed");
  EXPECT_EQ(service.streams, 5);
  server->Shutdown();
}

TEST(ClientChunkTest, BigCloudIsChunked) {
  // The server refuses any message over 256 KiB; the cloud is 1.2 MB, so it only gets
  // through in chunks (16,384 points = 192 KiB each).
  ServerOptions server_options;
  server_options.listen = "127.0.0.1:0";
  server_options.max_message_bytes = 256 << 10;
  auto server = ShapeIdServer::Start(server_options);
  ASSERT_TRUE(server.ok()) << server.status();
  ClientOptions options;
  options.target = (*server)->address();
  auto client = Client::Connect(options);
  ASSERT_TRUE(client.ok());
  const PointCloud cloud = Shape(0, 7, 100000);
  auto described = (*client)->Describe(cloud);
  ASSERT_TRUE(described.ok()) << described.status();
  EXPECT_EQ(described->num_points(), 100000u);

  // Chunks above the server's limit: refused (RESOURCE_EXHAUSTED), proving the limit bites.
  options.chunk_points = 100000;
  auto one_chunk = Client::Connect(options);
  ASSERT_TRUE(one_chunk.ok());
  const absl::Status status = (*one_chunk)->Describe(cloud).status();
  EXPECT_TRUE(absl::IsResourceExhausted(status)) << status;
}

TEST_F(ClientTest, ErrorsKeepCodeAndMessage) {
  EXPECT_TRUE(absl::IsNotFound(client_->GetGallery("nope").status()));
  EXPECT_TRUE(absl::IsNotFound(client_->Classify("nope", Shape(0, 1)).status()));
  EXPECT_TRUE(absl::IsNotFound(client_->DeleteGallery("nope").status()));

  v1::CreateGalleryRequest request;
  request.set_name("g");
  ASSERT_TRUE(client_->CreateGallery(request).ok());
  EXPECT_TRUE(absl::IsAlreadyExists(client_->CreateGallery(request).status()));
  EXPECT_TRUE(absl::IsFailedPrecondition(client_->Classify("g", Shape(0, 1)).status()));

  PointCloud two({{0, 0, 0}, {1, 1, 1}});
  const absl::Status few = client_->Describe(two).status();
  EXPECT_TRUE(absl::IsInvalidArgument(few)) << few;
  EXPECT_FALSE(few.message().empty());

  const absl::Status spec = client_->Describe(Shape(0, 1), "nosuchdescriptor").status();
  EXPECT_TRUE(absl::IsInvalidArgument(spec)) << spec;
  EXPECT_THAT(std::string(spec.message()), HasSubstr("nosuchdescriptor"));

  PointCloud bad = Shape(0, 1);
  bad.mutable_xyz()[3 * 500 + 1] = std::numeric_limits<float>::quiet_NaN();
  const absl::Status nan = client_->Describe(bad).status();
  EXPECT_TRUE(absl::IsInvalidArgument(nan)) << nan;

  const std::vector<TrainSample> none_cloud = {{"box", 0, nullptr}};
  EXPECT_TRUE(absl::IsInvalidArgument(client_->Train("g", none_cloud).status()));

  // Train is all-or-nothing: a taken id fails the stream and adds nothing.
  const PointCloud a = Shape(0, 1), b = Shape(1, 2);
  const std::vector<TrainSample> first = {{"box", 5, &a}};
  ASSERT_TRUE(client_->Train("g", first).ok());
  const std::vector<TrainSample> again = {{"rod", 6, &b}, {"box", 5, &a}};
  EXPECT_TRUE(absl::IsAlreadyExists(client_->Train("g", again).status()));
  EXPECT_EQ(client_->GetGallery("g")->sample_count(), 1u);
}

TEST_F(ClientTest, ExportThenImportUnderANewName) {
  CreateTrained("parts");
  std::vector<v1::GalleryExportChunk> chunks;
  ASSERT_TRUE(client_
                  ->ExportGallery("parts",
                                  [&](const v1::GalleryExportChunk& chunk) {
                                    chunks.push_back(chunk);
                                    return absl::OkStatus();
                                  })
                  .ok());
  ASSERT_GE(chunks.size(), 3u);
  EXPECT_TRUE(chunks.front().has_header());
  EXPECT_TRUE(chunks.back().has_trailer());

  size_t next = 0;
  const auto source = [&](v1::GalleryExportChunk* chunk) -> absl::StatusOr<bool> {
    if (next == chunks.size()) return false;
    *chunk = chunks[next++];
    return true;
  };
  auto imported = client_->ImportGallery(source, "parts-copy");
  ASSERT_TRUE(imported.ok()) << imported.status();
  EXPECT_EQ(imported->name(), "parts-copy");
  EXPECT_EQ(imported->sample_count(), 6u);
  auto a = client_->Classify("parts", Shape(1, 31), 3);
  auto b = client_->Classify("parts-copy", Shape(1, 31), 3);
  ASSERT_TRUE(a.ok() && b.ok());
  EXPECT_EQ(a->label(), b->label());
  ASSERT_EQ(a->neighbors_size(), b->neighbors_size());
  for (int i = 0; i < a->neighbors_size(); ++i) {
    EXPECT_EQ(a->neighbors(i).sample_id(), b->neighbors(i).sample_id());
    EXPECT_EQ(a->neighbors(i).distance(), b->neighbors(i).distance());
  }

  // Under the exported name, which is taken: the server's answer, as it is.
  next = 0;
  EXPECT_TRUE(absl::IsAlreadyExists(client_->ImportGallery(source).status()));
}

TEST_F(ClientTest, SinkAndSourceErrorsStopTheStream) {
  CreateTrained("parts");
  int calls = 0;
  const absl::Status full = client_->ExportGallery("parts", [&](const v1::GalleryExportChunk&) {
    ++calls;
    return absl::ResourceExhaustedError("disk full");
  });
  EXPECT_EQ(full, absl::ResourceExhaustedError("disk full"));
  EXPECT_EQ(calls, 1);
  EXPECT_TRUE(absl::IsNotFound(
      client_->ExportGallery("nope", [](const auto&) { return absl::OkStatus(); })));

  // The source fails after the header: the import is cancelled, not taken as truncated.
  std::vector<v1::GalleryExportChunk> chunks;
  ASSERT_TRUE(client_
                  ->ExportGallery("parts",
                                  [&](const v1::GalleryExportChunk& chunk) {
                                    chunks.push_back(chunk);
                                    return absl::OkStatus();
                                  })
                  .ok());
  size_t next = 0;
  const absl::Status cut = client_
                               ->ImportGallery(
                                   [&](v1::GalleryExportChunk* chunk) -> absl::StatusOr<bool> {
                                     if (next == 1)
                                       return absl::DataLossError("backup.shapeid is truncated");
                                     *chunk = chunks[next++];
                                     return true;
                                   },
                                   "cut")
                               .status();
  EXPECT_EQ(cut, absl::DataLossError("backup.shapeid is truncated"));
  EXPECT_TRUE(absl::IsNotFound(client_->GetGallery("cut").status()));
}

TEST(ClientRetryTest, UnavailableAfterBoundedRetries) {
  ClientOptions options;
  options.target = "127.0.0.1:1";  // nothing listens
  options.max_attempts = 3;
  options.initial_backoff = absl::Milliseconds(100);
  auto client = Client::Connect(options);
  ASSERT_TRUE(client.ok());
  const absl::Time start = absl::Now();
  const absl::Status status = (*client)->ListGalleries().status();
  const absl::Duration took = absl::Now() - start;
  EXPECT_TRUE(absl::IsUnavailable(status)) << status;
  EXPECT_GE(took, absl::Milliseconds(300));  // backoffs 100 + 200 ms
  EXPECT_LT(took, absl::Seconds(5));
  EXPECT_TRUE(absl::IsUnavailable((*client)->CheckHealth()));

  // An export that delivered nothing yet is retried like any read.
  const absl::Time start3 = absl::Now();
  EXPECT_TRUE(absl::IsUnavailable(
      (*client)->ExportGallery("g", [](const auto&) { return absl::OkStatus(); })));
  EXPECT_GE(absl::Now() - start3, absl::Milliseconds(300));

  // Not idempotent: one attempt, no backoff.
  const absl::Time start2 = absl::Now();
  v1::CreateGalleryRequest request;
  request.set_name("g");
  EXPECT_TRUE(absl::IsUnavailable((*client)->CreateGallery(request).status()));
  const auto no_chunks = [](v1::GalleryExportChunk*) -> absl::StatusOr<bool> { return false; };
  EXPECT_TRUE(absl::IsUnavailable((*client)->ImportGallery(no_chunks).status()));
  EXPECT_LT(absl::Now() - start2, absl::Milliseconds(100));
}

TEST_F(ClientTest, DeadlineIsHonoured) {
  ClientOptions options = client_->options();
  options.deadline = absl::Milliseconds(1);
  auto client = Client::Connect(options);
  ASSERT_TRUE(client.ok());
  const PointCloud cloud = Shape(0, 7, 200000);
  const absl::Time start = absl::Now();
  const absl::Status status = (*client)->Describe(cloud).status();
  EXPECT_TRUE(absl::IsDeadlineExceeded(status)) << status;
  EXPECT_LT(absl::Now() - start, absl::Seconds(2));
}

TEST_F(ClientTest, SharedAcrossThreads) {
  CreateTrained("shared");
  std::atomic<int> ok{0};
  std::vector<std::thread> threads;
  for (int t = 0; t < 8; ++t) {
    threads.emplace_back([&, t] {
      for (int i = 0; i < 5; ++i) {
        const int kind = (t + i) % 2;
        auto result = client_->Classify("shared", Shape(kind, 1000 + 10 * t + i, 3000));
        if (result.ok() && result->label() == (kind == 0 ? "box" : "rod") &&
            result->num_points() == 3000u && client_->GetGallery("shared").ok()) {
          ++ok;
        }
      }
    });
  }
  for (auto& thread : threads) thread.join();
  EXPECT_EQ(ok.load(), 40);
}

}  // namespace
}  // namespace shapeid
