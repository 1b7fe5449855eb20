// The ShapeId service through a real gRPC server on a loopback port, with the generated stub:
// every RPC implemented so far and every stream error it must name.

#include <cmath>
#include <condition_variable>
#include <cstring>
#include <limits>
#include <mutex>
#include <random>
#include <string>
#include <vector>

#include "core/descriptor_registry.h"
#include "gmock/gmock.h"
#include "grpcpp/generic/generic_stub.h"
#include "grpcpp/grpcpp.h"
#include "gtest/gtest.h"
#include "server/server.h"
#include "shapeid/v1/shapeid.grpc.pb.h"

namespace shapeid {
namespace {

using ::testing::HasSubstr;

PointCloud BlobCloud(size_t n, uint32_t seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<float> g;
  PointCloud cloud;
  for (size_t i = 0; i < n; ++i) cloud.Add(2 * g(rng), g(rng), 0.5f * g(rng));
  return cloud;
}

std::string Bytes(const float* xyz, size_t points) {
  std::string bytes(points * 12, '\0');
  std::memcpy(bytes.data(), xyz, bytes.size());
  return bytes;
}

class ShapeIdServiceTest : public ::testing::Test {
 protected:
  void SetUp() override {
    ServerOptions options;
    options.listen = "127.0.0.1:0";
    options.gallery_limits.max_points_per_cloud = 50000;
    auto server = ShapeIdServer::Start(options);
    ASSERT_TRUE(server.ok()) << server.status();
    server_ = std::move(server).value();
    channel_ = grpc::CreateChannel(server_->address(), grpc::InsecureChannelCredentials());
    stub_ = v1::ShapeId::NewStub(channel_);
  }

  // Sends `messages` on one Describe stream and returns the final status.
  grpc::Status DescribeStream(const std::vector<v1::DescribeRequest>& messages,
                              v1::DescribeResponse* response) {
    grpc::ClientContext context;
    context.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(30));
    auto writer = stub_->Describe(&context, response);
    for (const auto& m : messages) {
      if (!writer->Write(m)) break;  // the server has already answered
    }
    writer->WritesDone();
    return writer->Finish();
  }

  static v1::DescribeRequest Header(const std::string& spec, uint64_t expected = 0) {
    v1::DescribeRequest r;
    r.mutable_header()->set_descriptor_spec(spec);
    r.mutable_header()->set_expected_points(expected);
    return r;
  }

  static std::vector<v1::DescribeRequest> Chunks(const PointCloud& cloud, size_t per_chunk) {
    std::vector<v1::DescribeRequest> out;
    for (size_t i = 0; i < cloud.size(); i += per_chunk) {
      v1::DescribeRequest r;
      r.mutable_points()->set_xyz(
          Bytes(cloud.data() + 3 * i, std::min(per_chunk, cloud.size() - i)));
      out.push_back(r);
    }
    return out;
  }

  void ExpectHealthy() {
    grpc::ClientContext context;
    v1::ListDescriptorsResponse response;
    EXPECT_TRUE(stub_->ListDescriptors(&context, {}, &response).ok());
  }

