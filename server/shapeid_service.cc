#include "server/shapeid_service.h"

#include <algorithm>
#include <memory>
#include <optional>
#include <set>
#include <utility>
#include <vector>

#include "absl/strings/str_cat.h"
#include "absl/time/clock.h"
#include "absl/time/time.h"
#include "core/descriptor_registry.h"
#include "core/gallery/gallery.h"
#include "core/status_macros.h"
#include "core/version.h"
#include "server/call_gate.h"
#include "server/ceiling_alarm.h"
#include "server/cloud_assembler.h"
#include "server/gallery_export.h"
#include "server/grpc_status.h"
#include "server/process_stats.h"
#include "server/proto_convert.h"
#include "server/stream_reactor.h"

namespace shapeid {
namespace {

// Full method names, as the call gate's scope table (server/authorization.cc) knows them.
#define SHAPEID_METHOD(name) "/shapeid.v1.ShapeId/" #name

// Finishes a unary call of `method`: the call gate first (key and scope; UNAVAILABLE while
// loading or draining), then the request, parsed here because gRPC answers a request that
// does not parse with UNIMPLEMENTED, which clients read as "an older server"; here it is
// INVALID_ARGUMENT. Then `handler(request, &response, call)`, whose status ends the call; the
// handler fills in `call` (its gallery, points, samples), which the observer reports with
// that status.
template <typename Request, typename Response, CallGate::Kind kKind = CallGate::Kind::kUnary,
          typename Handler>
grpc::ServerUnaryReactor* Unary(grpc::CallbackServerContext* context, CallGate& gate,
                                const CallObserver& observer, absl::string_view method,
                                const grpc::ByteBuffer* raw_request,
                                grpc::ByteBuffer* raw_response, Handler handler) {
  grpc::ServerUnaryReactor* reactor = context->DefaultReactor();
  CallRecord call = observer.Start(*context, method);
  const auto finish = [&](const grpc::Status& status) {
    observer.Finish(call, status);
    reactor->Finish(status);
    return reactor;
  };
  absl::StatusOr<CallGate::Pass> pass = gate.Admit(*context, method, kKind);
  if (!pass.ok()) return finish(ToGrpcStatus(pass.status()));
  call.caller = std::string(pass->caller());
  Request request;
  grpc::ByteBuffer bytes(*raw_request);  // shares the received slices; parsing consumes it
  if (!grpc::SerializationTraits<Request>::Deserialize(&bytes, &request).ok()) {
    return finish(ToGrpcStatus(absl::InvalidArgumentError(absl::StrCat(
        call.method, ": the request is not a valid ", Request::descriptor()->full_name(),
        " (damaged, or from another protocol version)"))));
  }
  Response response;
  grpc::Status status = ToGrpcStatus(handler(request, &response, call));
  if (status.ok()) {
    bool own_buffer = false;
    status = grpc::SerializationTraits<Response>::Serialize(response, raw_response, &own_buffer);
  }
  return finish(status);
}

// Bytes of a PointChunk's xyz as points, for the call's report (a partial point counts
// nothing; the assembler refuses it).
int64_t PointsIn(const std::string& xyz) { return static_cast<int64_t>(xyz.size() / 12); }

absl::Status RequireGalleryName(absl::string_view rpc, const std::string& name) {
  if (name.empty())
    return absl::InvalidArgumentError(absl::StrCat(rpc, ": the gallery name is empty"));
  return absl::OkStatus();
}

// The descriptor a DescribeHeader asks for, shared by the stream and the one-message call:
// its spec, else the named gallery's, else the server's default.
absl::StatusOr<std::shared_ptr<const Descriptor>> DescriptorToUse(const v1::DescribeHeader& header,
                                                                  const ServiceOptions& options,
                                                                  const GalleryRegistry& registry) {
  if (header.descriptor_spec().empty() && !header.gallery().empty()) {
    SHAPEID_ASSIGN_OR_RETURN(const std::shared_ptr<Gallery> gallery,
                             registry.Get(header.gallery()));
    return gallery->Snapshot()->shared_descriptor();
  }
  const std::string& spec =
      header.descriptor_spec().empty() ? options.default_descriptor_spec : header.descriptor_spec();
  SHAPEID_ASSIGN_OR_RETURN(std::unique_ptr<Descriptor> descriptor, CreateDescriptor(spec));
  return std::shared_ptr<const Descriptor>(std::move(descriptor));
}

absl::Status DescribeInto(const Descriptor& descriptor, const PointCloud& cloud,
                          const CallObserver& observer, CallRecord& call,
                          v1::DescribeResponse* response) {
  const absl::Time start = absl::Now();
  std::vector<float> values;
  SHAPEID_RETURN_IF_ERROR(descriptor.Compute(cloud, &values));
  const absl::Duration elapsed = absl::Now() - start;
  observer.Described(call, descriptor.spec().kind, elapsed);
  ToProto(elapsed, response->mutable_describe_time());
  response->set_descriptor_spec(descriptor.spec().ToString());
  response->mutable_values()->Assign(values.begin(), values.end());
  response->set_num_points(cloud.size());
  return absl::OkStatus();
}

class DescribeReactor final : public StreamReactor<v1::DescribeRequest, v1::DescribeResponse> {
 public:
  DescribeReactor(grpc::CallbackServerContext* context, CallGate* gate,
                  const CallObserver* observer, const ServiceOptions& options,
                  const GalleryRegistry& registry, grpc::ByteBuffer* response)
      : StreamReactor(context, gate, observer, SHAPEID_METHOD(Describe), response),
        options_(options),
        registry_(registry),
        assembler_(options.max_points_per_cloud) {
    StartReading();
  }

