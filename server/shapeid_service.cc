#include "server/shapeid_service.h"

#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "absl/strings/escaping.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_split.h"
#include "core/descriptor_registry.h"
#include "core/gallery/gallery.h"
#include "core/status_macros.h"
#include "google/protobuf/io/coded_stream.h"
#include "server/authorization.h"
#include "server/cloud_calls.h"
#include "server/proto_convert.h"
#include "server/transfer_calls.h"
#include "server/unary_call.h"
#include "server/work_costs.h"

namespace shapeid {
namespace {

// A store write of a gallery's metadata or samples: cheap for the CPU, slow on the disk.
constexpr absl::Duration kStoreWriteCost = absl::Milliseconds(1);

std::shared_ptr<MemoryBudget> NewBudget(const ServiceOptions& options) {
  return std::make_shared<MemoryBudget>(MemoryBudgetOptions{
      options.memory_budget_bytes > 0 ? options.memory_budget_bytes : DefaultMemoryBudgetBytes(),
      options.memory_caller_share});
}

}  // namespace

ShapeIdService::ShapeIdService(ServiceOptions options, std::shared_ptr<GalleryRegistry> registry,
                               std::shared_ptr<const ApiKeyStore> keys, CallObserver observer)
    : options_(std::move(options)),
      registry_(std::move(registry)),
      gate_(std::move(keys), options_.max_streams_per_client, options_.max_call),
      observer_(std::move(observer)),
      budget_(NewBudget(options_)),
      scheduler_(options_.work, budget_),
      runtime_{&gate_, &observer_, &scheduler_, budget_.get(), &options_, registry_.get()} {}

ShapeIdService::~ShapeIdService() { scheduler_.Stop(); }

grpc::ServerReadReactor<grpc::ByteBuffer>* ShapeIdService::Describe(
    grpc::CallbackServerContext* context, grpc::ByteBuffer* response) {
  return StartDescribe(context, runtime_, response);
}

grpc::ServerReadReactor<grpc::ByteBuffer>* ShapeIdService::Train(
    grpc::CallbackServerContext* context, grpc::ByteBuffer* response) {
  return StartTrain(context, runtime_, response);
}

grpc::ServerReadReactor<grpc::ByteBuffer>* ShapeIdService::Classify(
    grpc::CallbackServerContext* context, grpc::ByteBuffer* response) {
  return StartClassify(context, runtime_, response);
}

grpc::ServerReadReactor<grpc::ByteBuffer>* ShapeIdService::RecognizeScene(
    grpc::CallbackServerContext* context, grpc::ByteBuffer* response) {
  return StartRecognizeScene(context, runtime_, response);
}

grpc::ServerUnaryReactor* ShapeIdService::DescribeCloud(grpc::CallbackServerContext* context,
                                                        const grpc::ByteBuffer* raw_request,
                                                        grpc::ByteBuffer* raw_response) {
  return RunUnary<v1::DescribeCloudRequest, v1::DescribeResponse>(
      context, runtime_, SHAPEID_METHOD(DescribeCloud), CallGate::Kind::kUnary, raw_request,
      raw_response,
      [this](const v1::DescribeCloudRequest& request, v1::DescribeResponse* response,
             AdmittedCall& call) {
        return shapeid::DescribeCloud(runtime_, request, response, call);
      });
}

grpc::ServerUnaryReactor* ShapeIdService::ClassifyCloud(grpc::CallbackServerContext* context,
                                                        const grpc::ByteBuffer* raw_request,
                                                        grpc::ByteBuffer* raw_response) {
  return RunUnary<v1::ClassifyCloudRequest, v1::ClassifyResponse>(
      context, runtime_, SHAPEID_METHOD(ClassifyCloud), CallGate::Kind::kUnary, raw_request,
      raw_response,
      [this](const v1::ClassifyCloudRequest& request, v1::ClassifyResponse* response,
             AdmittedCall& call) {
        return shapeid::ClassifyCloud(runtime_, request, response, call);
      });
}

grpc::ServerUnaryReactor* ShapeIdService::RecognizeSceneCloud(grpc::CallbackServerContext* context,
                                                              const grpc::ByteBuffer* raw_request,
                                                              grpc::ByteBuffer* raw_response) {
  return RunUnary<v1::RecognizeSceneCloudRequest, v1::RecognizeSceneResponse>(
      context, runtime_, SHAPEID_METHOD(RecognizeSceneCloud), CallGate::Kind::kUnary, raw_request,
      raw_response,
      [this](const v1::RecognizeSceneCloudRequest& request, v1::RecognizeSceneResponse* response,
             AdmittedCall& call) {
        return shapeid::RecognizeSceneCloud(runtime_, request, response, call);
      });
}

grpc::ServerUnaryReactor* ShapeIdService::CreateGallery(grpc::CallbackServerContext* context,
                                                        const grpc::ByteBuffer* raw_request,
                                                        grpc::ByteBuffer* raw_response) {
  return RunUnary<v1::CreateGalleryRequest, v1::Gallery>(
      context, runtime_, SHAPEID_METHOD(CreateGallery), CallGate::Kind::kUnary, raw_request,
      raw_response,
      [this](const v1::CreateGalleryRequest& request, v1::Gallery* response,
             AdmittedCall& call) -> absl::StatusOr<Work> {
        call.record().gallery = request.name();
        SHAPEID_ASSIGN_OR_RETURN(const GalleryOptions options, GalleryOptionsFromProto(request));
        return Work::Store(kStoreWriteCost, [this, &request, response, options] {
          SHAPEID_ASSIGN_OR_RETURN(const std::shared_ptr<Gallery> gallery,
                                   registry_->Create(request.name(), options));
          ToProto(*gallery->Snapshot(), response);
          return absl::OkStatus();
        });
      });
}

grpc::ServerUnaryReactor* ShapeIdService::GetGallery(grpc::CallbackServerContext* context,
                                                     const grpc::ByteBuffer* raw_request,
                                                     grpc::ByteBuffer* raw_response) {
  return RunUnary<v1::GetGalleryRequest, v1::Gallery>(
      context, runtime_, SHAPEID_METHOD(GetGallery), CallGate::Kind::kUnary, raw_request,
      raw_response,
      [this](const v1::GetGalleryRequest& request, v1::Gallery* response,
             AdmittedCall& call) -> absl::Status {
        call.record().gallery = request.name();
        SHAPEID_RETURN_IF_ERROR(RequireGalleryName("GetGallery", request.name()));
        SHAPEID_ASSIGN_OR_RETURN(const std::shared_ptr<Gallery> gallery,
                                 registry_->Get(request.name()));
        ToProto(*gallery->Snapshot(), response);
        return absl::OkStatus();
      });
}

grpc::ServerUnaryReactor* ShapeIdService::ListGalleries(grpc::CallbackServerContext* context,
                                                        const grpc::ByteBuffer* raw_request,
                                                        grpc::ByteBuffer* raw_response) {
  return RunUnary<v1::ListGalleriesRequest, v1::ListGalleriesResponse>(
      context, runtime_, SHAPEID_METHOD(ListGalleries), CallGate::Kind::kUnary, raw_request,
      raw_response,
      [this](const v1::ListGalleriesRequest& /*request*/, v1::ListGalleriesResponse* response,
             AdmittedCall& /*call*/) -> absl::Status {
        for (const std::shared_ptr<Gallery>& gallery : registry_->All()) {
          ToProto(*gallery->Snapshot(), response->add_galleries());
        }
        return absl::OkStatus();
      });
}

grpc::ServerUnaryReactor* ShapeIdService::DeleteGallery(grpc::CallbackServerContext* context,
                                                        const grpc::ByteBuffer* raw_request,
                                                        grpc::ByteBuffer* raw_response) {
  return RunUnary<v1::DeleteGalleryRequest, v1::DeleteGalleryResponse>(
      context, runtime_, SHAPEID_METHOD(DeleteGallery), CallGate::Kind::kUnary, raw_request,
      raw_response,
      [this](const v1::DeleteGalleryRequest& request, v1::DeleteGalleryResponse* response,
             AdmittedCall& call) -> absl::StatusOr<Work> {
        call.record().gallery = request.name();
        SHAPEID_RETURN_IF_ERROR(RequireGalleryName("DeleteGallery", request.name()));
        SHAPEID_ASSIGN_OR_RETURN(const std::shared_ptr<Gallery> gallery,
                                 registry_->Get(request.name()));
        return Work::Store(kStoreWriteCost, [this, &request, response, &call, gallery] {
          const int64_t samples = gallery->Snapshot()->num_samples();
          SHAPEID_RETURN_IF_ERROR(registry_->Delete(request.name()));
          response->set_samples_deleted(static_cast<uint64_t>(samples));
          call.record().samples = samples;
          return absl::OkStatus();
        });
      });
}

grpc::ServerUnaryReactor* ShapeIdService::RemoveSamples(grpc::CallbackServerContext* context,
                                                        const grpc::ByteBuffer* raw_request,
                                                        grpc::ByteBuffer* raw_response) {
  return RunUnary<v1::RemoveSamplesRequest, v1::RemoveSamplesResponse>(
      context, runtime_, SHAPEID_METHOD(RemoveSamples), CallGate::Kind::kUnary, raw_request,
      raw_response,
      [this](const v1::RemoveSamplesRequest& request, v1::RemoveSamplesResponse* response,
             AdmittedCall& call) -> absl::StatusOr<Work> {
        call.record().gallery = request.gallery();
        SHAPEID_RETURN_IF_ERROR(RequireGalleryName("RemoveSamples", request.gallery()));
        SHAPEID_ASSIGN_OR_RETURN(const std::shared_ptr<Gallery> gallery,
                                 registry_->Get(request.gallery()));
        if (request.sample_ids().empty() && request.labels().empty()) {
          return absl::InvalidArgumentError("RemoveSamples: give sample_ids, labels or both");
        }
        const std::shared_ptr<const GallerySnapshot> snapshot = gallery->Snapshot();
        return Work::Store(EstimateRemove(*snapshot), [&request, response, &call, gallery] {
          const std::vector<std::string> labels(request.labels().begin(), request.labels().end());
          SHAPEID_ASSIGN_OR_RETURN(
              const int64_t removed,
              gallery->RemoveSamples(
                  absl::MakeConstSpan(request.sample_ids().data(), request.sample_ids().size()),
                  labels));
          response->set_removed(static_cast<uint64_t>(removed));
          call.record().samples = removed;
          response->set_remaining(static_cast<uint64_t>(gallery->Snapshot()->num_samples()));
          return absl::OkStatus();
        });
      });
}

namespace {

constexpr uint32_t kDefaultPageSize = 1000;
constexpr uint32_t kMaxPageSize = 10000;

// A ListSamples page token: the gallery's incarnation and the last id returned, so that a
// token from another gallery (or an earlier one of the same name) is refused, not misread.
std::string PageToken(uint64_t incarnation, uint64_t last_id) {
  return absl::StrCat(incarnation, ".", last_id);
}

// What a ListSamplesResponse holds besides its samples: the page token (two uint64s and a
// dot, 41 characters at most) and the gallery version, with their tags and lengths.
constexpr size_t kPageOverheadBytes = 64;

// `page`'s samples into `response`, in order, while the response stays within `max_bytes`
// (but at least one sample), and the token of the next page: after the last sample sent,
// whether the page was cut by its size in bytes or by its count.
void FillSamplePage(const SamplePage& page, uint64_t incarnation, size_t max_bytes,
                    v1::ListSamplesResponse* response) {
  size_t bytes = kPageOverheadBytes;
  bool cut = false;
  for (const SampleInfo& sample : page.samples) {
    v1::SampleInfo* out = response->add_samples();
    ToProto(sample, out);
    const size_t size = out->ByteSizeLong();
    // The repeated field's tag (one byte) and length, then the message.
    const size_t entry = 1 + google::protobuf::io::CodedOutputStream::VarintSize64(size) + size;
    if (response->samples_size() > 1 && bytes + entry > max_bytes) {
      response->mutable_samples()->RemoveLast();
      cut = true;
      break;
    }
    bytes += entry;
  }
  if (cut || page.more) {
    response->set_next_page_token(
        PageToken(incarnation, response->samples(response->samples_size() - 1).sample_id()));
  }
}

absl::StatusOr<uint64_t> LastIdOfToken(absl::string_view token, uint64_t incarnation) {
  const std::vector<absl::string_view> parts = absl::StrSplit(token, '.');
  uint64_t token_incarnation = 0, last_id = 0;
  if (parts.size() != 2 || !absl::SimpleAtoi(parts[0], &token_incarnation) ||
      !absl::SimpleAtoi(parts[1], &last_id) || token_incarnation != incarnation) {
    return absl::InvalidArgumentError(
        absl::StrCat("ListSamples: page_token \"", absl::CHexEscape(token.substr(0, 64)),
                     "\" was not given by this gallery; start again with an empty token"));
  }
  return last_id;
}

}  // namespace

grpc::ServerUnaryReactor* ShapeIdService::ListSamples(grpc::CallbackServerContext* context,
                                                      const grpc::ByteBuffer* raw_request,
                                                      grpc::ByteBuffer* raw_response) {
  return RunUnary<v1::ListSamplesRequest, v1::ListSamplesResponse>(
      context, runtime_, SHAPEID_METHOD(ListSamples), CallGate::Kind::kUnary, raw_request,
      raw_response,
      [this](const v1::ListSamplesRequest& request, v1::ListSamplesResponse* response,
             AdmittedCall& call) -> absl::StatusOr<Work> {
        call.record().gallery = request.gallery();
        SHAPEID_RETURN_IF_ERROR(RequireGalleryName("ListSamples", request.gallery()));
        if (request.page_size() > kMaxPageSize) {
          return absl::InvalidArgumentError(absl::StrCat(
              "ListSamples: page_size ", request.page_size(), " is over ", kMaxPageSize));
        }
        SHAPEID_ASSIGN_OR_RETURN(const std::shared_ptr<Gallery> gallery,
                                 registry_->Get(request.gallery()));
        std::shared_ptr<const GallerySnapshot> snapshot = gallery->Snapshot();
        uint64_t after = 0;
        if (!request.page_token().empty()) {
          SHAPEID_ASSIGN_OR_RETURN(after,
                                   LastIdOfToken(request.page_token(), snapshot->incarnation()));
        }
        // A scan of the gallery's ids: priced like a removal's pass over its rows.
        const absl::Duration cost = EstimateRemove(*snapshot);
        return Work::Compute(
            cost, 0,
            [&request, response, &call, after, snapshot = std::move(snapshot),
             max_bytes = options_.max_answer_bytes] {
              const uint32_t page_size =
                  request.page_size() == 0 ? kDefaultPageSize : request.page_size();
              const SamplePage page = snapshot->ListSamples(request.label(), after, page_size);
              FillSamplePage(page, snapshot->incarnation(), max_bytes, response);
              response->set_gallery_version(snapshot->version());
              call.record().samples = response->samples_size();
              // Cut to max_answer_bytes above, but for a single sample: held, never refused.
              return call.HoldMemory(2 * response->ByteSizeLong(), "the page");
            });
      });
}

grpc::ServerWriteReactor<v1::GalleryExportChunk>* ShapeIdService::ExportGallery(
    grpc::CallbackServerContext* context, const v1::ExportGalleryRequest* request) {
  return StartExport(context, runtime_, *request);
}

grpc::ServerReadReactor<grpc::ByteBuffer>* ShapeIdService::ImportGallery(
    grpc::CallbackServerContext* context, grpc::ByteBuffer* response) {
  return StartImport(context, runtime_, response);
}

grpc::ServerUnaryReactor* ShapeIdService::ListDescriptors(grpc::CallbackServerContext* context,
                                                          const grpc::ByteBuffer* raw_request,
                                                          grpc::ByteBuffer* raw_response) {
  return RunUnary<v1::ListDescriptorsRequest, v1::ListDescriptorsResponse>(
      context, runtime_, SHAPEID_METHOD(ListDescriptors), CallGate::Kind::kUnary, raw_request,
      raw_response,
      [](const v1::ListDescriptorsRequest& /*request*/, v1::ListDescriptorsResponse* response,
         AdmittedCall& /*call*/) { return ToProto(RegisteredDescriptors(), response); });
}

grpc::ServerUnaryReactor* ShapeIdService::GetServerStats(grpc::CallbackServerContext* context,
                                                         const grpc::ByteBuffer* raw_request,
                                                         grpc::ByteBuffer* raw_response) {
  return RunUnary<v1::GetServerStatsRequest, v1::ServerStats>(
      context, runtime_, SHAPEID_METHOD(GetServerStats), CallGate::Kind::kOperations, raw_request,
      raw_response,
      [this](const v1::GetServerStatsRequest& /*request*/, v1::ServerStats* response,
             AdmittedCall& /*call*/) {
        BuildServerStats({&description_, &gate_.tracker(), registry_.get(), &scheduler_,
                          budget_.get(), observer_.metrics(), observer_.logger()},
                         response);
        return absl::OkStatus();
      });
}

grpc::ServerUnaryReactor* ShapeIdService::SetLogLevel(grpc::CallbackServerContext* context,
                                                      const grpc::ByteBuffer* raw_request,
                                                      grpc::ByteBuffer* raw_response) {
  return RunUnary<v1::SetLogLevelRequest, v1::SetLogLevelResponse>(
      context, runtime_, SHAPEID_METHOD(SetLogLevel), CallGate::Kind::kOperations, raw_request,
      raw_response,
      [this](const v1::SetLogLevelRequest& request, v1::SetLogLevelResponse* response,
             AdmittedCall& call) -> absl::Status {
        SHAPEID_ASSIGN_OR_RETURN(const LogLevel level, ParseLogLevel(request.level()));
        Logger* logger = observer_.logger();
        if (logger == nullptr) {
          return absl::FailedPreconditionError("SetLogLevel: this service keeps no log");
        }
        const LogLevel previous = logger->SetLevel(level);
        // A warning, so that the change shows at every level but error.
        logger->Warning("log level changed", {{"from", LogLevelName(previous)},
                                              {"to", LogLevelName(level)},
                                              {"peer", call.record().peer},
                                              {"request_id", call.record().request_id}});
        response->set_previous_level(std::string(LogLevelName(previous)));
        response->set_level(std::string(LogLevelName(level)));
        return absl::OkStatus();
      });
}

}  // namespace shapeid