  std::unique_ptr<ShapeIdServer> server_;
  std::shared_ptr<grpc::Channel> channel_;
  std::unique_ptr<v1::ShapeId::Stub> stub_;
};

TEST_F(ShapeIdServiceTest, DescribeOverChunksEqualsInProcessBitForBit) {
  const PointCloud cloud = BlobCloud(10007, 1);
  for (const char* spec : {"rphsd", "comsd:grid=30", "rphsd:refs=cross7,variant=reduced"}) {
    std::vector<v1::DescribeRequest> messages = {Header(spec, cloud.size())};
    for (auto& chunk : Chunks(cloud, 4096)) messages.push_back(chunk);
    v1::DescribeResponse response;
    const grpc::Status status = DescribeStream(messages, &response);
    ASSERT_TRUE(status.ok()) << spec << ": " << status.error_message();
    auto local = CreateDescriptor(spec);
    ASSERT_TRUE(local.ok());
    const std::vector<float> expected = *(*local)->Compute(cloud);
    EXPECT_EQ(std::vector<float>(response.values().begin(), response.values().end()), expected);
    EXPECT_EQ(response.descriptor_spec(), (*local)->spec().ToString());
    EXPECT_EQ(response.num_points(), cloud.size());
    EXPECT_TRUE(response.has_describe_time());
  }
}

TEST_F(ShapeIdServiceTest, DescribeDefaultsToDfsd) {
  const PointCloud cloud = BlobCloud(500, 2);
  std::vector<v1::DescribeRequest> messages = {Header("")};
  for (auto& chunk : Chunks(cloud, 500)) messages.push_back(chunk);
  v1::DescribeResponse response;
  ASSERT_TRUE(DescribeStream(messages, &response).ok());
  EXPECT_EQ(response.descriptor_spec(), "dfsd:grid=12,order=8,frame=box,fields=both,size=0");
  EXPECT_EQ(response.values_size(), 240);
}

TEST_F(ShapeIdServiceTest, DescribeCloudInOneMessageEqualsTheStreamWithTheSameErrors) {
  const PointCloud cloud = BlobCloud(3000, 4);
  const auto one_message = [&](const std::string& spec, const PointCloud& points,
                               v1::DescribeResponse* response, uint64_t expected = 0) {
    grpc::ClientContext context;
    v1::DescribeCloudRequest request;
    request.mutable_header()->set_descriptor_spec(spec);
    request.mutable_header()->set_expected_points(expected);
    request.mutable_points()->set_xyz(Bytes(points.data(), points.size()));
    return stub_->DescribeCloud(&context, request, response);
  };
  for (const char* spec : {"", "rphsd", "dfsd:frame=upright,up=y"}) {
    v1::DescribeResponse one, streamed;
    ASSERT_TRUE(one_message(spec, cloud, &one, cloud.size()).ok()) << spec;
    std::vector<v1::DescribeRequest> messages = {Header(spec, cloud.size())};
    for (auto& chunk : Chunks(cloud, 1000)) messages.push_back(chunk);
    ASSERT_TRUE(DescribeStream(messages, &streamed).ok()) << spec;
    EXPECT_EQ(one.descriptor_spec(), streamed.descriptor_spec());
    EXPECT_EQ(std::vector<float>(one.values().begin(), one.values().end()),
              std::vector<float>(streamed.values().begin(), streamed.values().end()))
        << spec;
    EXPECT_EQ(one.num_points(), cloud.size());
  }
  v1::DescribeResponse response;
  const grpc::Status bad_spec = one_message("esf", cloud, &response);
  EXPECT_EQ(bad_spec.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(bad_spec.error_message(), HasSubstr("unknown descriptor"));
  EXPECT_EQ(one_message("", PointCloud{{0, 0, 0}}, &response).error_code(),
            grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_EQ(one_message("", cloud, &response, cloud.size() + 1).error_code(),
            grpc::StatusCode::INVALID_ARGUMENT);
  {
    grpc::ClientContext context;
    v1::DescribeCloudRequest request;
    request.mutable_header()->set_gallery("missing");
    request.mutable_points()->set_xyz(Bytes(cloud.data(), cloud.size()));
    EXPECT_EQ(stub_->DescribeCloud(&context, request, &response).error_code(),
              grpc::StatusCode::NOT_FOUND);
  }
  {
    grpc::ClientContext context;
    v1::DescribeCloudRequest ragged;
    ragged.mutable_points()->set_xyz(std::string(12 * 50 + 7, '\0'));
    EXPECT_EQ(stub_->DescribeCloud(&context, ragged, &response).error_code(),
              grpc::StatusCode::INVALID_ARGUMENT);
  }
  // Over the server's max_points_per_cloud (50,000 here): refused as on the stream, healthy.
  const grpc::Status too_big = one_message("rphsd", BlobCloud(60000, 5), &response);
  EXPECT_EQ(too_big.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
  EXPECT_THAT(too_big.error_message(), HasSubstr("limit of 50000 points"));
  ExpectHealthy();
}

TEST_F(ShapeIdServiceTest, EveryMalformedStreamGetsAPreciseError) {
  const PointCloud cloud = BlobCloud(100, 3);
  v1::DescribeRequest odd_chunk;
  odd_chunk.mutable_points()->set_xyz(std::string(25, '\0'));
  v1::DescribeRequest empty_message;
  PointCloud with_nan = cloud;
  with_nan.mutable_xyz()[3 * 42 + 1] = std::numeric_limits<float>::quiet_NaN();
  const PointCloud big = BlobCloud(50001, 4);

  struct Case {
    std::string name;
    std::vector<v1::DescribeRequest> messages;
    grpc::StatusCode code;
    std::string message;
  };
  std::vector<Case> cases = {
      {"points first", Chunks(cloud, 10), grpc::StatusCode::INVALID_ARGUMENT,
       "the first message must be a DescribeHeader"},
      {"two headers",
       {Header("rphsd"), Header("rphsd")},
       grpc::StatusCode::INVALID_ARGUMENT,
       "a second DescribeHeader"},
      {"no header at all",
       {},
       grpc::StatusCode::INVALID_ARGUMENT,
       "ended without a DescribeHeader"},
      {"empty message",
       {empty_message},
       grpc::StatusCode::INVALID_ARGUMENT,
       "neither header nor points"},
      {"bad spec",
       {Header("rphsd:bins=0")},
       grpc::StatusCode::INVALID_ARGUMENT,
       "bins=0 is outside [1, 100000]"},
      {"unknown kind", {Header("esf")}, grpc::StatusCode::INVALID_ARGUMENT, "unknown descriptor"},
      {"partial point",
       {Header("rphsd"), odd_chunk},
       grpc::StatusCode::INVALID_ARGUMENT,
       "25 bytes is not a whole number of points"},
      {"too few points",
       {Header("rphsd")},
       grpc::StatusCode::INVALID_ARGUMENT,
       "cloud has 0 points; at least 3 are needed"},
      {"announced too many",
       {Header("rphsd", 60000)},
       grpc::StatusCode::RESOURCE_EXHAUSTED,
       "announces 60000 points, more than the limit of 50000"},
      {"short of announced",
       {Header("rphsd", 101)},
       grpc::StatusCode::INVALID_ARGUMENT,
       "announced 101 points but 100 arrived"},
  };
  for (auto& chunk : Chunks(cloud, 100)) cases.back().messages.push_back(chunk);
  Case nan_case{"NaN point",
                {Header("rphsd")},
                grpc::StatusCode::INVALID_ARGUMENT,
                "point 42 has a non-finite coordinate"};
  for (auto& chunk : Chunks(with_nan, 30)) nan_case.messages.push_back(chunk);
  cases.push_back(nan_case);
  Case big_case{"over the limit",
                {Header("rphsd")},
                grpc::StatusCode::RESOURCE_EXHAUSTED,
                "more than the limit of 50000 points"};
  for (auto& chunk : Chunks(big, 20000)) big_case.messages.push_back(chunk);
  cases.push_back(big_case);

  for (const Case& c : cases) {
    v1::DescribeResponse response;
    const grpc::Status status = DescribeStream(c.messages, &response);
    EXPECT_EQ(status.error_code(), c.code) << c.name << ": " << status.error_message();
    EXPECT_THAT(status.error_message(), HasSubstr(c.message)) << c.name;
    ExpectHealthy();
  }
}

TEST_F(ShapeIdServiceTest, ListDescriptorsOffersTheRegistryWithDefaults) {
  grpc::ClientContext context;
  v1::ListDescriptorsResponse response;
  ASSERT_TRUE(stub_->ListDescriptors(&context, {}, &response).ok());
  ASSERT_EQ(response.descriptors_size(), static_cast<int>(RegisteredDescriptors().size()));
  const v1::DescriptorKind& rphsd = response.descriptors(0);
  EXPECT_EQ(rphsd.kind(), "rphsd");
  EXPECT_EQ(rphsd.default_spec(), "rphsd:refs=cubic27,bins=100,variant=complete");
  EXPECT_EQ(rphsd.default_dimension(), 81u);
  ASSERT_EQ(rphsd.parameters_size(), 3);
  EXPECT_EQ(rphsd.parameters(1).name(), "bins");
  EXPECT_EQ(rphsd.parameters(1).default_value(), "100");
  EXPECT_FALSE(rphsd.parameters(1).help().empty());
}

TEST_F(ShapeIdServiceTest, HealthServiceAnswersServing) {
  auto health = grpc::CreateChannel(server_->address(), grpc::InsecureChannelCredentials());
  grpc::GenericStub generic(health);
  // The default health service is registered: grpc.health.v1.Health/Check with an empty
  // request (service "") answers SERVING (status 1), serialized as field 1 = 1.
  grpc::ClientContext context;
  grpc::ByteBuffer request;  // empty HealthCheckRequest
  grpc::Slice empty("");
  request = grpc::ByteBuffer(&empty, 1);
  grpc::ByteBuffer reply;
  std::mutex mu;
  std::condition_variable cv;
  bool done = false;
  grpc::Status status;
  generic.UnaryCall(&context, "/grpc.health.v1.Health/Check", grpc::StubOptions(), &request, &reply,
                    [&](grpc::Status s) {
                      std::lock_guard<std::mutex> lock(mu);
                      status = s;
                      done = true;
                      cv.notify_one();
                    });
  std::unique_lock<std::mutex> lock(mu);
  cv.wait(lock, [&] { return done; });
  ASSERT_TRUE(status.ok()) << status.error_message();
  std::vector<grpc::Slice> slices;
  ASSERT_TRUE(reply.Dump(&slices).ok());
  std::string bytes;
  for (const auto& s : slices) bytes.append(reinterpret_cast<const char*>(s.begin()), s.size());
  EXPECT_EQ(bytes, std::string("\x08\x01", 2));  // status: SERVING
}

}  // namespace
}  // namespace shapeid
