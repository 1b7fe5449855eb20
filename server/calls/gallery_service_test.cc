// The gallery RPCs of the ShapeId service through a real gRPC server on a loopback port:
// create / get / list / delete, Train streams (bulk, all-or-nothing, cut), Classify,
// RemoveSamples, export and import, every error code the issues name, and concurrent clients.

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstring>
#include <limits>
#include <map>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include "absl/strings/str_cat.h"
#include "absl/time/clock.h"
#include "core/gallery/gallery.h"
#include "core/testing/test_clouds.h"
#include "gmock/gmock.h"
#include "grpcpp/grpcpp.h"
#include "gtest/gtest.h"
#include "server/server.h"
#include "server/testing/raw_call.h"
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
    channel_ = grpc::CreateChannel(server_->address(), grpc::InsecureChannelCredentials());
    stub_ = v1::ShapeId::NewStub(channel_);
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
    std::string source = {};
    std::map<std::string, std::string> metadata = {};
  };

  // One Train stream carrying `samples`, each split into chunks of `chunk` points.
  grpc::Status Train(const std::string& gallery, const std::vector<Sample>& samples,
                     v1::TrainResponse* response, size_t chunk = 256,
                     const v1::ViewAugmentation* augmentation = nullptr) {
    grpc::ClientContext context;
    auto writer = stub_->Train(&context, response);
    v1::TrainRequest header;
    header.mutable_header()->set_gallery(gallery);
    if (augmentation != nullptr) *header.mutable_header()->mutable_augmentation() = *augmentation;
    bool open = writer->Write(header);
    for (const Sample& s : samples) {
      v1::TrainRequest start;
      start.mutable_sample()->set_label(s.label);
      start.mutable_sample()->set_sample_id(s.id);
      start.mutable_sample()->set_source(s.source);
      start.mutable_sample()->mutable_metadata()->insert(s.metadata.begin(), s.metadata.end());
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
                        v1::ClassifyResponse* response, uint32_t k = 0,
                        v1::ShapeId::Stub* stub = nullptr) {
    grpc::ClientContext context;
    auto writer = (stub != nullptr ? stub : stub_.get())->Classify(&context, response);
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

  // Every chunk of one ExportGallery call, in order.
  grpc::Status Export(const std::string& gallery, std::vector<v1::GalleryExportChunk>* chunks) {
    grpc::ClientContext context;
    v1::ExportGalleryRequest request;
    request.set_name(gallery);
    auto reader = stub_->ExportGallery(&context, request);
    chunks->clear();
    for (v1::GalleryExportChunk chunk; reader->Read(&chunk);) chunks->push_back(chunk);
    return reader->Finish();
  }

  // One ImportGallery stream of `chunks`, `name` on the first message.
  static grpc::Status Import(v1::ShapeId::Stub& stub,
                             const std::vector<v1::GalleryExportChunk>& chunks,
                             const std::string& name = "", v1::Gallery* out = nullptr,
                             const std::string& second_name = "") {
    grpc::ClientContext context;
    v1::Gallery response;
    auto writer = stub.ImportGallery(&context, &response);
    for (size_t i = 0; i < chunks.size(); ++i) {
      v1::ImportGalleryRequest request;
      request.set_name(i == 0 ? name : (i == 1 ? second_name : ""));
      *request.mutable_chunk() = chunks[i];
      if (!writer->Write(request)) break;
    }
    writer->WritesDone();
    const grpc::Status status = writer->Finish();
    if (out != nullptr) *out = response;
    return status;
  }

  // A second, empty server: where galleries are moved to.
  v1::ShapeId::Stub& Other() {
    if (other_stub_ == nullptr) {
      ServerOptions options;
      options.listen = "127.0.0.1:0";
      other_ = std::move(ShapeIdServer::Start(options)).value();
      other_stub_ = v1::ShapeId::NewStub(
          grpc::CreateChannel(other_->address(), grpc::InsecureChannelCredentials()));
    }
    return *other_stub_;
  }

  std::unique_ptr<ShapeIdServer> server_;
  std::shared_ptr<grpc::Channel> channel_;
  std::unique_ptr<v1::ShapeId::Stub> stub_;
  std::unique_ptr<ShapeIdServer> other_;
  std::unique_ptr<v1::ShapeId::Stub> other_stub_;
};

uint64_t Bits(double d) {
  uint64_t bits;
  std::memcpy(&bits, &d, sizeof bits);
  return bits;
}

// The same answer, bit for bit: label, votes, neighbor ids, labels and distances.
void ExpectSameAnswer(const v1::ClassifyResponse& a, const v1::ClassifyResponse& b) {
  EXPECT_EQ(a.label(), b.label());
  EXPECT_EQ(a.unknown(), b.unknown());
  EXPECT_EQ(Bits(a.confidence()), Bits(b.confidence()));
  ASSERT_EQ(a.neighbors_size(), b.neighbors_size());
  for (int i = 0; i < a.neighbors_size(); ++i) {
    EXPECT_EQ(a.neighbors(i).sample_id(), b.neighbors(i).sample_id()) << i;
    EXPECT_EQ(a.neighbors(i).label(), b.neighbors(i).label()) << i;
    EXPECT_EQ(Bits(a.neighbors(i).distance()), Bits(b.neighbors(i).distance())) << i;
  }
  ASSERT_EQ(a.votes_size(), b.votes_size());
  for (int i = 0; i < a.votes_size(); ++i) {
    EXPECT_EQ(a.votes(i).label(), b.votes(i).label());
    EXPECT_EQ(Bits(a.votes(i).weight()), Bits(b.votes(i).weight()));
  }
}

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

TEST_F(GalleryServiceTest, BulkTrainThenClassifyRecognizesShapes) {
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

grpc::Status ClassifyCloud(v1::ShapeId::Stub& stub, const std::string& gallery,
                           const PointCloud& cloud, v1::ClassifyResponse* response, uint32_t k = 0,
                           uint64_t expected_points = 0) {
  grpc::ClientContext context;
  v1::ClassifyCloudRequest request;
  request.mutable_header()->set_gallery(gallery);
  request.mutable_header()->set_k(k);
  request.mutable_header()->set_expected_points(expected_points);
  request.mutable_points()->set_xyz(
      std::string(reinterpret_cast<const char*>(cloud.data()), cloud.size() * 12));
  return stub.ClassifyCloud(&context, request, response);
}

TEST_F(GalleryServiceTest, ClassifyCloudAnswersLikeTheStreamWithTheSameErrors) {
  ASSERT_TRUE(Create("g").ok());
  v1::ClassifyResponse one, streamed;
  const grpc::Status on_empty = ClassifyCloud(*stub_, "g", Shape(0, 1), &one);
  EXPECT_EQ(on_empty.error_code(), grpc::StatusCode::FAILED_PRECONDITION);
  EXPECT_THAT(on_empty.error_message(), HasSubstr("has no samples"));
  v1::TrainResponse trained;
  ASSERT_TRUE(Train("g", TrainingSet(3, 5), &trained).ok());

  for (int kind = 0; kind < 3; ++kind) {
    const PointCloud query = Shape(kind, 700 + kind, 1500);
    ASSERT_TRUE(ClassifyCloud(*stub_, "g", query, &one, 3, query.size()).ok());
    ASSERT_TRUE(Classify("g", query, &streamed, 3).ok());
    EXPECT_EQ(one.label(), kShapeNames[kind]);
    EXPECT_EQ(one.num_points(), 1500u);
    ExpectSameAnswer(one, streamed);
  }

  const PointCloud cloud = Shape(0, 9);
  EXPECT_EQ(ClassifyCloud(*stub_, "missing", cloud, &one).error_code(),
            grpc::StatusCode::NOT_FOUND);
  EXPECT_EQ(ClassifyCloud(*stub_, "", cloud, &one).error_code(),
            grpc::StatusCode::INVALID_ARGUMENT);
  const grpc::Status few = ClassifyCloud(*stub_, "g", PointCloud{{0, 0, 0}, {1, 1, 1}}, &one);
  EXPECT_EQ(few.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(few.error_message(), HasSubstr("cloud has 2 points"));
  const grpc::Status short_of = ClassifyCloud(*stub_, "g", cloud, &one, 0, cloud.size() + 1);
  EXPECT_EQ(short_of.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  {
    grpc::ClientContext context;
    v1::ClassifyCloudRequest ragged;
    ragged.mutable_header()->set_gallery("g");
    ragged.mutable_points()->set_xyz(std::string(13 * 12 + 5, '\0'));
    const grpc::Status status = stub_->ClassifyCloud(&context, ragged, &one);
    EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  }
  {
    grpc::ClientContext context;
    v1::ClassifyCloudRequest headless;
    headless.mutable_points()->set_xyz(std::string(12 * 100, '\0'));
    const grpc::Status status = stub_->ClassifyCloud(&context, headless, &one);
    EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
    EXPECT_THAT(status.error_message(), HasSubstr("no header"));
  }
  EXPECT_EQ(Get("g").sample_count(), 9u);  // unchanged by every error above
}

TEST_F(GalleryServiceTest, AugmentedGalleriesStoreViewsAndCountEachObjectOnce) {
  grpc::ClientContext context;
  v1::CreateGalleryRequest request;
  request.set_name("robot");
  request.set_descriptor_spec("dfsd:frame=box");
  request.mutable_knn()->set_k(3);
  request.mutable_augmentation()->set_views(4);
  v1::Gallery created;
  ASSERT_TRUE(stub_->CreateGallery(&context, request, &created).ok());
  EXPECT_EQ(created.augmentation().views(), 4u);
  EXPECT_DOUBLE_EQ(created.augmentation().noise(), 0.01);  // defaults filled
  EXPECT_EQ(created.augmentation().min_points(), 300u);
  EXPECT_EQ(created.augmentation().max_points(), 500u);
  EXPECT_EQ(created.augmentation().mix(), v1::VIEW_MIX_UNSPECIFIED);  // the camera's, left unset

  v1::TrainResponse trained;
  ASSERT_TRUE(Train("robot", TrainingSet(3, 40), &trained).ok());
  v1::Gallery gallery = Get("robot");
  EXPECT_EQ(gallery.sample_count(), 9u);
  EXPECT_GT(gallery.vector_count(), 9u * 3);  // most clouds got all 4 views
  EXPECT_LE(gallery.vector_count(), 9u * 5);

  // A stream can turn augmentation off for its own samples.
  v1::ViewAugmentation off;
  const uint64_t before = gallery.vector_count();
  ASSERT_TRUE(Train("robot", {{"box", 0, Shape(0, 77)}}, &trained, 256, &off).ok());
  EXPECT_EQ(Get("robot").vector_count(), before + 1);
  // ... or use varied views; an unknown mix is refused by name.
  v1::ViewAugmentation varied;
  varied.set_views(3);
  varied.set_mix(v1::VIEW_MIX_VARIED);
  ASSERT_TRUE(Train("robot", {{"box", 0, Shape(0, 79)}}, &trained, 256, &varied).ok());
  EXPECT_GT(Get("robot").vector_count(), before + 2);  // the cloud and most of its 3 views
  EXPECT_LE(Get("robot").vector_count(), before + 1 + 4);
  varied.set_mix(static_cast<v1::ViewMix>(9));
  const grpc::Status bad_mix = Train("robot", {{"box", 0, Shape(0, 80)}}, &trained, 256, &varied);
  EXPECT_EQ(bad_mix.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(bad_mix.error_message(), HasSubstr("view mix 9"));
  // ... and an invalid setting fails the stream by name, adding nothing.
  v1::ViewAugmentation too_many;
  too_many.set_views(65);
  const grpc::Status refused = Train("robot", {{"box", 0, Shape(0, 78)}}, &trained, 256, &too_many);
  EXPECT_EQ(refused.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(refused.error_message(), HasSubstr("views 65"));
  EXPECT_EQ(Get("robot").sample_count(), 11u);

  // Three distinct objects answer, whichever views matched.
  v1::ClassifyResponse answer;
  ASSERT_TRUE(Classify("robot", Shape(1, 500, 900), &answer).ok());
  ASSERT_EQ(answer.neighbors_size(), 3);
  EXPECT_NE(answer.neighbors(0).sample_id(), answer.neighbors(1).sample_id());
  EXPECT_NE(answer.neighbors(1).sample_id(), answer.neighbors(2).sample_id());
  EXPECT_NE(answer.neighbors(0).sample_id(), answer.neighbors(2).sample_id());
  for (const v1::Neighbor& n : answer.neighbors()) EXPECT_LE(n.view(), 4u);
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

// gRPC reports a streamed message that does not parse exactly as the end of the stream; the
// service reads its streams raw so that such a message fails the call (found by the
// bad-input corpus, tests/bad_input_test.cc: the samples before it used to be committed).
TEST_F(GalleryServiceTest, AMessageThatDoesNotParseFailsTheWholeStream) {
  ASSERT_TRUE(Create("g").ok());
  v1::TrainRequest header;
  header.mutable_header()->set_gallery("g");
  v1::TrainRequest sample;
  sample.mutable_sample()->set_label("box");
  v1::TrainRequest points;
  const PointCloud cloud = Shape(0, 1);
  points.mutable_points()->set_xyz(Bytes(cloud, 0, cloud.size()));
  const std::vector<std::string> valid = {header.SerializeAsString(), sample.SerializeAsString(),
                                          points.SerializeAsString()};
  std::string invalid_label;  // proto3 refuses a string field that is not UTF-8
  v1::TrainRequest bad_label;
  bad_label.mutable_sample()->set_label("x");
  invalid_label = bad_label.SerializeAsString();
  invalid_label.back() = '\xff';
  for (const std::string& last : {std::string("\xff\xff\xff\xff"), invalid_label}) {
    std::vector<std::string> messages = valid;
    messages.push_back(last);
    const grpc::Status status =
        testing_raw::RawCall(channel_, "/shapeid.v1.ShapeId/Train", messages);
    EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
    EXPECT_THAT(status.error_message(),
                HasSubstr("Train: message 4 of the stream is not a valid shapeid.v1.TrainRequest"));
    EXPECT_EQ(Get("g").sample_count(), 0u);
  }
  // The same three valid messages alone train one sample: the raw path parses like gRPC's.
  v1::TrainResponse trained;
  std::string reply;
  ASSERT_TRUE(testing_raw::RawCall(channel_, "/shapeid.v1.ShapeId/Train", valid, &reply).ok());
  ASSERT_TRUE(trained.ParseFromString(reply));
  EXPECT_EQ(trained.gallery_sample_count(), 1u);

  // A unary request that does not parse is INVALID_ARGUMENT too (gRPC would say UNIMPLEMENTED,
  // which clients take for "an older server").
  const grpc::Status unary =
      testing_raw::RawCall(channel_, "/shapeid.v1.ShapeId/ClassifyCloud", {"\xff\xff\xff"});
  EXPECT_EQ(unary.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(
      unary.error_message(),
      HasSubstr("ClassifyCloud: the request is not a valid shapeid.v1.ClassifyCloudRequest"));
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

// A Train stream's layout holds for every sample; a sample whose bytes betray it (here
// little-endian among big-endian ones) fails the whole stream, named, and trains nothing.
TEST_F(GalleryServiceTest, ASampleWhoseBytesBetrayTheLayoutFailsTheStream) {
  ASSERT_TRUE(Create("g").ok());
  const auto records = [](const PointCloud& cloud, bool big_endian) {
    std::string bytes(cloud.size() * 16, '\0');  // x y z intensity
    for (size_t i = 0; i < 3 * cloud.size(); ++i) {
      char v[4];
      std::memcpy(v, cloud.data() + i, 4);
      if (big_endian) std::reverse(v, v + 4);  // this host is little-endian
      std::memcpy(&bytes[i / 3 * 16 + i % 3 * 4], v, 4);
    }
    return bytes;
  };
  const auto train = [&](const std::vector<bool>& big_endian, v1::TrainResponse* response) {
    grpc::ClientContext context;
    auto writer = stub_->Train(&context, response);
    v1::TrainRequest header;
    header.mutable_header()->set_gallery("g");
    v1::PointLayout* layout = header.mutable_header()->mutable_layout();
    layout->set_point_step(16);
    layout->set_is_bigendian(true);
    v1::PointCoordinate* axes[3] = {layout->mutable_x(), layout->mutable_y(), layout->mutable_z()};
    for (int a = 0; a < 3; ++a) {
      axes[a]->set_offset(4 * a);
      axes[a]->set_datatype(v1::FLOAT32);
    }
    bool open = writer->Write(header);
    for (size_t s = 0; s < big_endian.size(); ++s) {
      v1::TrainRequest sample, points;
      sample.mutable_sample()->set_label(kShapeNames[s % 3]);
      points.mutable_points()->set_xyz(records(Shape(s % 3, 40 + s), big_endian[s]));
      open = open && writer->Write(sample) && writer->Write(points);
    }
    writer->WritesDone();
    return writer->Finish();
  };
  v1::TrainResponse response;
  const grpc::Status status = train({true, false, true}, &response);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(status.error_message(), HasSubstr("sample 1"));
  EXPECT_THAT(status.error_message(), HasSubstr("the points look byte-swapped: "));
  EXPECT_THAT(status.error_message(), HasSubstr("0 read little-endian; is is_bigendian right?"));
  EXPECT_EQ(Get("g").sample_count(), 0u);
  ASSERT_TRUE(train({true, true, true}, &response).ok());
  EXPECT_EQ(response.gallery_sample_count(), 3u);
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

TEST_F(GalleryServiceTest, ExportThenImportElsewhereAnswersBitForBit) {
  grpc::ClientContext create_context;
  v1::CreateGalleryRequest create;
  create.set_name("shapes");
  create.set_descriptor_spec("rphsd:refs=cubic27,bins=30");
  create.mutable_knn()->set_k(3);
  create.mutable_knn()->set_weighting(v1::VOTE_WEIGHTING_DISTANCE);
  create.mutable_knn()->set_scaling(v1::FEATURE_SCALING_ZSCORE);
  v1::Gallery created;
  ASSERT_TRUE(stub_->CreateGallery(&create_context, create, &created).ok());
  std::vector<Sample> samples = TrainingSet(5, 300);
  samples[4].id = 7;  // a client id among assigned ones
  v1::TrainResponse trained;
  ASSERT_TRUE(Train("shapes", samples, &trained).ok());

  std::vector<v1::GalleryExportChunk> chunks;
  const grpc::Status exported = Export("shapes", &chunks);
  ASSERT_TRUE(exported.ok()) << exported.error_message();
  ASSERT_GE(chunks.size(), 3u);
  EXPECT_EQ(chunks.front().header().sample_count(), 15u);
  EXPECT_EQ(chunks.back().trailer().sample_count(), 15u);

  v1::Gallery moved;
  const grpc::Status imported = Import(Other(), chunks, "", &moved);
  ASSERT_TRUE(imported.ok()) << imported.error_message();
  const v1::Gallery original = Get("shapes");
  EXPECT_EQ(moved.name(), "shapes");
  EXPECT_EQ(moved.descriptor_spec(), original.descriptor_spec());
  EXPECT_EQ(moved.knn().SerializeAsString(), original.knn().SerializeAsString());
  EXPECT_EQ(moved.sample_count(), 15u);
  EXPECT_EQ(moved.create_time().SerializeAsString(), original.create_time().SerializeAsString());
  EXPECT_EQ(moved.update_time().SerializeAsString(), original.update_time().SerializeAsString());
  EXPECT_EQ(moved.descriptor_version(), original.descriptor_version());
  EXPECT_GT(original.descriptor_version(), 0u);
  EXPECT_EQ(moved.software_version(), original.software_version());
  EXPECT_FALSE(original.software_version().empty());
  EXPECT_EQ(moved.incompatible(), "");

  // A copy on the same server, under a new name.
  v1::Gallery copy;
  ASSERT_TRUE(Import(*stub_, chunks, "copy", &copy).ok());
  EXPECT_EQ(copy.name(), "copy");
  for (int kind = 0; kind < 3; ++kind) {
    const PointCloud query = Shape(kind, 4242 + kind, 1500);
    v1::ClassifyResponse here, there, copied;
    ASSERT_TRUE(Classify("shapes", query, &here, 5).ok());
    ASSERT_TRUE(Classify("shapes", query, &there, 5, &Other()).ok());
    ASSERT_TRUE(Classify("copy", query, &copied, 5).ok());
    EXPECT_EQ(here.label(), kShapeNames[kind]);
    ExpectSameAnswer(here, there);
    ExpectSameAnswer(here, copied);
  }

  // The name is taken now: refused, and the copy is unchanged.
  const grpc::Status again = Import(*stub_, chunks, "copy");
  EXPECT_EQ(again.error_code(), grpc::StatusCode::ALREADY_EXISTS);
  EXPECT_THAT(again.error_message(), HasSubstr("'copy' already exists"));
  EXPECT_EQ(Get("copy").version(), copy.version());
}

TEST_F(GalleryServiceTest, ImportRefusesBadStreamsAndCreatesNothing) {
  ASSERT_TRUE(Create("g", "rphsd:refs=cross7,bins=10").ok());
  v1::TrainResponse trained;
  ASSERT_TRUE(Train("g", TrainingSet(2, 11), &trained).ok());
  std::vector<v1::GalleryExportChunk> chunks;
  ASSERT_TRUE(Export("g", &chunks).ok());
  ASSERT_EQ(chunks.size(), 3u);  // header, one run of 6 samples, trailer

  auto damaged = chunks;
  float* feature = damaged[1].mutable_samples()->mutable_features()->Mutable(5);
  *feature = std::nextafter(*feature, 2.0f);
  grpc::Status status = Import(*stub_, damaged, "damaged");
  EXPECT_EQ(status.error_code(), grpc::StatusCode::DATA_LOSS);
  EXPECT_THAT(status.error_message(), HasSubstr("export damaged: checksum mismatch"));

  const std::vector<v1::GalleryExportChunk> truncated(chunks.begin(), chunks.end() - 1);
  status = Import(*stub_, truncated, "truncated");
  EXPECT_EQ(status.error_code(), grpc::StatusCode::DATA_LOSS);
  EXPECT_THAT(status.error_message(), HasSubstr("export truncated: 6 of 6 samples, no trailer"));

  const std::vector<v1::GalleryExportChunk> reordered = {chunks[1], chunks[0], chunks[2]};
  status = Import(*stub_, reordered, "reordered");
  EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(status.error_message(), HasSubstr("samples before the header"));

  auto future = chunks;
  future[0].mutable_header()->set_format_version(2);
  EXPECT_EQ(Import(*stub_, future, "future").error_code(), grpc::StatusCode::FAILED_PRECONDITION);
  EXPECT_EQ(Import(*stub_, chunks, "no spaces").error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_EQ(Import(*stub_, {}, "empty").error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  const grpc::Status renamed = Import(*stub_, chunks, "first", nullptr, "second");
  EXPECT_EQ(renamed.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(renamed.error_message(), HasSubstr("read from the first message only"));
  EXPECT_EQ(Import(*stub_, chunks).error_code(), grpc::StatusCode::ALREADY_EXISTS);  // "g"

  grpc::ClientContext context;
  v1::ListGalleriesResponse list;
  ASSERT_TRUE(stub_->ListGalleries(&context, {}, &list).ok());
  ASSERT_EQ(list.galleries_size(), 1);  // every refused import left nothing behind
  EXPECT_EQ(list.galleries(0).name(), "g");
}

TEST_F(GalleryServiceTest, ExportErrorsAndCancellation) {
  std::vector<v1::GalleryExportChunk> chunks;
  const grpc::Status missing = Export("nope", &chunks);
  EXPECT_EQ(missing.error_code(), grpc::StatusCode::NOT_FOUND);
  EXPECT_THAT(missing.error_message(), HasSubstr("nope"));
  EXPECT_TRUE(chunks.empty());
  EXPECT_EQ(Export("", &chunks).error_code(), grpc::StatusCode::INVALID_ARGUMENT);

  // A client that goes away after the first chunk ends the call on the server too: the
  // shutdown below would otherwise wait its whole grace period for it.
  ASSERT_TRUE(Create("g").ok());
  v1::TrainResponse trained;
  ASSERT_TRUE(Train("g", TrainingSet(2, 3), &trained).ok());
  grpc::ClientContext context;
  v1::ExportGalleryRequest request;
  request.set_name("g");
  auto reader = stub_->ExportGallery(&context, request);
  v1::GalleryExportChunk first;
  ASSERT_TRUE(reader->Read(&first));
  EXPECT_TRUE(first.has_header());
  context.TryCancel();
  EXPECT_EQ(reader->Finish().error_code(), grpc::StatusCode::CANCELLED);
  const absl::Time start = absl::Now();
  server_->Shutdown(absl::Seconds(20));
  EXPECT_LT(absl::Now() - start, absl::Seconds(5));
}

TEST_F(GalleryServiceTest, AnExportDuringTrainingIsOneConsistentSnapshot) {
  ASSERT_TRUE(Create("live", "rphsd:refs=cross7,bins=10").ok());
  v1::TrainResponse trained;
  ASSERT_TRUE(Train("live", TrainingSet(1, 1), &trained).ok());  // batches of 3 samples
  std::atomic<bool> done{false};
  std::thread trainer([&] {
    for (uint32_t i = 0; i < 15; ++i) {
      v1::TrainResponse response;
      EXPECT_TRUE(Train("live", TrainingSet(1, 100 + i), &response).ok());
    }
    done = true;
  });
  std::vector<uint64_t> counts;
  for (int e = 0; e < 40 && (e < 3 || !done); ++e) {
    std::vector<v1::GalleryExportChunk> chunks;
    const grpc::Status status = Export("live", &chunks);
    ASSERT_TRUE(status.ok()) << status.error_message();
    const uint64_t announced = chunks.front().header().sample_count();
    uint64_t carried = 0;
    for (const auto& chunk : chunks) carried += chunk.samples().sample_ids_size();
    EXPECT_EQ(carried, announced);
    EXPECT_EQ(chunks.back().trailer().sample_count(), announced);
    EXPECT_EQ(announced % 3, 0u) << "a Train batch was torn";
    counts.push_back(announced);
    // The server's own checks (order, count, checksum) accept it.
    const grpc::Status imported = Import(Other(), chunks, absl::StrCat("snap-", e));
    EXPECT_TRUE(imported.ok()) << imported.error_message();
  }
  trainer.join();
  EXPECT_TRUE(std::is_sorted(counts.begin(), counts.end()));
}

// Provenance goes in with Train, comes back with every neighbor and from ListSamples (paged
// by id, by label), and survives an export and import.
TEST_F(GalleryServiceTest, ProvenanceTravelsWithItsSamples) {
  ASSERT_TRUE(Create("traced").ok());
  std::vector<Sample> samples;
  for (uint64_t i = 0; i < 9; ++i) {
    const int kind = static_cast<int>(i % 3);
    Sample s{kShapeNames[kind], 100 - i, Shape(kind, static_cast<uint32_t>(i))};
    if (i % 2 == 0) s.source = absl::StrCat("/scans/", i, ".pcd");
    if (i == 4) s.metadata = {{"camera", "d435"}, {"session", "7"}};
    samples.push_back(std::move(s));
  }
  v1::TrainResponse trained;
  ASSERT_TRUE(Train("traced", samples, &trained).ok());

  v1::ClassifyResponse answer;
  ASSERT_TRUE(Classify("traced", Shape(1, 50), &answer, 9).ok());
  ASSERT_EQ(answer.neighbors_size(), 9);
  for (const v1::Neighbor& n : answer.neighbors()) {
    const uint64_t i = 100 - n.sample_id();
    EXPECT_EQ(n.source(), i % 2 == 0 ? absl::StrCat("/scans/", i, ".pcd") : "") << i;
    EXPECT_EQ(n.metadata_size(), i == 4 ? 2 : 0) << i;
    if (i == 4) {
      EXPECT_EQ(n.metadata().at("session"), "7");
    }
  }

  const auto list = [&](v1::ListSamplesRequest request, v1::ListSamplesResponse* response) {
    grpc::ClientContext context;
    return stub_->ListSamples(&context, request, response);
  };
  v1::ListSamplesRequest request;
  request.set_gallery("traced");
  request.set_page_size(4);
  std::vector<uint64_t> ids;
  int pages = 0;
  for (;;) {
    v1::ListSamplesResponse page;
    ASSERT_TRUE(list(request, &page).ok());
    ++pages;
    EXPECT_EQ(page.gallery_version(), 1u);
    for (const v1::SampleInfo& s : page.samples()) {
      ids.push_back(s.sample_id());
      const uint64_t i = 100 - s.sample_id();
      EXPECT_EQ(s.label(), kShapeNames[i % 3]);
      EXPECT_EQ(s.views(), 1u);
      EXPECT_EQ(s.source(), i % 2 == 0 ? absl::StrCat("/scans/", i, ".pcd") : "");
    }
    if (page.next_page_token().empty()) break;
    request.set_page_token(page.next_page_token());
  }
  EXPECT_EQ(pages, 3);
  EXPECT_EQ(ids, (std::vector<uint64_t>{92, 93, 94, 95, 96, 97, 98, 99, 100}));

  v1::ListSamplesRequest by_label;
  by_label.set_gallery("traced");
  by_label.set_label(kShapeNames[0]);
  v1::ListSamplesResponse page;
  ASSERT_TRUE(list(by_label, &page).ok());
  EXPECT_EQ(page.samples_size(), 3);
  EXPECT_TRUE(page.next_page_token().empty());

  // Errors: a token of another gallery or none at all, a page too large, no such gallery.
  ASSERT_TRUE(Create("other").ok());
  v1::ListSamplesRequest bad = request;
  bad.set_gallery("other");
  grpc::Status status = list(bad, &page);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(status.error_message(), HasSubstr("was not given by this gallery"));
  bad.set_page_token("garbage");
  EXPECT_EQ(list(bad, &page).error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  bad = by_label;
  bad.set_page_size(10001);
  status = list(bad, &page);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(status.error_message(), HasSubstr("page_size 10001 is over 10000"));
  bad = by_label;
  bad.set_gallery("nosuch");
  EXPECT_EQ(list(bad, &page).error_code(), grpc::StatusCode::NOT_FOUND);

  // Too much provenance fails the sample, naming it.
  Sample big{"box", 5, Shape(0, 60)};
  big.source = std::string(4097, 's');
  status = Train("traced", {big}, &trained);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(status.error_message(), HasSubstr("sample 0: source"));

  // Export and import keep it.
  std::vector<v1::GalleryExportChunk> chunks;
  ASSERT_TRUE(Export("traced", &chunks).ok());
  ASSERT_TRUE(Import(*stub_, chunks, "traced-copy").ok());
  by_label.set_gallery("traced-copy");
  by_label.clear_label();
  ASSERT_TRUE(list(by_label, &page).ok());
  ASSERT_EQ(page.samples_size(), 9);
  EXPECT_EQ(page.samples(4).source(), "/scans/4.pcd");  // id 96
  EXPECT_EQ(page.samples(4).metadata().at("camera"), "d435");
}

// ListSamples fills a page by count and by bytes: with samples at the provenance limits
// (about 8.6 KB each), a default page (1,000) stops before it passes max_answer_bytes, and
// the pages still give every sample once, in id order, with a label or without.
TEST_F(GalleryServiceTest, ListSamplesPagesStayWithinMaxAnswerBytes) {
  const auto restart = [&](size_t max_answer_bytes) {
    ServerOptions options;
    options.listen = "127.0.0.1:0";
    options.service.max_answer_bytes = max_answer_bytes;
    auto server = ShapeIdServer::Start(options);
    ASSERT_TRUE(server.ok()) << server.status();
    server_ = std::move(server).value();
    channel_ = grpc::CreateChannel(server_->address(), grpc::InsecureChannelCredentials());
    stub_ = v1::ShapeId::NewStub(channel_);
  };
  std::vector<Sample> samples;
  for (uint64_t id = 1; id <= 40; ++id) {
    Sample s{id % 2 == 0 ? "even" : "odd", id, Shape(static_cast<int>(id % 3), 7 + id, 100)};
    s.source = absl::StrCat("/scans/", id, "/");
    s.source.resize(4096, 's');     // kMaxSourceBytes
    for (int k = 0; k < 64; ++k) {  // kMaxMetadataEntries, kMaxMetadataBytes of keys and values
      s.metadata[absl::StrCat("k", k / 10, k % 10)] =
          std::string(61, static_cast<char>('a' + k % 26));
    }
    samples.push_back(std::move(s));
  }
  // Pages of `page_size` (0: the default) until the last; each page's size in bytes.
  const auto list_all = [&](const std::string& label, uint32_t page_size,
                            std::vector<uint64_t>* ids, std::vector<size_t>* page_bytes) {
    v1::ListSamplesRequest request;
    request.set_gallery("fat");
    request.set_label(label);
    request.set_page_size(page_size);
    for (int pages = 0; pages < 100; ++pages) {
      grpc::ClientContext context;
      v1::ListSamplesResponse page;
      const grpc::Status status = stub_->ListSamples(&context, request, &page);
      ASSERT_TRUE(status.ok()) << status.error_message();
      ASSERT_GT(page.samples_size(), 0);
      page_bytes->push_back(page.ByteSizeLong());
      for (const v1::SampleInfo& sample : page.samples()) {
        ids->push_back(sample.sample_id());
        EXPECT_EQ(sample.source(), samples[sample.sample_id() - 1].source);
        EXPECT_EQ(sample.metadata_size(), 64);
      }
      if (page.next_page_token().empty()) return;
      request.set_page_token(page.next_page_token());
    }
    FAIL() << "more than 100 pages";
  };
  std::vector<uint64_t> every(40), odd;
  for (uint64_t id = 1; id <= 40; ++id) {
    every[id - 1] = id;
    if (id % 2 == 1) odd.push_back(id);
  }

  constexpr size_t kMaxAnswer = 64 << 10;
  restart(kMaxAnswer);
  v1::TrainResponse trained;
  ASSERT_TRUE(Create("fat").ok());
  ASSERT_TRUE(Train("fat", samples, &trained).ok());
  std::vector<uint64_t> ids;
  std::vector<size_t> bytes;
  list_all("", 0, &ids, &bytes);
  EXPECT_EQ(ids, every);
  EXPECT_GE(bytes.size(), 6u);  // 40 x 8.6 KB in pages of at most 64 KiB
  for (size_t b : bytes) EXPECT_LE(b, kMaxAnswer);
  EXPECT_GT(bytes[0], kMaxAnswer - 9000);  // full: one more sample would not fit
  // A page_size below what fits: pages cut by count, as before.
  ids.clear();
  bytes.clear();
  list_all("", 3, &ids, &bytes);
  EXPECT_EQ(ids, every);
  EXPECT_EQ(bytes.size(), 14u);
  ids.clear();
  bytes.clear();
  list_all("odd", 0, &ids, &bytes);
  EXPECT_EQ(ids, odd);
  for (size_t b : bytes) EXPECT_LE(b, kMaxAnswer);

  // A limit below one sample (possible in ServiceOptions, not the flag): one sample a page.
  restart(1000);
  ASSERT_TRUE(Create("fat").ok());
  ASSERT_TRUE(Train("fat", samples, &trained).ok());
  ids.clear();
  bytes.clear();
  list_all("", 0, &ids, &bytes);
  EXPECT_EQ(ids, every);
  EXPECT_EQ(bytes.size(), 40u);
}

// A Classify whose answer (k neighbors, each with its provenance) would pass
// max_answer_bytes is refused saying what to ask for; one that fits is answered, and the
// memory its answer held is given back.
TEST_F(GalleryServiceTest, AClassifyAnswerOverMaxAnswerBytesIsRefusedNamingK) {
  ServerOptions options;
  options.listen = "127.0.0.1:0";
  options.service.max_answer_bytes = 64 << 10;
  auto server = ShapeIdServer::Start(options);
  ASSERT_TRUE(server.ok()) << server.status();
  server_ = std::move(server).value();
  channel_ = grpc::CreateChannel(server_->address(), grpc::InsecureChannelCredentials());
  stub_ = v1::ShapeId::NewStub(channel_);
  std::vector<Sample> samples;
  for (uint64_t id = 1; id <= 20; ++id) {
    Sample s{id % 2 == 0 ? "even" : "odd", id, Shape(static_cast<int>(id % 3), 7 + id, 100)};
    s.source = std::string(4096, 's');
    s.metadata["camera"] = std::string(4000, 'c');
    samples.push_back(std::move(s));
  }
  v1::TrainResponse trained;
  ASSERT_TRUE(Create("fat").ok());
  ASSERT_TRUE(Train("fat", samples, &trained).ok());
  const auto classify = [&](uint32_t k, v1::ClassifyResponse* response) {
    v1::ClassifyCloudRequest request;
    request.mutable_header()->set_gallery("fat");
    request.mutable_header()->set_k(k);
    const PointCloud query = Shape(1, 99, 100);
    request.mutable_points()->set_xyz(
        std::string(reinterpret_cast<const char*>(query.data()), query.size() * 12));
    grpc::ClientContext context;
    return stub_->ClassifyCloud(&context, request, response);
  };
  v1::ClassifyResponse response;
  const grpc::Status refused = classify(20, &response);  // 20 x 8 KB: 160 KB
  EXPECT_EQ(refused.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
  EXPECT_THAT(refused.error_message(), HasSubstr("--max_answer_bytes"));
  EXPECT_THAT(refused.error_message(), HasSubstr("fewer neighbors (k)"));
  const grpc::Status fits = classify(5, &response);
  ASSERT_TRUE(fits.ok()) << fits.error_message();
  EXPECT_EQ(response.neighbors_size(), 5);
  EXPECT_EQ(response.neighbors(0).source(), std::string(4096, 's'));
  // The worker gives its work's memory back just after the answer is sent.
  v1::ServerStats stats;
  for (int i = 0; i < 200; ++i) {
    grpc::ClientContext stats_context;
    ASSERT_TRUE(stub_->GetServerStats(&stats_context, v1::GetServerStatsRequest(), &stats).ok());
    if (stats.memory_held_bytes() == 0) break;
    absl::SleepFor(absl::Milliseconds(10));
  }
  EXPECT_EQ(stats.memory_held_bytes(), 0u);
  EXPECT_GE(stats.memory_held_peak_bytes(), 2 * response.ByteSizeLong());
  EXPECT_EQ(stats.caller_backlog().seconds() + stats.caller_backlog().nanos(), 0);
}

}  // namespace
}  // namespace shapeid
