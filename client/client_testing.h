#ifndef SHAPEID_CLIENT_CLIENT_TESTING_H_
#define SHAPEID_CLIENT_CLIENT_TESTING_H_

// Test-only fakes for the client's and the CLI's tests: a gRPC server on a free loopback port
// serving one fake service, a fake of the operations calls (GetServerStats, SetLogLevel)
// that records the x-request-id each call carried, and a gallery whose samples carry the
// largest provenance allowed.

#include <map>
#include <memory>
#include <mutex>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "absl/strings/str_cat.h"
#include "client/client.h"
#include "grpcpp/grpcpp.h"
#include "shapeid/v1/shapeid.grpc.pb.h"

namespace shapeid::client_testing {

// A server on a free loopback port serving only `service` (a fake); `*target` is its address.
inline std::unique_ptr<grpc::Server> StartFakeServer(grpc::Service* service, std::string* target) {
  grpc::ServerBuilder builder;
  int port = 0;
  builder.AddListeningPort("127.0.0.1:0", grpc::InsecureServerCredentials(), &port);
  builder.RegisterService(service);
  std::unique_ptr<grpc::Server> server = builder.BuildAndStart();
  *target = absl::StrCat("127.0.0.1:", port);
  return server;
}

// Answers GetServerStats with `stats` and SetLogLevel as the server does (the four levels,
// INVALID_ARGUMENT otherwise), after refusing the first `unavailable_attempts` calls
// UNAVAILABLE. Every call's x-request-id ("" when it carried none) is kept, in order.
class FakeOperationsService final : public v1::ShapeId::CallbackService {
 public:
  explicit FakeOperationsService(v1::ServerStats stats = v1::ServerStats())
      : stats_(std::move(stats)) {}

  grpc::ServerUnaryReactor* GetServerStats(grpc::CallbackServerContext* context,
                                           const v1::GetServerStatsRequest* /*request*/,
                                           v1::ServerStats* response) override {
    grpc::Status status = Arrive(context);
    if (status.ok()) {
      std::lock_guard<std::mutex> lock(mu_);
      *response = stats_;
    }
    return Answer(context, status);
  }

  grpc::ServerUnaryReactor* SetLogLevel(grpc::CallbackServerContext* context,
                                        const v1::SetLogLevelRequest* request,
                                        v1::SetLogLevelResponse* response) override {
    grpc::Status status = Arrive(context);
    if (status.ok()) {
      const std::string& level = request->level();
      if (level != "debug" && level != "info" && level != "warning" && level != "error") {
        status = grpc::Status(grpc::StatusCode::INVALID_ARGUMENT,
                              absl::StrCat("unknown log level \"", level, "\""));
      } else {
        std::lock_guard<std::mutex> lock(mu_);
        response->set_previous_level(stats_.log_level());
        response->set_level(level);
        stats_.set_log_level(level);
      }
    }
    return Answer(context, status);
  }

  void RefuseNext(int attempts) {
    std::lock_guard<std::mutex> lock(mu_);
    unavailable_attempts_ = attempts;
  }

  std::vector<std::string> request_ids() const {
    std::lock_guard<std::mutex> lock(mu_);
    return request_ids_;
  }

 private:
  grpc::Status Arrive(grpc::CallbackServerContext* context) {
    const auto& metadata = context->client_metadata();
    const auto id = metadata.find("x-request-id");
    std::lock_guard<std::mutex> lock(mu_);
    request_ids_.push_back(
        id == metadata.end() ? std::string() : std::string(id->second.data(), id->second.size()));
    if (unavailable_attempts_ > 0) {
      --unavailable_attempts_;
      return grpc::Status(grpc::StatusCode::UNAVAILABLE, "loading its galleries");
    }
    return grpc::Status::OK;
  }

  static grpc::ServerUnaryReactor* Answer(grpc::CallbackServerContext* context,
                                          const grpc::Status& status) {
    grpc::ServerUnaryReactor* reactor = context->DefaultReactor();
    reactor->Finish(status);
    return reactor;
  }

  mutable std::mutex mu_;
  v1::ServerStats stats_;
  int unavailable_attempts_ = 0;
  std::vector<std::string> request_ids_;
};

// Creates gallery `name` (the server's default spec) and trains `count` samples of 100
// random points (ids 1 to count, labels "a" and "b" in turn), each with the largest provenance
// allowed (core/gallery/sample_provenance.h): a source of 4,096 bytes and 64 pairs of 4,096
// bytes of keys and values, about 8.6 KB a sample on the wire. 1,000 of them (a default
// ListSamples page, a Classify with k = 1000) pass gRPC's default 4 MiB receive limit.
inline absl::Status TrainFatProvenanceGallery(Client& client, const std::string& name, int count) {
  v1::CreateGalleryRequest create;
  create.set_name(name);
  if (absl::Status created = client.CreateGallery(create).status(); !created.ok()) {
    return created;
  }
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  std::vector<PointCloud> clouds(static_cast<size_t>(count));
  std::vector<TrainSample> samples;
  for (int i = 0; i < count; ++i) {
    for (int p = 0; p < 100; ++p) clouds[i].Add(u(rng), (1 + i % 2) * u(rng), 0.2f * u(rng));
    TrainSample sample{i % 2 == 0 ? "a" : "b", static_cast<uint64_t>(i + 1), &clouds[i]};
    sample.source = absl::StrCat("/scans/", i + 1, "/");
    sample.source.resize(4096, 's');
    for (int k = 0; k < 64; ++k) {
      sample.metadata[absl::StrCat("k", k / 10, k % 10)] =
          std::string(61, static_cast<char>('a' + k % 26));
    }
    samples.push_back(std::move(sample));
  }
  return client.Train(name, samples).status();
}

}  // namespace shapeid::client_testing

#endif  // SHAPEID_CLIENT_CLIENT_TESTING_H_
