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
#include "server/service_options.h"
#include "server/stream_reactor.h"
#include "shapeid/v1/shapeid.grpc.pb.h"

namespace shapeid {

// The gRPC edge of shapeid: each method turns its messages into calls on core/ (descriptors,
// the gallery registry) and the result into one status through ToGrpcStatus
// (server/grpc_status.h). All state lives in the registry; thread-safe.
//
// The streaming methods do their CPU work (describing a cloud) on gRPC's callback threads
// when the stream ends; a 100,000-point cloud costs about 2 ms there.
//
// Every call passes the call gate first (server/call_gate.h): with `keys` non-empty, its API
// key must cover the method's scope (server/authorization.h); streams are counted per client
// and ended at the ceiling of `options`.
class ShapeIdService final : public v1::ShapeId::CallbackService {
 public:
  ShapeIdService(ServiceOptions options, std::shared_ptr<GalleryRegistry> registry,
                 std::shared_ptr<const ApiKeyStore> keys = nullptr)
      : options_(std::move(options)),
        registry_(std::move(registry)),
        gate_(std::move(keys), options_.max_streams_per_client, options_.max_call) {}

  grpc::ServerReadReactor<v1::DescribeRequest>* Describe(grpc::CallbackServerContext* context,
                                                         v1::DescribeResponse* response) override;
  grpc::ServerReadReactor<v1::TrainRequest>* Train(grpc::CallbackServerContext* context,
                                                   v1::TrainResponse* response) override;
  grpc::ServerReadReactor<v1::ClassifyRequest>* Classify(grpc::CallbackServerContext* context,
                                                         v1::ClassifyResponse* response) override;
  grpc::ServerUnaryReactor* DescribeCloud(grpc::CallbackServerContext* context,
                                          const v1::DescribeCloudRequest* request,
                                          v1::DescribeResponse* response) override;
  grpc::ServerUnaryReactor* ClassifyCloud(grpc::CallbackServerContext* context,
                                          const v1::ClassifyCloudRequest* request,
                                          v1::ClassifyResponse* response) override;

  grpc::ServerUnaryReactor* CreateGallery(grpc::CallbackServerContext* context,
                                          const v1::CreateGalleryRequest* request,
                                          v1::Gallery* response) override;
  grpc::ServerUnaryReactor* GetGallery(grpc::CallbackServerContext* context,
                                       const v1::GetGalleryRequest* request,
                                       v1::Gallery* response) override;
  grpc::ServerUnaryReactor* ListGalleries(grpc::CallbackServerContext* context,
                                          const v1::ListGalleriesRequest* request,
                                          v1::ListGalleriesResponse* response) override;
  grpc::ServerUnaryReactor* DeleteGallery(grpc::CallbackServerContext* context,
                                          const v1::DeleteGalleryRequest* request,
                                          v1::DeleteGalleryResponse* response) override;
  grpc::ServerUnaryReactor* RemoveSamples(grpc::CallbackServerContext* context,
                                          const v1::RemoveSamplesRequest* request,
                                          v1::RemoveSamplesResponse* response) override;
  // Streams one snapshot of the gallery (server/gallery_export.h), so training during the
  // export does not tear it; stops at the first failed write (client gone, deadline).
  grpc::ServerWriteReactor<v1::GalleryExportChunk>* ExportGallery(
      grpc::CallbackServerContext* context, const v1::ExportGalleryRequest* request) override;
  // Assembles and checks the export as it arrives (the first error ends the call), then
  // GalleryRegistry::Import: all-or-nothing.
  grpc::ServerReadReactor<v1::ImportGalleryRequest>* ImportGallery(
      grpc::CallbackServerContext* context, v1::Gallery* response) override;

  grpc::ServerUnaryReactor* ListDescriptors(grpc::CallbackServerContext* context,
                                            const v1::ListDescriptorsRequest* request,
                                            v1::ListDescriptorsResponse* response) override;

  // Refuses every call with UNAVAILABLE "loading" until StartServing (a new service serves
  // at once; the server holds it while it loads galleries from the store).
  void HoldUntilLoaded() { gate_.tracker().SetState(CallTracker::State::kLoading); }
  void StartServing() { gate_.tracker().SetState(CallTracker::State::kServing); }
  // Refuses new calls (UNAVAILABLE) from now on; calls already running continue.
  void StartDraining() { gate_.tracker().StartDraining(); }
  int64_t calls_in_flight() const { return gate_.tracker().in_flight(); }

 private:
  // The cloud of a DescribeCloud or ClassifyCloud request, checked as a stream's would be.
  absl::StatusOr<PointCloud> CloudInOneMessage(uint64_t expected_points,
                                               absl::string_view xyz) const;

  const ServiceOptions options_;
  const std::shared_ptr<GalleryRegistry> registry_;
  CallGate gate_;
};

}  // namespace shapeid

#endif  // SHAPEID_SERVER_SHAPEID_SERVICE_H_
