// The gallery RPCs of the ShapeId service through a real gRPC server on a loopback port:
// create / get / list / delete, Train streams (bulk, all-or-nothing, cut), Classify,
// RemoveSamples, every error code the issue names, and concurrent clients.

#include <atomic>
#include <cstring>
#include <limits>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include "core/gallery/gallery.h"
#include "core/testing/test_clouds.h"
#include "gmock/gmock.h"
#include "grpcpp/grpcpp.h"
#include "gtest/gtest.h"
#include "server/server.h"
#include "shapeid/v1/shapeid.grpc.pb.h"

namespace shapeid {
namespace {

using ::testing::HasSubstr;

using testing_clouds::kShapeNames;

// 600 points unless a test needs another size.
PointCloud Shape(int kind, uint32_t seed, size_t n = 600) {
  return testing_clouds::ShapeCloud(kind, seed, n);
}

std::string Bytes(const PointCloud& cloud, size_t first, size_t count) {
  std::string bytes(count * 12, '\0');
  std::memcpy(bytes.data(), cloud.data() + 3 * first, bytes.size());
  return bytes;
}

class GalleryServiceTest : public ::testing::Test {
 protected:
  void SetUp() override {
    ServerOptions options;
    options.listen = "127.0.0.1:0";
    auto server = ShapeIdServer::Start(options);
    ASSERT_TRUE(server.ok()) << server.status();
    server_ = std::move(server).value();
    stub_ = v1::ShapeId::NewStub(
        grpc::CreateChannel(server_->address(), grpc::InsecureChannelCredentials()));
  }

  grpc::Status Create(const std::string& name, const std::string& spec = "", double reject = 0,
                      v1::Gallery* out = nullptr) {
    grpc::ClientContext context;
    v1::CreateGalleryRequest request;
    request.set_name(name);
    request.set_descriptor_spec(spec);
    request.set_reject_distance(reject);
    v1::Gallery response;
    const grpc::Status status = stub_->CreateGallery(&context, request, &response);
    if (out != nullptr) *out = response;
    return status;
  }

  v1::Gallery Get(const std::string& name, grpc::Status* status = nullptr) {
    grpc::ClientContext context;
    v1::GetGalleryRequest request;
    request.set_name(name);
    v1::Gallery response;
    const grpc::Status s = stub_->GetGallery(&context, request, &response);
    if (status != nullptr) *status = s;
    return response;
  }

  struct Sample {
    std::string label;
    uint64_t id = 0;
    PointCloud cloud;
  };

  // One Train stream carrying `samples`, each split into chunks of `chunk` points.
  grpc::Status Train(const std::string& gallery, const std::vector<Sample>& samples,
                     v1::TrainResponse* response, size_t chunk = 256) {
    grpc::ClientContext context;
    auto writer = stub_->Train(&context, response);
    v1::TrainRequest header;
    header.mutable_header()->set_gallery(gallery);
    bool open = writer->Write(header);
    for (const Sample& s : samples) {
      v1::TrainRequest start;
      start.mutable_sample()->set_label(s.label);
      start.mutable_sample()->set_sample_id(s.id);
      open = open && writer->Write(start);
      for (size_t i = 0; open && i < s.cloud.size(); i += chunk) {
        v1::TrainRequest points;
        points.mutable_points()->set_xyz(Bytes(s.cloud, i, std::min(chunk, s.cloud.size() - i)));
        open = writer->Write(points);
      }
    }
    writer->WritesDone();
    return writer->Finish();
  }

  grpc::Status Classify(const std::string& gallery, const PointCloud& cloud,
                        v1::ClassifyResponse* response, uint32_t k = 0) {
    grpc::ClientContext context;
    auto writer = stub_->Classify(&context, response);
    v1::ClassifyRequest header;
    header.mutable_header()->set_gallery(gallery);
    header.mutable_header()->set_k(k);
    bool open = writer->Write(header);
    for (size_t i = 0; open && i < cloud.size(); i += 1000) {
      v1::ClassifyRequest points;
      points.mutable_points()->set_xyz(Bytes(cloud, i, std::min<size_t>(1000, cloud.size() - i)));
      open = writer->Write(points);
    }
    writer->WritesDone();
    return writer->Finish();
  }