 private:
  absl::Status OnMessage(const v1::DescribeRequest& request) override {
    switch (request.kind_case()) {
      case v1::DescribeRequest::kHeader:
        return OnHeader(request.header());
      case v1::DescribeRequest::kPoints:
        if (descriptor_ == nullptr) {
          return absl::InvalidArgumentError(
              "Describe: the first message must be a DescribeHeader; points came first");
        }
        call().points += PointsIn(request.points().xyz());
        return assembler_.Append(request.points().xyz());
      case v1::DescribeRequest::KIND_NOT_SET:
        break;
    }
    return absl::InvalidArgumentError("Describe: a message with neither header nor points");
  }

  absl::Status OnHeader(const v1::DescribeHeader& header) {
    if (descriptor_ != nullptr) {
      return absl::InvalidArgumentError("Describe: a second DescribeHeader in one stream");
    }
    if (header.descriptor_spec().empty()) call().gallery = header.gallery();  // else unused
    SHAPEID_ASSIGN_OR_RETURN(descriptor_, DescriptorToUse(header, options_, registry_));
    return assembler_.Start(header.expected_points());
  }

  absl::Status OnEnd() override {
    if (descriptor_ == nullptr) {
      return absl::InvalidArgumentError("Describe: the stream ended without a DescribeHeader");
    }
    SHAPEID_ASSIGN_OR_RETURN(const PointCloud cloud, assembler_.Finish());
    return DescribeInto(*descriptor_, cloud, observer(), call(), response());
  }

  const ServiceOptions& options_;
  const GalleryRegistry& registry_;
  CloudAssembler assembler_;
  std::shared_ptr<const Descriptor> descriptor_;
};

// One Train stream: TrainHeader, then samples (SampleHeader + PointChunks). Each sample is
// described as soon as its points are complete; the batch commits only when the stream ends
// OK, so an error or a cut stream (the reactor dies without OnEnd) publishes nothing.
class TrainReactor final : public StreamReactor<v1::TrainRequest, v1::TrainResponse> {
 public:
  TrainReactor(grpc::CallbackServerContext* context, CallGate* gate, const CallObserver* observer,
               const ServiceOptions& options, const GalleryRegistry& registry,
               grpc::ByteBuffer* response)
      : StreamReactor(context, gate, observer, SHAPEID_METHOD(Train), response),
        registry_(registry),
        max_samples_(options.max_samples_per_train),
        assembler_(options.max_points_per_cloud) {
    StartReading();
  }

