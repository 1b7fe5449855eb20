#include "fuzz/fuzz_service.h"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <utility>

#include "core/point_cloud.h"
#include "core/testing/test_clouds.h"

namespace shapeid::fuzz {
namespace {

constexpr int kMaxCalls = 16;
constexpr int kMaxMessagesPerStream = 64;

void Fail(const std::string& what, const grpc::Status& status = grpc::Status::OK) {
  std::fprintf(stderr, "fuzz oracle failed: %s (status %d: %s)\n", what.c_str(),
               static_cast<int>(status.error_code()), status.error_message().c_str());
  std::abort();
}

std::unique_ptr<grpc::ClientContext> NewContext() {
  auto context = std::make_unique<grpc::ClientContext>();
  // Far beyond any honest call on these small limits; libFuzzer's -timeout catches a hang
  // first.
  context->set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(60));
  return context;
}

std::string Xyz(const PointCloud& cloud) {
  std::string bytes(cloud.size() * 12, '\0');
  std::memcpy(bytes.data(), cloud.data(), bytes.size());
  return bytes;
}

// Writes the messages of a client stream, stopping early where the server has already
// answered or where the call's cancel_after says the client gives up.
template <typename Request, typename Response, typename Open>
grpc::Status RunClientStream(const google::protobuf::RepeatedPtrField<Request>& messages,
                             uint32_t cancel_after, Open open, Response* response) {
  auto context = NewContext();
  auto writer = open(context.get(), response);
  int written = 0;
  for (const Request& message : messages) {
    if (written == kMaxMessagesPerStream) break;
    if (cancel_after != 0 && written == static_cast<int>(cancel_after)) {
      context->TryCancel();
      return writer->Finish();
    }
    if (!writer->Write(message)) break;
    ++written;
  }
  writer->WritesDone();
  return writer->Finish();
}

void CheckDescribe(const v1::DescribeResponse& response) {
  if (response.values().empty()) Fail("Describe answered no values");
  for (float v : response.values()) {
    if (!std::isfinite(v)) Fail("Describe answered a non-finite value");
  }
}

void CheckClassify(const v1::ClassifyResponse& response) {
  if (response.label().empty() && !response.unknown()) Fail("Classify answered no label");
  double previous = 0;
  for (const v1::Neighbor& n : response.neighbors()) {
    if (!std::isfinite(n.distance()) || n.distance() < previous) {
      Fail("Classify's neighbors are not sorted by finite distance");
    }
    previous = n.distance();
  }
}

// Every point sent is in exactly one plane, object or count; indices, when sent, ascend
// within the frame; each object is classified or carries its error.
void CheckScene(const v1::RecognizeSceneResponse& response, bool indices) {
  uint64_t accounted = response.non_finite_points() + response.outside_region() +
                       response.in_small_clusters() + response.in_large_clusters();
  for (const v1::ScenePlane& plane : response.planes()) {
    if (plane.coefficients_size() != 4) Fail("a scene plane without 4 coefficients");
    accounted += plane.num_points();
  }
  for (const v1::SceneObject& object : response.objects()) {
    CheckClassify(object.classification());
    accounted += object.classification().num_points();
    if (indices &&
        static_cast<uint64_t>(object.indices_size()) != object.classification().num_points()) {
      Fail("a scene object's indices do not match its point count");
    }
    for (int i = 0; i < object.indices_size(); ++i) {
      if (object.indices(i) >= response.num_points() ||
          (i > 0 && object.indices(i) <= object.indices(i - 1))) {
        Fail("a scene object's indices are not ascending within the frame");
      }
    }
  }
  if (accounted != response.num_points()) Fail("a scene's points are not all accounted for");
}

bool Documented(grpc::StatusCode code) {
  switch (code) {
    case grpc::StatusCode::OK:
    case grpc::StatusCode::INVALID_ARGUMENT:
    case grpc::StatusCode::NOT_FOUND:
    case grpc::StatusCode::ALREADY_EXISTS:
    case grpc::StatusCode::FAILED_PRECONDITION:
    case grpc::StatusCode::RESOURCE_EXHAUSTED:
    case grpc::StatusCode::DATA_LOSS:
      return true;
    default:
      return false;
  }
}

}  // namespace