  std::vector<Sample> TrainingSet(int per_shape, uint32_t seed) {
    std::vector<Sample> samples;
    for (int i = 0; i < per_shape; ++i) {
      for (int kind = 0; kind < 3; ++kind) {
        samples.push_back({kShapeNames[kind], 0, Shape(kind, seed + 10 * i + kind)});
      }
    }
    return samples;
  }

  std::unique_ptr<ShapeIdServer> server_;
  std::unique_ptr<v1::ShapeId::Stub> stub_;
};

TEST_F(GalleryServiceTest, CreateGetListDeleteWithEveryError) {
  v1::Gallery created;
  ASSERT_TRUE(Create("lab-1", "rphsd:refs=cross7", 0, &created).ok());
  EXPECT_EQ(created.descriptor_spec(), "rphsd:refs=cross7,bins=100,variant=complete");
  EXPECT_EQ(created.dimension(), 21u);
  EXPECT_EQ(created.knn().k(), 1u);
  EXPECT_EQ(created.knn().scaling(), v1::FEATURE_SCALING_NONE);
  EXPECT_EQ(created.sample_count(), 0u);
  EXPECT_GT(created.create_time().seconds(), 0);

  EXPECT_EQ(Create("lab-1").error_code(), grpc::StatusCode::ALREADY_EXISTS);
  const grpc::Status bad_name = Create("no spaces");
  EXPECT_EQ(bad_name.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(bad_name.error_message(), HasSubstr("[A-Za-z0-9]"));
  const grpc::Status bad_spec = Create("lab-2", "rphsd:bins=0");
  EXPECT_EQ(bad_spec.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(bad_spec.error_message(), HasSubstr("bins=0"));
  ASSERT_TRUE(Create("a-first").ok());

  grpc::Status status;
  Get("nope", &status);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::NOT_FOUND);
  EXPECT_THAT(status.error_message(), HasSubstr("nope"));

  grpc::ClientContext list_context;
  v1::ListGalleriesResponse list;
  ASSERT_TRUE(stub_->ListGalleries(&list_context, {}, &list).ok());
  ASSERT_EQ(list.galleries_size(), 2);
  EXPECT_EQ(list.galleries(0).name(), "a-first");  // sorted
  EXPECT_EQ(list.galleries(1).name(), "lab-1");

  grpc::ClientContext delete_context;
  v1::DeleteGalleryRequest del;
  del.set_name("lab-1");
  v1::DeleteGalleryResponse deleted;
  ASSERT_TRUE(stub_->DeleteGallery(&delete_context, del, &deleted).ok());
  grpc::ClientContext again_context;
  EXPECT_EQ(stub_->DeleteGallery(&again_context, del, &deleted).error_code(),
            grpc::StatusCode::NOT_FOUND);
}

TEST_F(GalleryServiceTest, BulkTrainThenClassifyRecognisesShapes) {
  ASSERT_TRUE(Create("shapes", "rphsd:refs=cubic27,bins=30").ok());
  v1::TrainResponse trained;
  std::vector<Sample> samples = TrainingSet(4, 100);
  samples[0].id = 42;  // a client-chosen id among assigned ones
  const grpc::Status status = Train("shapes", samples, &trained);
  ASSERT_TRUE(status.ok()) << status.error_message();
  ASSERT_EQ(trained.sample_ids_size(), 12);
  EXPECT_EQ(trained.sample_ids(0), 42u);
  EXPECT_GE(trained.sample_ids(1), kFirstAssignedId);
  EXPECT_EQ(trained.gallery_sample_count(), 12u);

  const v1::Gallery gallery = Get("shapes");
  EXPECT_EQ(gallery.sample_count(), 12u);
  ASSERT_EQ(gallery.label_counts_size(), 3);
  EXPECT_EQ(gallery.label_counts(0).label(), "box");
  EXPECT_EQ(gallery.label_counts(0).count(), 4u);

  for (int kind = 0; kind < 3; ++kind) {
    v1::ClassifyResponse answer;
    ASSERT_TRUE(Classify("shapes", Shape(kind, 999 + kind, 2000), &answer, 3).ok());
    EXPECT_EQ(answer.label(), kShapeNames[kind]);
    EXPECT_FALSE(answer.unknown());
    ASSERT_EQ(answer.neighbors_size(), 3);
    EXPECT_LE(answer.neighbors(0).distance(), answer.neighbors(1).distance());
    EXPECT_EQ(answer.votes(0).label(), answer.label());
    EXPECT_GT(answer.confidence(), 0.0);
    EXPECT_EQ(answer.num_points(), 2000u);
    EXPECT_TRUE(answer.has_describe_time());
  }
}

TEST_F(GalleryServiceTest, TrainIsAllOrNothing) {
  ASSERT_TRUE(Create("g").ok());
  std::vector<Sample> samples = TrainingSet(2, 7);
  samples[3].cloud.mutable_xyz()[3 * 17 + 2] = std::numeric_limits<float>::infinity();
  v1::TrainResponse response;
  const grpc::Status status = Train("g", samples, &response);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(status.error_message(), HasSubstr("sample 3"));
  EXPECT_THAT(status.error_message(), HasSubstr("point 17"));
  EXPECT_EQ(Get("g").sample_count(), 0u);

  // A duplicate id fails the whole stream too.
  std::vector<Sample> dup = TrainingSet(1, 8);
  dup[0].id = 5;
  dup[2].id = 5;
  EXPECT_EQ(Train("g", dup, &response).error_code(), grpc::StatusCode::ALREADY_EXISTS);
  EXPECT_EQ(Get("g").sample_count(), 0u);
}

TEST_F(GalleryServiceTest, ACutTrainStreamLeavesNoTrace) {
  ASSERT_TRUE(Create("g").ok());
  grpc::ClientContext context;
  v1::TrainResponse response;
  auto writer = stub_->Train(&context, &response);
  v1::TrainRequest header;
  header.mutable_header()->set_gallery("g");
  ASSERT_TRUE(writer->Write(header));
  const PointCloud cloud = Shape(0, 1);
  for (int s = 0; s < 3; ++s) {
    v1::TrainRequest sample;
    sample.mutable_sample()->set_label("box");
    ASSERT_TRUE(writer->Write(sample));
    v1::TrainRequest points;
    points.mutable_points()->set_xyz(Bytes(cloud, 0, cloud.size()));
    ASSERT_TRUE(writer->Write(points));
  }
  context.TryCancel();  // the client goes away mid-stream
  EXPECT_EQ(writer->Finish().error_code(), grpc::StatusCode::CANCELLED);
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  EXPECT_EQ(Get("g").sample_count(), 0u);
}

TEST_F(GalleryServiceTest, StreamErrorsAreNamed) {
  ASSERT_TRUE(Create("g").ok());
  v1::TrainResponse trained;
  EXPECT_EQ(Train("missing", TrainingSet(1, 1), &trained).error_code(),
            grpc::StatusCode::NOT_FOUND);
  const grpc::Status empty = Train("g", {}, &trained);
  EXPECT_EQ(empty.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(empty.error_message(), HasSubstr("no sample"));
  const grpc::Status no_label = Train("g", {{"", 0, Shape(0, 1)}}, &trained);
  EXPECT_EQ(no_label.error_code(), grpc::StatusCode::INVALID_ARGUMENT);

  v1::ClassifyResponse answer;
  const grpc::Status on_empty = Classify("g", Shape(0, 1), &answer);
  EXPECT_EQ(on_empty.error_code(), grpc::StatusCode::FAILED_PRECONDITION);
  EXPECT_THAT(on_empty.error_message(), HasSubstr("has no samples"));
  EXPECT_EQ(Classify("missing", Shape(0, 1), &answer).error_code(), grpc::StatusCode::NOT_FOUND);
  ASSERT_TRUE(Train("g", TrainingSet(1, 2), &trained).ok());
  const grpc::Status few = Classify("g", PointCloud{{0, 0, 0}, {1, 1, 1}}, &answer);
  EXPECT_EQ(few.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(few.error_message(), HasSubstr("cloud has 2 points"));
  // Points before the header.
  grpc::ClientContext context;
  auto writer = stub_->Classify(&context, &answer);
  v1::ClassifyRequest points;
  points.mutable_points()->set_xyz(std::string(12, '\0'));
  writer->Write(points);
  writer->WritesDone();
  const grpc::Status first = writer->Finish();
  EXPECT_EQ(first.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(first.error_message(), HasSubstr("first message must be a ClassifyHeader"));
  EXPECT_EQ(Get("g").sample_count(), 3u);  // unchanged by every error above
}

TEST_F(GalleryServiceTest, RejectDistanceAnswersUnknown) {
  ASSERT_TRUE(Create("strict", "rphsd:bins=30", 1e-9).ok());
  v1::TrainResponse trained;
  ASSERT_TRUE(Train("strict", TrainingSet(1, 3), &trained).ok());
  v1::ClassifyResponse answer;
  ASSERT_TRUE(Classify("strict", Shape(1, 77), &answer).ok());
  EXPECT_TRUE(answer.unknown());
  EXPECT_EQ(answer.label(), "unknown");
  ASSERT_GT(answer.neighbors_size(), 0);  // the evidence is still reported
}

TEST_F(GalleryServiceTest, RemoveSamplesByIdAndLabel) {
  ASSERT_TRUE(Create("g").ok());
  v1::TrainResponse trained;
  ASSERT_TRUE(Train("g", TrainingSet(3, 5), &trained).ok());
  grpc::ClientContext context;
  v1::RemoveSamplesRequest request;
  request.set_gallery("g");
  request.add_labels("rod");
  request.add_sample_ids(trained.sample_ids(0));  // a box
  v1::RemoveSamplesResponse removed;
  ASSERT_TRUE(stub_->RemoveSamples(&context, request, &removed).ok());
  EXPECT_EQ(removed.removed(), 4u);
  EXPECT_EQ(removed.remaining(), 5u);

  grpc::ClientContext missing_context;
  v1::RemoveSamplesRequest missing;
  missing.set_gallery("g");
  missing.add_sample_ids(12345);
  EXPECT_EQ(stub_->RemoveSamples(&missing_context, missing, &removed).error_code(),
            grpc::StatusCode::NOT_FOUND);
  EXPECT_EQ(Get("g").sample_count(), 5u);
}

TEST_F(GalleryServiceTest, SixteenConcurrentClientsTrainAndClassify) {
  ASSERT_TRUE(Create("shared", "rphsd:refs=cross7,bins=20").ok());
  v1::TrainResponse seeded;
  ASSERT_TRUE(Train("shared", TrainingSet(1, 9), &seeded).ok());
  std::atomic<int> failures{0};
  std::vector<std::thread> clients;
  for (int c = 0; c < 16; ++c) {
    clients.emplace_back([&, c] {
      for (int i = 0; i < 5; ++i) {
        v1::TrainResponse trained;
        if (!Train("shared", {{kShapeNames[c % 3], 0, Shape(c % 3, 1000 * c + i, 300)}}, &trained)
                 .ok()) {
          ++failures;
        }
        v1::ClassifyResponse answer;
        if (!Classify("shared", Shape(i % 3, 50 * c + i, 300), &answer).ok()) ++failures;
      }
    });
  }
  for (auto& t : clients) t.join();
  EXPECT_EQ(failures.load(), 0);
  EXPECT_EQ(Get("shared").sample_count(), 3u + 16u * 5u);  // no sample lost
}

TEST_F(GalleryServiceTest, DescribeWithAGallerySpec) {
  ASSERT_TRUE(Create("g", "comsd:grid=20").ok());
  grpc::ClientContext context;
  v1::DescribeResponse response;
  auto writer = stub_->Describe(&context, &response);
  v1::DescribeRequest header;
  header.mutable_header()->set_gallery("g");
  writer->Write(header);
  const PointCloud cloud = Shape(1, 3);
  v1::DescribeRequest points;
  points.mutable_points()->set_xyz(Bytes(cloud, 0, cloud.size()));
  writer->Write(points);
  writer->WritesDone();
  ASSERT_TRUE(writer->Finish().ok());
  EXPECT_EQ(response.descriptor_spec(), "comsd:grid=20");
  EXPECT_EQ(response.values_size(), 91);
}

}  // namespace
}  // namespace shapeid