 private:
  absl::Status OnMessage(const v1::TrainRequest& request) override {
    switch (request.kind_case()) {
      case v1::TrainRequest::kHeader: {
        if (batch_ != nullptr) return absl::InvalidArgumentError("Train: a second TrainHeader");
        call().gallery = request.header().gallery();
        SHAPEID_RETURN_IF_ERROR(RequireGalleryName("Train", request.header().gallery()));
        SHAPEID_ASSIGN_OR_RETURN(const std::shared_ptr<Gallery> gallery,
                                 registry_.Get(request.header().gallery()));
        batch_ = std::make_unique<TrainBatch>(gallery->NewBatch());
        batch_gallery_ = gallery;
        descriptor_kind_ = gallery->Snapshot()->shared_descriptor()->spec().kind;
        if (request.header().has_augmentation()) {
          SHAPEID_ASSIGN_OR_RETURN(const AugmentOptions augment,
                                   FromProto(request.header().augmentation()));
          SHAPEID_RETURN_IF_ERROR(batch_->SetAugment(augment));
        }
        return absl::OkStatus();
      }
      case v1::TrainRequest::kSample: {
        if (batch_ == nullptr) {
          return absl::InvalidArgumentError("Train: the first message must be a TrainHeader");
        }
        if (max_samples_ > 0 && sample_headers_ >= max_samples_) {
          return absl::ResourceExhaustedError(absl::StrCat(
              "Train: the stream carries more than ", max_samples_,
              " samples, the limit per stream (max_samples_per_train); send them in several "
              "streams"));
        }
        ++sample_headers_;
        SHAPEID_RETURN_IF_ERROR(FinishSample());
        sample_ = request.sample();
        return assembler_.Start(sample_.expected_points());
      }
      case v1::TrainRequest::kPoints:
        if (batch_ == nullptr) {
          return absl::InvalidArgumentError("Train: the first message must be a TrainHeader");
        }
        if (!assembler_.started()) {
          return absl::InvalidArgumentError(
              absl::StrCat("Train: points after sample ", samples_, " without a SampleHeader"));
        }
        call().points += PointsIn(request.points().xyz());
        return assembler_.Append(request.points().xyz());
      case v1::TrainRequest::KIND_NOT_SET:
        break;
    }
    return absl::InvalidArgumentError("Train: a message with no header, sample or points");
  }

  // Describes the sample whose points have all arrived, if any, into the batch.
  absl::Status FinishSample() {
    if (!assembler_.started()) return absl::OkStatus();
    auto cloud = assembler_.Finish();
    if (!cloud.ok()) {
      return absl::Status(cloud.status().code(),
                          absl::StrCat("sample ", samples_, ": ", cloud.status().message()));
    }
    const absl::Time start = absl::Now();
    SHAPEID_RETURN_IF_ERROR(batch_->AddSample(sample_.sample_id(), sample_.label(), *cloud));
    const absl::Duration elapsed = absl::Now() - start;
    observer().Described(call(), descriptor_kind_, elapsed);
    describe_time_ += elapsed;
    ++samples_;
    call().samples = samples_;
    return absl::OkStatus();
  }

  absl::Status OnEnd() override {
    if (batch_ == nullptr)
      return absl::InvalidArgumentError("Train: the stream ended without a TrainHeader");
    SHAPEID_RETURN_IF_ERROR(FinishSample());
    if (samples_ == 0) return absl::InvalidArgumentError("Train: the stream carried no sample");
    SHAPEID_ASSIGN_OR_RETURN(const CommitResult committed, batch_->Commit());
    response()->mutable_sample_ids()->Assign(committed.ids.begin(), committed.ids.end());
    response()->set_gallery_version(committed.version);
    response()->set_gallery_sample_count(
        static_cast<uint64_t>(batch_gallery_->Snapshot()->num_samples()));
    ToProto(describe_time_, response()->mutable_describe_time());
    return absl::OkStatus();
  }

  const GalleryRegistry& registry_;
  const int64_t max_samples_;
  CloudAssembler assembler_;
  std::unique_ptr<TrainBatch> batch_;
  std::shared_ptr<Gallery> batch_gallery_;
  v1::SampleHeader sample_;
  int64_t sample_headers_ = 0;
  int64_t samples_ = 0;
  absl::Duration describe_time_;
  std::string descriptor_kind_;
};

// Classify's checks on its header, shared by the stream and the one-message call: the
// gallery exists and has samples (failing before the points are read, not after).
absl::StatusOr<std::shared_ptr<Gallery>> GalleryToClassify(const GalleryRegistry& registry,
                                                           const v1::ClassifyHeader& header) {
  SHAPEID_RETURN_IF_ERROR(RequireGalleryName("Classify", header.gallery()));
  SHAPEID_ASSIGN_OR_RETURN(std::shared_ptr<Gallery> gallery, registry.Get(header.gallery()));
  if (gallery->Snapshot()->empty()) {
    return absl::FailedPreconditionError(absl::StrCat(
        "gallery '", gallery->name(), "' has no samples; train it before classifying"));
  }
  return gallery;
}

int NeighboursAsked(const v1::ClassifyHeader& header) {
  return static_cast<int>(std::min<uint32_t>(header.k(), 1 << 20));
}

absl::Status ClassifyInto(const Gallery& gallery, const PointCloud& cloud,
                          const v1::ClassifyHeader& header, const CallObserver& observer,
                          CallRecord& call, v1::ClassifyResponse* response) {
  const std::shared_ptr<const GallerySnapshot> snapshot = gallery.Snapshot();
  SHAPEID_ASSIGN_OR_RETURN(
      const GalleryClassification answer,
      snapshot->Classify(cloud, gallery.limits().cloud_limits(), NeighboursAsked(header),
                         header.exact() ? SearchMode::kExact : SearchMode::kDefault));
  observer.Described(call, snapshot->shared_descriptor()->spec().kind, answer.describe_time);
  observer.Searched(call, answer.knn.approximate, answer.search_time);
  ToProto(answer, cloud.size(), response);
  return absl::OkStatus();
}

class ClassifyReactor final : public StreamReactor<v1::ClassifyRequest, v1::ClassifyResponse> {
 public:
  ClassifyReactor(grpc::CallbackServerContext* context, CallGate* gate,
                  const CallObserver* observer, const ServiceOptions& options,
                  const GalleryRegistry& registry, grpc::ByteBuffer* response)
      : StreamReactor(context, gate, observer, SHAPEID_METHOD(Classify), response),
        registry_(registry),
        assembler_(options.max_points_per_cloud) {
    StartReading();
  }

