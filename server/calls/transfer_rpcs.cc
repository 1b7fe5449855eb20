#include "server/calls/transfer_rpcs.h"

#include <memory>
#include <optional>
#include <string>
#include <utility>

#include "absl/strings/str_cat.h"
#include "absl/time/clock.h"
#include "core/gallery/gallery.h"
#include "core/gallery/gallery_registry.h"
#include "core/status_macros.h"
#include "server/calls/grpc_status.h"
#include "server/calls/stream_reactor.h"
#include "server/runtime/work_costs.h"
#include "server/wire/gallery_export.h"
#include "server/wire/proto_convert.h"

namespace shapeid {
namespace {

// Streams one snapshot of a gallery, one chunk in flight at a time (gRPC's flow control
// paces the writes), so memory stays at one chunk whatever the gallery's size. Past the
// server's ceiling the next write is not started: the call ends DEADLINE_EXCEEDED. A client
// that stops reading leaves a write pending for ever, which only cancelling ends: the
// ceiling's alarm does that a second later.
class ExportReactor final : public grpc::ServerWriteReactor<v1::GalleryExportChunk> {
 public:
  ExportReactor(grpc::CallbackServerContext* context, const ServiceRuntime& runtime,
                absl::string_view method, const v1::ExportGalleryRequest& request)
      : context_(context), call_(context, runtime, method, CallGate::Kind::kStream) {
    call_.record().gallery = request.name();
    if (!call_.admission().ok()) {
      End(ToGrpcStatus(call_.admission()));
      return;
    }
    if (const absl::Status started = Start(runtime, request.name()); !started.ok()) {
      End(ToGrpcStatus(started));
      return;
    }
    call_.ArmCeiling(absl::Seconds(1), [this] { context_->TryCancel(); });
    WriteNext();
  }

 private:
  absl::Status Start(const ServiceRuntime& runtime, const std::string& name) {
    SHAPEID_ASSIGN_OR_RETURN(const std::shared_ptr<Gallery> gallery,
                             NamedGallery(runtime, call_.record(), name));
    const std::shared_ptr<const GallerySnapshot> snapshot = gallery->Snapshot();
    call_.record().samples = snapshot->num_samples();
    exporter_ = std::make_unique<GalleryExporter>(snapshot);
    return absl::OkStatus();
  }

  void WriteNext() {
    if (!exporter_->Next(&chunk_)) {
      End(grpc::Status::OK);
    } else if (absl::Now() >= call_.cut_off()) {
      End(ToGrpcStatus(CeilingExceeded(call_.max_call())));
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

  void End(const grpc::Status& status) { Finish(call_.Conclude(status)); }

  void OnDone() override {
    call_.DisarmCeiling();
    delete this;
  }

  grpc::CallbackServerContext* const context_;
  AdmittedCall call_;
  std::unique_ptr<GalleryExporter> exporter_;
  v1::GalleryExportChunk chunk_;
};

class ImportReactor final : public StreamReactor<v1::ImportGalleryRequest, v1::Gallery> {
 public:
  ImportReactor(grpc::CallbackServerContext* context, const ServiceRuntime& runtime,
                absl::string_view method, grpc::ByteBuffer* response)
      : StreamReactor(context, runtime, method, response),
        registry_(*runtime.registry),
        assembler_(runtime.registry->limits().max_samples_per_gallery) {
    StartReading();
  }

 private:
  absl::StatusOr<std::optional<Work>> OnMessage(const v1::ImportGalleryRequest& request) override {
    if (messages_++ == 0) {
      name_ = request.name();
      call().record().gallery = name_;
      if (!request.has_chunk() && !name_.empty()) return std::nullopt;  // a name alone
    } else if (!request.name().empty() && request.name() != name_) {
      return absl::InvalidArgumentError(
          absl::StrCat("ImportGallery: message ", messages_ - 1, " names '", request.name(),
                       "'; the name is read from the first message only"));
    }
    // The assembled gallery holds about what the chunks carry.
    SHAPEID_RETURN_IF_ERROR(
        call().HoldMemory(request.chunk().samples().ByteSizeLong(), "the gallery being imported"));
    SHAPEID_RETURN_IF_ERROR(assembler_.Add(request.chunk()));
    if (request.chunk().has_header()) dimension_ = request.chunk().header().dimension();
    return std::nullopt;
  }

  absl::StatusOr<Work> OnEnd() override {
    const int64_t samples = assembler_.num_samples();
    return Work::Store(EstimateBuild(samples, dimension_), [this] {
      SHAPEID_ASSIGN_OR_RETURN(StoredGallery stored, assembler_.Finish());
      if (!name_.empty()) stored.name = name_;
      call().record().gallery = stored.name;
      call().record().samples = static_cast<int64_t>(stored.samples.size());
      SHAPEID_ASSIGN_OR_RETURN(const std::shared_ptr<Gallery> gallery,
                               registry_.Import(std::move(stored)));
      ToProto(*gallery->Snapshot(), response());
      return absl::OkStatus();
    });
  }

  GalleryRegistry& registry_;
  GalleryImportAssembler assembler_;
  std::string name_;
  int64_t messages_ = 0;
  int dimension_ = 0;
};

}  // namespace

grpc::ServerWriteReactor<v1::GalleryExportChunk>* ExportGalleryRpc::Start(
    grpc::CallbackServerContext* context, const ServiceRuntime& runtime, absl::string_view method,
    const v1::ExportGalleryRequest& request) {
  return new ExportReactor(context, runtime, method, request);
}

grpc::ServerReadReactor<grpc::ByteBuffer>* ImportGalleryRpc::Start(
    grpc::CallbackServerContext* context, const ServiceRuntime& runtime, absl::string_view method,
    grpc::ByteBuffer* response) {
  return new ImportReactor(context, runtime, method, response);
}

}  // namespace shapeid
