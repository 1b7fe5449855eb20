#ifndef SHAPEID_SERVER_SHAPEID_SERVICE_H_
#define SHAPEID_SERVER_SHAPEID_SERVICE_H_

#include <memory>
#include <utility>

#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "core/gallery/gallery_registry.h"
#include "core/point_cloud.h"
#include "server/api_keys.h"
#include "server/call_gate.h"
#include "server/call_observer.h"
#include "server/service_options.h"
#include "server/stream_reactor.h"
#include "shapeid/v1/shapeid.grpc.pb.h"

namespace shapeid {

// The methods that take requests are registered raw (their messages arrive as bytes and are
// parsed by the service): gRPC reports a streamed message that does not parse as the end of
// the stream, and a unary request that does not parse as UNIMPLEMENTED; shapeid answers both
// INVALID_ARGUMENT and keeps nothing of the call. ExportGallery stays typed (its request is a
// name).
using ShapeIdRawService =
    v1::ShapeId::WithRawCallbackMethod_Describe<v1::ShapeId::WithRawCallbackMethod_DescribeCloud<
        v1::ShapeId::WithRawCallbackMethod_Train<v1::ShapeId::WithRawCallbackMethod_Classify<
            v1::ShapeId::WithRawCallbackMethod_ClassifyCloud<
                v1::ShapeId::WithRawCallbackMethod_CreateGallery<
                    v1::ShapeId::WithRawCallbackMethod_GetGallery<
                        v1::ShapeId::WithRawCallbackMethod_ListGalleries<
                            v1::ShapeId::WithRawCallbackMethod_DeleteGallery<
                                v1::ShapeId::WithRawCallbackMethod_RemoveSamples<
                                    v1::ShapeId::WithRawCallbackMethod_ImportGallery<
                                        v1::ShapeId::WithRawCallbackMethod_ListDescriptors<
                                            v1::ShapeId::WithRawCallbackMethod_GetServerStats<
                                                v1::ShapeId::WithRawCallbackMethod_SetLogLevel<
                                                    v1::ShapeId::CallbackService>>>>>>>>>>>>>>;

// The gRPC edge of shapeid: each method turns its messages into calls on core/ (descriptors,
// the gallery registry) and the result into one status through ToGrpcStatus
// (server/grpc_status.h). All state lives in the registry; thread-safe.
//
// The streaming methods do their CPU work (describing a cloud) on gRPC's callback threads
// when the stream ends; a 100,000-point cloud costs about 2 ms there.
//
// Every call passes the call gate first (server/call_gate.h): with `keys` non-empty, its API
// key must cover the method's scope (server/authorization.h); streams are counted per client
// and ended at the ceiling of `options`. Every call, admitted or not, is reported once to the
// observer when it is answered: a log line and the metrics (server/call_observer.h).
class ShapeIdService final : public ShapeIdRawService {
 public:
  ShapeIdService(ServiceOptions options, std::shared_ptr<GalleryRegistry> registry,
                 std::shared_ptr<const ApiKeyStore> keys = nullptr, CallObserver observer = {})
      : options_(std::move(options)),
        registry_(std::move(registry)),
        gate_(std::move(keys), options_.max_streams_per_client, options_.max_call),
        observer_(std::move(observer)) {}

  // What GetServerStats reports about the server around the service; set once, before
  // serving.
  struct ServerDescription {
    std::string store;            // "shapeid-data", "PostgreSQL db:5432/shapeid (shared)"
    std::string metrics_address;  // empty: no endpoint
    absl::Time started = absl::Now();
  };
  void SetDescription(ServerDescription description) { description_ = std::move(description); }

  // Client streams: messages v1::DescribeRequest, TrainRequest, ClassifyRequest; answers
  // v1::DescribeResponse, TrainResponse, ClassifyResponse.
  grpc::ServerReadReactor<grpc::ByteBuffer>* Describe(grpc::CallbackServerContext* context,
                                                      grpc::ByteBuffer* response) override;
  grpc::ServerReadReactor<grpc::ByteBuffer>* Train(grpc::CallbackServerContext* context,
                                                   grpc::ByteBuffer* response) override;
  grpc::ServerReadReactor<grpc::ByteBuffer>* Classify(grpc::CallbackServerContext* context,
                                                      grpc::ByteBuffer* response) override;
  // Unary calls: the request and response types of the proto, as bytes.
  grpc::ServerUnaryReactor* DescribeCloud(grpc::CallbackServerContext* context,
                                          const grpc::ByteBuffer* raw_request,
                                          grpc::ByteBuffer* raw_response) override;
  grpc::ServerUnaryReactor* ClassifyCloud(grpc::CallbackServerContext* context,
                                          const grpc::ByteBuffer* raw_request,
                                          grpc::ByteBuffer* raw_response) override;