FuzzServer::FuzzServer() {
  GalleryLimits limits;
  limits.max_points_per_cloud = 4096;
  limits.max_samples_per_gallery = 64;
  limits.max_galleries = 4;
  registry_ = std::make_shared<GalleryRegistry>(limits);
  ServiceOptions options;
  options.max_samples_per_train = 8;
  service_ = std::make_unique<ShapeIdService>(options, registry_);
  grpc::ServerBuilder builder;
  builder.RegisterService(service_.get());
  server_ = builder.BuildAndStart();
  if (server_ == nullptr) Fail("the in-process server did not start");
  stub_ = v1::ShapeId::NewStub(server_->InProcessChannel(grpc::ChannelArguments()));

  v1::CreateGalleryRequest create;
  create.set_name("base");
  v1::Gallery gallery;
  auto context = NewContext();
  grpc::Status status = stub_->CreateGallery(context.get(), create, &gallery);
  if (!status.ok()) Fail("creating the base gallery", status);

  google::protobuf::RepeatedPtrField<v1::TrainRequest> train;
  train.Add()->mutable_header()->set_gallery("base");
  for (int kind = 0; kind < 3; ++kind) {
    v1::SampleHeader* sample = train.Add()->mutable_sample();
    sample->set_label(testing_clouds::kShapeNames[kind]);
    train.Add()->mutable_points()->set_xyz(Xyz(testing_clouds::ShapeCloud(kind, 7, 64)));
  }
  v1::TrainResponse trained;
  status = RunClientStream(
      train, 0, [&](grpc::ClientContext* c, v1::TrainResponse* r) { return stub_->Train(c, r); },
      &trained);
  if (!status.ok()) Fail("training the base gallery", status);
}

FuzzServer::~FuzzServer() {
  server_->Shutdown(std::chrono::system_clock::now() + std::chrono::seconds(5));
}

std::string FuzzServer::GalleriesState() {
  auto context = NewContext();
  v1::ListGalleriesResponse response;
  const grpc::Status status =
      stub_->ListGalleries(context.get(), v1::ListGalleriesRequest(), &response);
  if (!status.ok()) Fail("ListGalleries failed", status);
  return response.DebugString();
}