 private:
  absl::Status OnMessage(const v1::ClassifyRequest& request) override {
    switch (request.kind_case()) {
      case v1::ClassifyRequest::kHeader: {
        if (gallery_ != nullptr)
          return absl::InvalidArgumentError("Classify: a second ClassifyHeader");
        call().gallery = request.header().gallery();
        SHAPEID_ASSIGN_OR_RETURN(gallery_, GalleryToClassify(registry_, request.header()));
        header_ = request.header();
        return assembler_.Start(request.header().expected_points());
      }
      case v1::ClassifyRequest::kPoints:
        if (gallery_ == nullptr) {
          return absl::InvalidArgumentError(
              "Classify: the first message must be a ClassifyHeader; points came first");
        }
        call().points += PointsIn(request.points().xyz());
        return assembler_.Append(request.points().xyz());
      case v1::ClassifyRequest::KIND_NOT_SET:
        break;
    }
    return absl::InvalidArgumentError("Classify: a message with neither header nor points");
  }

  absl::Status OnEnd() override {
    if (gallery_ == nullptr)
      return absl::InvalidArgumentError("Classify: the stream ended without a ClassifyHeader");
    SHAPEID_ASSIGN_OR_RETURN(const PointCloud cloud, assembler_.Finish());
    return ClassifyInto(*gallery_, cloud, header_, observer(), call(), response());
  }

  const GalleryRegistry& registry_;
  CloudAssembler assembler_;
  std::shared_ptr<Gallery> gallery_;
  v1::ClassifyHeader header_;
};

// Streams one snapshot of a gallery, one chunk in flight at a time (gRPC's flow control
// paces the writes), so memory stays at one chunk whatever the gallery's size. Past the
// server's ceiling (CallGate::CutOff) the next write is not started: the call ends
// DEADLINE_EXCEEDED. A client that stops reading leaves a write pending for ever, which only
// cancelling ends: the alarm does that a second after the ceiling.
class ExportReactor final : public grpc::ServerWriteReactor<v1::GalleryExportChunk> {
 public:
  ExportReactor(grpc::CallbackServerContext* context, CallGate* gate,
                const CallObserver* observer, const GalleryRegistry& registry,
                const v1::ExportGalleryRequest& request)
      : context_(context),
        observer_(observer),
        max_call_(gate->max_call()),
        call_(observer->Start(*context, SHAPEID_METHOD(ExportGallery))),
        pass_(gate->Admit(*context, SHAPEID_METHOD(ExportGallery), CallGate::Kind::kStream)) {
    call_.gallery = request.name();
    if (!pass_.ok()) {
      End(ToGrpcStatus(pass_.status()));
      return;
    }
    call_.caller = std::string(pass_->caller());
    const absl::Status started = Start(registry, request.name());
    if (!started.ok()) {
      End(ToGrpcStatus(started));
      return;
    }
    if (const std::optional<absl::Time> cut = gate->CutOff(*context)) {
      cut_at_ = *cut;
      ceiling_.Arm(*cut + absl::Seconds(1), [this] { context_->TryCancel(); });
    }
    WriteNext();
  }

 private:
  absl::Status Start(const GalleryRegistry& registry, const std::string& name) {
    SHAPEID_RETURN_IF_ERROR(RequireGalleryName("ExportGallery", name));
    SHAPEID_ASSIGN_OR_RETURN(const std::shared_ptr<Gallery> gallery, registry.Get(name));
    const std::shared_ptr<const GallerySnapshot> snapshot = gallery->Snapshot();
    call_.samples = snapshot->num_samples();
    exporter_ = std::make_unique<GalleryExporter>(snapshot);
    return absl::OkStatus();
  }