  grpc::ServerUnaryReactor* CreateGallery(grpc::CallbackServerContext* context,
                                          const grpc::ByteBuffer* raw_request,
                                          grpc::ByteBuffer* raw_response) override;
  grpc::ServerUnaryReactor* GetGallery(grpc::CallbackServerContext* context,
                                       const grpc::ByteBuffer* raw_request,
                                       grpc::ByteBuffer* raw_response) override;
  grpc::ServerUnaryReactor* ListGalleries(grpc::CallbackServerContext* context,
                                          const grpc::ByteBuffer* raw_request,
                                          grpc::ByteBuffer* raw_response) override;
  grpc::ServerUnaryReactor* DeleteGallery(grpc::CallbackServerContext* context,
                                          const grpc::ByteBuffer* raw_request,
                                          grpc::ByteBuffer* raw_response) override;
  grpc::ServerUnaryReactor* RemoveSamples(grpc::CallbackServerContext* context,
                                          const grpc::ByteBuffer* raw_request,
                                          grpc::ByteBuffer* raw_response) override;
  // Streams one snapshot of the gallery (server/gallery_export.h), so training during the
  // export does not tear it; stops at the first failed write (client gone, deadline).
  grpc::ServerWriteReactor<v1::GalleryExportChunk>* ExportGallery(
      grpc::CallbackServerContext* context, const v1::ExportGalleryRequest* request) override;
  // Assembles and checks the export as it arrives (the first error ends the call), then
  // GalleryRegistry::Import: all-or-nothing. Messages v1::ImportGalleryRequest; answer
  // v1::Gallery.
  grpc::ServerReadReactor<grpc::ByteBuffer>* ImportGallery(grpc::CallbackServerContext* context,
                                                           grpc::ByteBuffer* response) override;

  grpc::ServerUnaryReactor* ListDescriptors(grpc::CallbackServerContext* context,
                                            const grpc::ByteBuffer* raw_request,
                                            grpc::ByteBuffer* raw_response) override;

  // Operations (docs/operations.md): v1::ServerStats from the metrics, the registry and the
  // call gate; SetLogLevel changes the observer's logger (INVALID_ARGUMENT for an unknown
  // level; FAILED_PRECONDITION for a service without a logger).
  grpc::ServerUnaryReactor* GetServerStats(grpc::CallbackServerContext* context,
                                           const grpc::ByteBuffer* raw_request,
                                           grpc::ByteBuffer* raw_response) override;
  grpc::ServerUnaryReactor* SetLogLevel(grpc::CallbackServerContext* context,
                                        const grpc::ByteBuffer* raw_request,
                                        grpc::ByteBuffer* raw_response) override;

  // Refuses every call with UNAVAILABLE "loading" until StartServing (a new service serves
  // at once; the server holds it while it loads galleries from the store).
  void HoldUntilLoaded() { gate_.tracker().SetState(CallTracker::State::kLoading); }
  void StartServing() { gate_.tracker().SetState(CallTracker::State::kServing); }
  // A replica over a shared store: refuse every call while the store is unreachable.
  void SetStoreReachable(bool reachable) {
    gate_.tracker().SetState(reachable ? CallTracker::State::kServing
                                       : CallTracker::State::kStoreUnreachable);
  }
  // Refuses new calls (UNAVAILABLE) from now on; calls already running continue.
  void StartDraining() { gate_.tracker().StartDraining(); }
  int64_t calls_in_flight() const { return gate_.tracker().in_flight(); }
  bool serving() const { return gate_.tracker().state() == CallTracker::State::kServing; }

 private:
  // The cloud of a DescribeCloud or ClassifyCloud request, checked as a stream's would be.
  absl::StatusOr<PointCloud> CloudInOneMessage(uint64_t expected_points,
                                               absl::string_view xyz) const;

  const ServiceOptions options_;
  const std::shared_ptr<GalleryRegistry> registry_;
  CallGate gate_;
  const CallObserver observer_;
  ServerDescription description_;
};

}  // namespace shapeid

#endif  // SHAPEID_SERVER_SHAPEID_SERVICE_H_