grpc::Status FuzzServer::Run(const Call& call) {
  auto context = NewContext();
  v1::ShapeId::Stub& stub = *stub_;
  switch (call.kind_case()) {
    case Call::kDescribe: {
      v1::DescribeResponse response;
      grpc::Status status = RunClientStream(
          call.describe().messages(), call.cancel_after(),
          [&](grpc::ClientContext* c, v1::DescribeResponse* r) { return stub.Describe(c, r); },
          &response);
      if (status.ok()) CheckDescribe(response);
      return status;
    }
    case Call::kTrain: {
      v1::TrainResponse response;
      return RunClientStream(
          call.train().messages(), call.cancel_after(),
          [&](grpc::ClientContext* c, v1::TrainResponse* r) { return stub.Train(c, r); },
          &response);
    }
    case Call::kClassify: {
      v1::ClassifyResponse response;
      grpc::Status status = RunClientStream(
          call.classify().messages(), call.cancel_after(),
          [&](grpc::ClientContext* c, v1::ClassifyResponse* r) { return stub.Classify(c, r); },
          &response);
      if (status.ok()) CheckClassify(response);
      return status;
    }
    case Call::kImportGallery: {
      v1::Gallery response;
      return RunClientStream(
          call.import_gallery().messages(), call.cancel_after(),
          [&](grpc::ClientContext* c, v1::Gallery* r) { return stub.ImportGallery(c, r); },
          &response);
    }
    case Call::kDescribeCloud: {
      v1::DescribeResponse response;
      grpc::Status status = stub.DescribeCloud(context.get(), call.describe_cloud(), &response);
      if (status.ok()) CheckDescribe(response);
      return status;
    }
    case Call::kClassifyCloud: {
      v1::ClassifyResponse response;
      grpc::Status status = stub.ClassifyCloud(context.get(), call.classify_cloud(), &response);
      if (status.ok()) CheckClassify(response);
      return status;
    }
    case Call::kRecognizeScene: {
      v1::RecognizeSceneResponse response;
      grpc::Status status = RunClientStream(
          call.recognize_scene().messages(), call.cancel_after(),
          [&](grpc::ClientContext* c, v1::RecognizeSceneResponse* r) {
            return stub.RecognizeScene(c, r);
          },
          &response);
      const auto& messages = call.recognize_scene().messages();
      if (status.ok()) {
        CheckScene(response, !messages.empty() && messages[0].header().return_indices());
      }
      return status;
    }
    case Call::kRecognizeSceneCloud: {
      v1::RecognizeSceneResponse response;
      grpc::Status status =
          stub.RecognizeSceneCloud(context.get(), call.recognize_scene_cloud(), &response);
      if (status.ok()) CheckScene(response, call.recognize_scene_cloud().header().return_indices());
      return status;
    }
    case Call::kCreateGallery: {
      v1::Gallery response;
      return stub.CreateGallery(context.get(), call.create_gallery(), &response);
    }
    case Call::kGetGallery: {
      v1::Gallery response;
      return stub.GetGallery(context.get(), call.get_gallery(), &response);
    }
    case Call::kListGalleries: {
      v1::ListGalleriesResponse response;
      return stub.ListGalleries(context.get(), call.list_galleries(), &response);
    }
    case Call::kDeleteGallery: {
      v1::DeleteGalleryResponse response;
      return stub.DeleteGallery(context.get(), call.delete_gallery(), &response);
    }
    case Call::kRemoveSamples: {
      v1::RemoveSamplesResponse response;
      return stub.RemoveSamples(context.get(), call.remove_samples(), &response);
    }
    case Call::kExportGallery: {
      auto reader = stub.ExportGallery(context.get(), call.export_gallery());
      v1::GalleryExportChunk chunk;
      uint32_t read = 0;
      while (reader->Read(&chunk)) {
        if (call.cancel_after() != 0 && ++read == call.cancel_after()) {
          context->TryCancel();
          break;
        }
      }
      return reader->Finish();
    }
    case Call::kListDescriptors: {
      v1::ListDescriptorsResponse response;
      return stub.ListDescriptors(context.get(), call.list_descriptors(), &response);
    }
    case Call::KIND_NOT_SET:
      break;
  }
  return grpc::Status::OK;
}

void RunSession(const ServiceSession& session) {
  FuzzServer server;
  int calls = 0;
  for (const Call& call : session.calls()) {
    if (calls++ == kMaxCalls) break;
    const std::string before = server.GalleriesState();
    const grpc::Status status = server.Run(call);
    const bool cancelled =
        call.cancel_after() != 0 && status.error_code() == grpc::StatusCode::CANCELLED;
    if (!Documented(status.error_code()) && !cancelled) {
      Fail("call " + std::to_string(calls) + " (field " + std::to_string(call.kind_case()) +
               ") failed with an undocumented code",
           status);
    }
    if (!status.ok() && server.GalleriesState() != before) {
      Fail("call " + std::to_string(calls) + " (field " + std::to_string(call.kind_case()) +
               ") failed and still changed the galleries",
           status);
    }
  }
  // The server still answers, and the base gallery, if the session left it, still classifies.
  v1::GetGalleryRequest get;
  get.set_name("base");
  v1::Gallery base;
  auto context = NewContext();
  if (server.stub().GetGallery(context.get(), get, &base).ok() && base.sample_count() > 0) {
    v1::ClassifyCloudRequest classify;
    classify.mutable_header()->set_gallery("base");
    classify.mutable_header()->set_k(1);
    classify.mutable_points()->set_xyz(Xyz(testing_clouds::ShapeCloud(1, 8, 64)));
    v1::ClassifyResponse response;
    auto context2 = NewContext();
    const grpc::Status status = server.stub().ClassifyCloud(context2.get(), classify, &response);
    if (!status.ok()) Fail("the base gallery no longer classifies", status);
    CheckClassify(response);
  }
}

}  // namespace shapeid::fuzz