  void WriteNext() {
    if (!exporter_->Next(&chunk_)) {
      End(grpc::Status::OK);
    } else if (absl::Now() >= cut_at_) {
      End(ToGrpcStatus(CeilingExceeded(max_call_)));
    } else {
      StartWrite(&chunk_);
    }
  }

  void OnWriteDone(bool ok) override {
    if (!ok) {  // cancelled, past its deadline, or the client went away: stop streaming
      End(grpc::Status(grpc::StatusCode::CANCELLED, "the export was cancelled"));
      return;
    }
    WriteNext();
  }

  // Finish, with the client's stream slot freed first (CallGate::Pass::ReleaseSlot).
  void End(const grpc::Status& status) {
    if (pass_.ok()) pass_->ReleaseSlot();
    observer_->Finish(call_, status);
    Finish(status);
  }

  void OnDone() override {
    ceiling_.Disarm();
    delete this;
  }

  grpc::CallbackServerContext* const context_;
  const CallObserver* const observer_;
  const absl::Duration max_call_;
  CallRecord call_;  // before pass_: a refused call is reported too
  absl::StatusOr<CallGate::Pass> pass_;
  absl::Time cut_at_ = absl::InfiniteFuture();
  CeilingAlarm ceiling_;
  std::unique_ptr<GalleryExporter> exporter_;
  v1::GalleryExportChunk chunk_;
};

// ImportGallery: the chunks go into a GalleryImportAssembler as they arrive, so a malformed
// export fails at its first bad chunk; the registry sees the gallery only when the stream
// ends complete and undamaged.
class ImportReactor final : public StreamReactor<v1::ImportGalleryRequest, v1::Gallery> {
 public:
  ImportReactor(grpc::CallbackServerContext* context, CallGate* gate, const CallObserver* observer,
                GalleryRegistry& registry, grpc::ByteBuffer* response)
      : StreamReactor(context, gate, observer, SHAPEID_METHOD(ImportGallery), response),
        registry_(registry),
        assembler_(registry.limits().max_samples_per_gallery) {
    StartReading();
  }

 private:
  absl::Status OnMessage(const v1::ImportGalleryRequest& request) override {
    if (messages_++ == 0) {
      name_ = request.name();
      call().gallery = name_;
      if (!request.has_chunk() && !name_.empty()) return absl::OkStatus();  // a name alone
    } else if (!request.name().empty() && request.name() != name_) {
      return absl::InvalidArgumentError(
          absl::StrCat("ImportGallery: message ", messages_ - 1, " names '", request.name(),
                       "'; the name is read from the first message only"));
    }
    return assembler_.Add(request.chunk());
  }

  absl::Status OnEnd() override {
    SHAPEID_ASSIGN_OR_RETURN(StoredGallery stored, assembler_.Finish());
    if (!name_.empty()) stored.name = name_;
    call().gallery = stored.name;
    call().samples = static_cast<int64_t>(stored.samples.size());
    SHAPEID_ASSIGN_OR_RETURN(const std::shared_ptr<Gallery> gallery, registry_.Import(std::move(stored)));
    ToProto(*gallery->Snapshot(), response());
    return absl::OkStatus();
  }

