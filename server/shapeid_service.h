#ifndef SHAPEID_SERVER_SHAPEID_SERVICE_H_
#define SHAPEID_SERVER_SHAPEID_SERVICE_H_

#include <memory>
#include <utility>

#include "core/gallery/gallery_registry.h"
#include "server/admitted_call.h"
#include "server/api_keys.h"
#include "server/call_gate.h"
#include "server/call_observer.h"
#include "server/memory_budget.h"
#include "server/server_stats.h"
#include "server/service_options.h"
#include "server/work_scheduler.h"
#include "shapeid/v1/shapeid.grpc.pb.h"

namespace shapeid {

// The methods that take requests are registered raw (their messages arrive as bytes and are
// parsed by the service): gRPC reports a streamed message that does not parse as the end of
// the stream, and a unary request that does not parse as UNIMPLEMENTED; shapeid answers both
// INVALID_ARGUMENT and keeps nothing of the call. ExportGallery stays typed (its request is a
// name).
using ShapeIdRawService = v1::ShapeId::WithRawCallbackMethod_Describe<
    v1::ShapeId::WithRawCallbackMethod_DescribeCloud<v1::ShapeId::WithRawCallbackMethod_Train<
        v1::ShapeId::WithRawCallbackMethod_Classify<v1::ShapeId::WithRawCallbackMethod_ClassifyCloud<
            v1::ShapeId::WithRawCallbackMethod_RecognizeScene<
                v1::ShapeId::WithRawCallbackMethod_RecognizeSceneCloud<
                    v1::ShapeId::WithRawCallbackMethod_CreateGallery<
                        v1::ShapeId::WithRawCallbackMethod_GetGallery<
                            v1::ShapeId::WithRawCallbackMethod_ListGalleries<
                                v1::ShapeId::WithRawCallbackMethod_DeleteGallery<
                                    v1::ShapeId::WithRawCallbackMethod_RemoveSamples<
                                        v1::ShapeId::WithRawCallbackMethod_ListSamples<
                                            v1::ShapeId::WithRawCallbackMethod_ImportGallery<
                                                v1::ShapeId::WithRawCallbackMethod_ListDescriptors<
                                                    v1::ShapeId::WithRawCallbackMethod_GetServerStats<
                                                        v1::ShapeId::
                                                            WithRawCallbackMethod_SetLogLevel<
                                                                v1::ShapeId::
                                                                    CallbackService>>>>>>>>>>>>>>>>>;

// The gRPC edge of shapeid: each method turns its messages into calls on core/ (descriptors,
// the gallery registry) and the result into one status (server/grpc_status.h). All state
// lives in the registry; thread-safe.
//
// Every call is admitted the same way (server/admitted_call.h): the call gate (API key and
// scope, server state, a stream's slot; server/call_gate.h), the memory it holds, and one
// report to the observer when it is answered (a log line and the metrics). gRPC's threads only
// move bytes: describing, searching and store writes run on the service's work scheduler
// (server/work_scheduler.h), admitted by estimated cost into cheap, heavy and store lanes and
// shared fairly between callers, so that health checks and cheap calls never wait behind a
// heavy one (docs/reliability.md). Clouds in transit and describing's working memory come
// from one memory budget (server/memory_budget.h).
class ShapeIdService final : public ShapeIdRawService {
 public:
  ShapeIdService(ServiceOptions options, std::shared_ptr<GalleryRegistry> registry,
                 std::shared_ptr<const ApiKeyStore> keys = nullptr, CallObserver observer = {});
  // Stops the scheduler: queued work is dropped, running work finishes first. The gRPC
  // server must be shut down before (its calls need their answers).
  ~ShapeIdService() override;

  // What GetServerStats reports about the server around the service; set once, before
  // serving.
  void SetDescription(ServerDescription description) { description_ = std::move(description); }

  // Client streams: messages v1::DescribeRequest, TrainRequest, ClassifyRequest; answers
  // v1::DescribeResponse, TrainResponse, ClassifyResponse.
  grpc::ServerReadReactor<grpc::ByteBuffer>* Describe(grpc::CallbackServerContext* context,
                                                      grpc::ByteBuffer* response) override;
  grpc::ServerReadReactor<grpc::ByteBuffer>* Train(grpc::CallbackServerContext* context,
                                                   grpc::ByteBuffer* response) override;
  grpc::ServerReadReactor<grpc::ByteBuffer>* Classify(grpc::CallbackServerContext* context,
                                                      grpc::ByteBuffer* response) override;
  grpc::ServerReadReactor<grpc::ByteBuffer>* RecognizeScene(grpc::CallbackServerContext* context,
                                                            grpc::ByteBuffer* response) override;
  // Unary calls: the request and response types of the proto, as bytes.
  grpc::ServerUnaryReactor* DescribeCloud(grpc::CallbackServerContext* context,
                                          const grpc::ByteBuffer* raw_request,
                                          grpc::ByteBuffer* raw_response) override;
  grpc::ServerUnaryReactor* ClassifyCloud(grpc::CallbackServerContext* context,
                                          const grpc::ByteBuffer* raw_request,
                                          grpc::ByteBuffer* raw_response) override;
  grpc::ServerUnaryReactor* RecognizeSceneCloud(grpc::CallbackServerContext* context,
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
  grpc::ServerUnaryReactor* ListSamples(grpc::CallbackServerContext* context,
                                        const grpc::ByteBuffer* raw_request,
                                        grpc::ByteBuffer* raw_response) override;
  // server/transfer_calls.h.
  grpc::ServerWriteReactor<v1::GalleryExportChunk>* ExportGallery(
      grpc::CallbackServerContext* context, const v1::ExportGalleryRequest* request) override;
  grpc::ServerReadReactor<grpc::ByteBuffer>* ImportGallery(grpc::CallbackServerContext* context,
                                                           grpc::ByteBuffer* response) override;

  grpc::ServerUnaryReactor* ListDescriptors(grpc::CallbackServerContext* context,
                                            const grpc::ByteBuffer* raw_request,
                                            grpc::ByteBuffer* raw_response) override;

  // Operations (docs/operations.md), answered on gRPC's thread in every state: v1::ServerStats
  // (server/server_stats.h); SetLogLevel changes the observer's logger (INVALID_ARGUMENT for an
  // unknown level; FAILED_PRECONDITION for a service without a logger).
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
  const WorkScheduler& scheduler() const { return scheduler_; }
  const MemoryBudget& budget() const { return *budget_; }
  const std::shared_ptr<MemoryBudget>& shared_budget() const { return budget_; }

 private:
  const ServiceOptions options_;
  const std::shared_ptr<GalleryRegistry> registry_;
  CallGate gate_;
  const CallObserver observer_;
  const std::shared_ptr<MemoryBudget> budget_;
  WorkScheduler scheduler_;
  const ServiceRuntime runtime_;
  ServerDescription description_;
};

}  // namespace shapeid

#endif  // SHAPEID_SERVER_SHAPEID_SERVICE_H_
