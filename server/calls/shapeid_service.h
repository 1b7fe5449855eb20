#ifndef SHAPEID_SERVER_CALLS_SHAPEID_SERVICE_H_
#define SHAPEID_SERVER_CALLS_SHAPEID_SERVICE_H_

#include <memory>
#include <utility>

#include "core/gallery/gallery_registry.h"
#include "server/calls/admitted_call.h"
#include "server/calls/rpc_list.h"
#include "server/calls/service_options.h"
#include "server/calls/transfer_rpcs.h"
#include "server/ops/call_observer.h"
#include "server/ops/server_stats.h"
#include "server/runtime/call_gate.h"
#include "server/runtime/memory_budget.h"
#include "server/runtime/work_scheduler.h"
#include "server/security/api_keys.h"
#include "shapeid/v1/shapeid.grpc.pb.h"

namespace shapeid {

// The methods that take requests are registered raw (their messages arrive as bytes and are
// parsed by the service): gRPC reports a streamed message that does not parse as the end of
// the stream, and a unary request that does not parse as UNIMPLEMENTED; shapeid answers both
// INVALID_ARGUMENT and keeps nothing of the call. ExportGallery (kServerStream) stays typed
// (its request is a name). The wrappers come from server/calls/rpc_list.h, nested by
// RawMethods: gRPC's generated WithRawCallbackMethod_X<Base> each derive from their Base.
template <template <class> class... Wrappers>
struct RawMethods;
template <>
struct RawMethods<> {
  using type = v1::ShapeId::CallbackService;
};
template <template <class> class Wrap, template <class> class... Rest>
struct RawMethods<Wrap, Rest...> {
  using type = Wrap<typename RawMethods<Rest...>::type>;
};
template <class Base>
using AsItIs = Base;

#define SHAPEID_SERVICE_RAW_kCloud(name) \
  v1::ShapeId::WithRawCallbackMethod_##name, v1::ShapeId::WithRawCallbackMethod_##name##Cloud,
#define SHAPEID_SERVICE_RAW_kStream(name) v1::ShapeId::WithRawCallbackMethod_##name,
#define SHAPEID_SERVICE_RAW_kServerStream(name)
#define SHAPEID_SERVICE_RAW_kUnary SHAPEID_SERVICE_RAW_kStream
#define SHAPEID_SERVICE_RAW_kOperations SHAPEID_SERVICE_RAW_kStream
#define SHAPEID_SERVICE_RAW(name, scope, shape) SHAPEID_SERVICE_RAW_##shape(name)

using ShapeIdRawService = RawMethods<SHAPEID_RPCS(SHAPEID_SERVICE_RAW) AsItIs>::type;

// The handler declarations of each shape of server/calls/rpc_list.h, as gRPC's generated base
// class names them.
#define SHAPEID_SERVICE_DECLARE_kCloud(name)                                            \
  grpc::ServerReadReactor<grpc::ByteBuffer>* name(grpc::CallbackServerContext* context, \
                                                  grpc::ByteBuffer* response) override; \
  grpc::ServerUnaryReactor* name##Cloud(grpc::CallbackServerContext* context,           \
                                        const grpc::ByteBuffer* raw_request,            \
                                        grpc::ByteBuffer* raw_response) override;
#define SHAPEID_SERVICE_DECLARE_kStream(name)                                           \
  grpc::ServerReadReactor<grpc::ByteBuffer>* name(grpc::CallbackServerContext* context, \
                                                  grpc::ByteBuffer* response) override;
#define SHAPEID_SERVICE_DECLARE_kServerStream(name)                                         \
  grpc::ServerWriteReactor<name##Rpc::Response>* name(grpc::CallbackServerContext* context, \
                                                      const name##Rpc::Request* request) override;
#define SHAPEID_SERVICE_DECLARE_kUnary(name)                           \
  grpc::ServerUnaryReactor* name(grpc::CallbackServerContext* context, \
                                 const grpc::ByteBuffer* raw_request,  \
                                 grpc::ByteBuffer* raw_response) override;
#define SHAPEID_SERVICE_DECLARE_kOperations SHAPEID_SERVICE_DECLARE_kUnary
#define SHAPEID_SERVICE_DECLARE(name, scope, shape) SHAPEID_SERVICE_DECLARE_##shape(name)

// The gRPC edge of shapeid: each method turns its messages into calls on core/ (descriptors,
// the gallery registry) and the result into one status (server/calls/grpc_status.h). All state
// lives in the registry; thread-safe.
//
// Every call is admitted the same way (server/calls/admitted_call.h): the call gate (API key and
// scope, server state, a stream's slot; server/runtime/call_gate.h), the memory it holds, and one
// report to the observer when it is answered (a log line and the metrics). gRPC's threads only
// move bytes: describing, searching and store writes run on the service's work scheduler
// (server/runtime/work_scheduler.h), admitted by estimated cost into cheap, heavy and store lanes
// and shared fairly between callers, so that health checks and cheap calls never wait behind a
// heavy one (docs/reliability.md). Clouds in transit and describing's working memory come
// from one memory budget (server/runtime/memory_budget.h).
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

  // One handler per RPC of server/calls/rpc_list.h (two for a cloud RPC: its stream and its
  // one-message call), declared from the list by shape below.
  SHAPEID_RPCS(SHAPEID_SERVICE_DECLARE)

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

#endif  // SHAPEID_SERVER_CALLS_SHAPEID_SERVICE_H_