  GalleryRegistry& registry_;
  GalleryImportAssembler assembler_;
  std::string name_;
  int64_t messages_ = 0;
};

}  // namespace

grpc::ServerReadReactor<grpc::ByteBuffer>* ShapeIdService::Describe(
    grpc::CallbackServerContext* context, grpc::ByteBuffer* response) {
  return new DescribeReactor(context, &gate_, &observer_, options_, *registry_, response);
}

grpc::ServerReadReactor<grpc::ByteBuffer>* ShapeIdService::Train(
    grpc::CallbackServerContext* context, grpc::ByteBuffer* response) {
  return new TrainReactor(context, &gate_, &observer_, options_, *registry_, response);
}

grpc::ServerReadReactor<grpc::ByteBuffer>* ShapeIdService::Classify(
    grpc::CallbackServerContext* context, grpc::ByteBuffer* response) {
  return new ClassifyReactor(context, &gate_, &observer_, options_, *registry_, response);
}

absl::StatusOr<PointCloud> ShapeIdService::CloudInOneMessage(uint64_t expected_points,
                                                             absl::string_view xyz) const {
  // The streams' assembler with a single chunk: the same checks and the same messages.
  CloudAssembler assembler(options_.max_points_per_cloud);
  SHAPEID_RETURN_IF_ERROR(assembler.Start(expected_points));
  SHAPEID_RETURN_IF_ERROR(assembler.Append(xyz));
  return assembler.Finish();
}

grpc::ServerUnaryReactor* ShapeIdService::DescribeCloud(grpc::CallbackServerContext* context,
                                                        const grpc::ByteBuffer* raw_request,
                                                        grpc::ByteBuffer* raw_response) {
  return Unary<v1::DescribeCloudRequest, v1::DescribeResponse>(
      context, gate_, observer_, SHAPEID_METHOD(DescribeCloud), raw_request, raw_response,
      [&](const v1::DescribeCloudRequest& request, v1::DescribeResponse* response,
          CallRecord& call) -> absl::Status {
        if (request.header().descriptor_spec().empty()) call.gallery = request.header().gallery();
        call.points = PointsIn(request.points().xyz());
        SHAPEID_ASSIGN_OR_RETURN(const std::shared_ptr<const Descriptor> descriptor,
                                 DescriptorToUse(request.header(), options_, *registry_));
        SHAPEID_ASSIGN_OR_RETURN(
            const PointCloud cloud,
            CloudInOneMessage(request.header().expected_points(), request.points().xyz()));
        return DescribeInto(*descriptor, cloud, observer_, call, response);
      });
}

grpc::ServerUnaryReactor* ShapeIdService::ClassifyCloud(grpc::CallbackServerContext* context,
                                                        const grpc::ByteBuffer* raw_request,
                                                        grpc::ByteBuffer* raw_response) {
  return Unary<v1::ClassifyCloudRequest, v1::ClassifyResponse>(
      context, gate_, observer_, SHAPEID_METHOD(ClassifyCloud), raw_request, raw_response,
      [&](const v1::ClassifyCloudRequest& request, v1::ClassifyResponse* response,
          CallRecord& call) -> absl::Status {
        call.gallery = request.header().gallery();
        call.points = PointsIn(request.points().xyz());
        if (!request.has_header()) {
          return absl::InvalidArgumentError("ClassifyCloud: the request has no header");
        }
        SHAPEID_ASSIGN_OR_RETURN(const std::shared_ptr<Gallery> gallery,
                                 GalleryToClassify(*registry_, request.header()));
        SHAPEID_ASSIGN_OR_RETURN(
            const PointCloud cloud,
            CloudInOneMessage(request.header().expected_points(), request.points().xyz()));
        return ClassifyInto(*gallery, cloud, request.header(), observer_, call, response);
      });
}

grpc::ServerUnaryReactor* ShapeIdService::CreateGallery(grpc::CallbackServerContext* context,
                                                        const grpc::ByteBuffer* raw_request,
                                                        grpc::ByteBuffer* raw_response) {
  return Unary<v1::CreateGalleryRequest, v1::Gallery>(
      context, gate_, observer_, SHAPEID_METHOD(CreateGallery), raw_request, raw_response,
      [&](const v1::CreateGalleryRequest& request, v1::Gallery* response,
          CallRecord& call) -> absl::Status {
        call.gallery = request.name();
        SHAPEID_ASSIGN_OR_RETURN(const GalleryOptions options, GalleryOptionsFromProto(request));
        SHAPEID_ASSIGN_OR_RETURN(const std::shared_ptr<Gallery> gallery,
                                 registry_->Create(request.name(), options));
        ToProto(*gallery->Snapshot(), response);
        return absl::OkStatus();
      });
}

grpc::ServerUnaryReactor* ShapeIdService::GetGallery(grpc::CallbackServerContext* context,
                                                     const grpc::ByteBuffer* raw_request,
                                                     grpc::ByteBuffer* raw_response) {
  return Unary<v1::GetGalleryRequest, v1::Gallery>(
      context, gate_, observer_, SHAPEID_METHOD(GetGallery), raw_request, raw_response,
      [&](const v1::GetGalleryRequest& request, v1::Gallery* response,
          CallRecord& call) -> absl::Status {
        call.gallery = request.name();
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
  return Unary<v1::ListGalleriesRequest, v1::ListGalleriesResponse>(
      context, gate_, observer_, SHAPEID_METHOD(ListGalleries), raw_request, raw_response,
      [&](const v1::ListGalleriesRequest& /*request*/, v1::ListGalleriesResponse* response,
          CallRecord& /*call*/) -> absl::Status {
        for (const std::shared_ptr<Gallery>& gallery : registry_->All()) {
          ToProto(*gallery->Snapshot(), response->add_galleries());
        }
        return absl::OkStatus();
      });
}

grpc::ServerUnaryReactor* ShapeIdService::DeleteGallery(grpc::CallbackServerContext* context,
                                                        const grpc::ByteBuffer* raw_request,
                                                        grpc::ByteBuffer* raw_response) {
  return Unary<v1::DeleteGalleryRequest, v1::DeleteGalleryResponse>(
      context, gate_, observer_, SHAPEID_METHOD(DeleteGallery), raw_request, raw_response,
      [&](const v1::DeleteGalleryRequest& request, v1::DeleteGalleryResponse* response,
          CallRecord& call) -> absl::Status {
        call.gallery = request.name();
        SHAPEID_RETURN_IF_ERROR(RequireGalleryName("DeleteGallery", request.name()));
        SHAPEID_ASSIGN_OR_RETURN(const std::shared_ptr<Gallery> gallery,
                                 registry_->Get(request.name()));
        const int64_t samples = gallery->Snapshot()->num_samples();
        SHAPEID_RETURN_IF_ERROR(registry_->Delete(request.name()));
        response->set_samples_deleted(static_cast<uint64_t>(samples));
        call.samples = samples;
        return absl::OkStatus();
      });
}

grpc::ServerUnaryReactor* ShapeIdService::RemoveSamples(grpc::CallbackServerContext* context,
                                                        const grpc::ByteBuffer* raw_request,
                                                        grpc::ByteBuffer* raw_response) {
  return Unary<v1::RemoveSamplesRequest, v1::RemoveSamplesResponse>(
      context, gate_, observer_, SHAPEID_METHOD(RemoveSamples), raw_request, raw_response,
      [&](const v1::RemoveSamplesRequest& request, v1::RemoveSamplesResponse* response,
          CallRecord& call) -> absl::Status {
        call.gallery = request.gallery();
        SHAPEID_RETURN_IF_ERROR(RequireGalleryName("RemoveSamples", request.gallery()));
        SHAPEID_ASSIGN_OR_RETURN(const std::shared_ptr<Gallery> gallery,
                                 registry_->Get(request.gallery()));
        if (request.sample_ids().empty() && request.labels().empty()) {
          return absl::InvalidArgumentError("RemoveSamples: give sample_ids, labels or both");
        }
        // One removal of the union, so the call is all-or-nothing. Labels are resolved against
        // the gallery as it is now; a label with no samples is NOT_FOUND.
        std::set<uint64_t> ids(request.sample_ids().begin(), request.sample_ids().end());
        const auto snapshot = gallery->Snapshot();
        for (const std::string& label : request.labels()) {
          const std::vector<uint64_t> labelled = snapshot->IdsWithLabel(label);
          if (labelled.empty()) {
            return absl::NotFoundError(absl::StrCat("gallery '", gallery->name(),
                                                    "' has no samples labelled '", label, "'"));
          }
          ids.insert(labelled.begin(), labelled.end());
        }
        const std::vector<uint64_t> all(ids.begin(), ids.end());
        SHAPEID_ASSIGN_OR_RETURN(const int64_t removed, gallery->RemoveSamples(all));
        response->set_removed(static_cast<uint64_t>(removed));
        call.samples = removed;
        response->set_remaining(static_cast<uint64_t>(gallery->Snapshot()->num_samples()));
        return absl::OkStatus();
      });
}

grpc::ServerWriteReactor<v1::GalleryExportChunk>* ShapeIdService::ExportGallery(
    grpc::CallbackServerContext* context, const v1::ExportGalleryRequest* request) {
  return new ExportReactor(context, &gate_, &observer_, *registry_, *request);
}

grpc::ServerReadReactor<grpc::ByteBuffer>* ShapeIdService::ImportGallery(
    grpc::CallbackServerContext* context, grpc::ByteBuffer* response) {
  return new ImportReactor(context, &gate_, &observer_, *registry_, response);
}

grpc::ServerUnaryReactor* ShapeIdService::ListDescriptors(grpc::CallbackServerContext* context,
                                                          const grpc::ByteBuffer* raw_request,
                                                          grpc::ByteBuffer* raw_response) {
  return Unary<v1::ListDescriptorsRequest, v1::ListDescriptorsResponse>(
      context, gate_, observer_, SHAPEID_METHOD(ListDescriptors), raw_request, raw_response,
      [&](const v1::ListDescriptorsRequest& /*request*/, v1::ListDescriptorsResponse* response,
          CallRecord& /*call*/) -> absl::Status {
        for (const DescriptorKind& kind : RegisteredDescriptors()) {
          v1::DescriptorKind* out = response->add_descriptors();
          out->set_kind(kind.kind);
          out->set_summary(kind.summary);
          for (const DescriptorParam& p : kind.params) {
            v1::DescriptorParameter* param = out->add_parameters();
            param->set_name(p.name);
            param->set_default_value(p.default_value);
            param->set_help(p.help);
          }
          SHAPEID_ASSIGN_OR_RETURN(const std::unique_ptr<Descriptor> defaults,
                                   CreateDescriptor(kind.kind));
          out->set_default_spec(defaults->spec().ToString());
          out->set_default_dimension(static_cast<uint32_t>(defaults->dimension()));
        }
        return absl::OkStatus();
      });
}

grpc::ServerUnaryReactor* ShapeIdService::GetServerStats(grpc::CallbackServerContext* context,
                                                         const grpc::ByteBuffer* raw_request,
                                                         grpc::ByteBuffer* raw_response) {
  return Unary<v1::GetServerStatsRequest, v1::ServerStats, CallGate::Kind::kOperations>(
      context, gate_, observer_, SHAPEID_METHOD(GetServerStats), raw_request, raw_response,
      [&](const v1::GetServerStatsRequest& /*request*/, v1::ServerStats* response,
          CallRecord& /*call*/) -> absl::Status {
        response->set_version(kShapeidVersion);
        ToProto(absl::Now() - description_.started, response->mutable_uptime());
        response->set_state(CallTracker::StateName(gate_.tracker().state()));
        // Not counting this call itself.
        response->set_calls_in_flight(std::max<int64_t>(0, gate_.tracker().in_flight() - 1));
        if (const ServerMetrics* metrics = observer_.metrics()) {
          for (const MethodSummary& summary : metrics->MethodSummaries()) {
            v1::MethodStats* method = response->add_methods();
            method->set_method(summary.method);
            method->set_calls(summary.calls);
            method->set_errors(summary.errors);
            if (summary.p50) ToProto(*summary.p50, method->mutable_latency_p50());
            if (summary.p99) ToProto(*summary.p99, method->mutable_latency_p99());
          }
          response->set_points_received(metrics->points_received());
        }
        std::vector<v1::GalleryStats> galleries;
        uint64_t samples = 0;
        for (const std::shared_ptr<Gallery>& gallery : registry_->All()) {
          const std::shared_ptr<const GallerySnapshot> snapshot = gallery->Snapshot();
          v1::GalleryStats& stats = galleries.emplace_back();
          stats.set_name(gallery->name());
          stats.set_samples(static_cast<uint64_t>(snapshot->num_samples()));
          stats.set_version(snapshot->version());
          samples += stats.samples();
        }
        std::stable_sort(galleries.begin(), galleries.end(),
                         [](const v1::GalleryStats& a, const v1::GalleryStats& b) {
                           return a.samples() > b.samples();
                         });
        for (v1::GalleryStats& stats : galleries) *response->add_galleries() = std::move(stats);
        response->set_samples(samples);
        if (const absl::StatusOr<ProcessStats> process = ReadProcessStats(); process.ok()) {
          response->set_resident_memory_bytes(static_cast<uint64_t>(process->resident_bytes));
        }
        response->set_store(description_.store.empty() ? "memory" : description_.store);
        if (const Logger* logger = observer_.logger()) {
          response->set_log_level(std::string(LogLevelName(logger->level())));
        }
        response->set_metrics_address(description_.metrics_address);
        return absl::OkStatus();
      });
}

grpc::ServerUnaryReactor* ShapeIdService::SetLogLevel(grpc::CallbackServerContext* context,
                                                      const grpc::ByteBuffer* raw_request,
                                                      grpc::ByteBuffer* raw_response) {
  return Unary<v1::SetLogLevelRequest, v1::SetLogLevelResponse, CallGate::Kind::kOperations>(
      context, gate_, observer_, SHAPEID_METHOD(SetLogLevel), raw_request, raw_response,
      [&](const v1::SetLogLevelRequest& request, v1::SetLogLevelResponse* response,
          CallRecord& call) -> absl::Status {
        SHAPEID_ASSIGN_OR_RETURN(const LogLevel level, ParseLogLevel(request.level()));
        Logger* logger = observer_.logger();
        if (logger == nullptr) {
          return absl::FailedPreconditionError("SetLogLevel: this service keeps no log");
        }
        const LogLevel previous = logger->SetLevel(level);
        // A warning, so that the change shows at every level but error.
        logger->Warning("log level changed", {{"from", LogLevelName(previous)},
                                              {"to", LogLevelName(level)},
                                              {"peer", call.peer},
                                              {"request_id", call.request_id}});
        response->set_previous_level(std::string(LogLevelName(previous)));
        response->set_level(std::string(LogLevelName(level)));
        return absl::OkStatus();
      });
}

}  // namespace shapeid
