#ifndef SHAPEID_SERVER_CALLS_UNARY_CALL_H_
#define SHAPEID_SERVER_CALLS_UNARY_CALL_H_

#include <type_traits>
#include <utility>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/string_view.h"
#include "grpcpp/grpcpp.h"
#include "grpcpp/impl/codegen/proto_utils.h"
#include "grpcpp/support/byte_buffer.h"
#include "server/calls/admitted_call.h"
#include "server/calls/grpc_status.h"

namespace shapeid {

// Runs one unary call of the service: admits it (server/calls/admitted_call.h), holds its request's
// memory from the budget (the received bytes and their parsed copy; operations calls are
// exempt, so that they answer however busy the server is), parses the request, here because
// gRPC answers a request that does not parse with UNIMPLEMENTED, which clients read as "an
// older server" (here it is INVALID_ARGUMENT), then calls
//   handler(const Request&, Response*, AdmittedCall&)
// on gRPC's thread. A handler that returns absl::Status has done its work there (it must cost
// microseconds); one that returns absl::StatusOr<Work> hands its work to the scheduler, and
// the call is answered when that work is done. The request, the response and the call live
// until then.
template <typename Request, typename Response, typename Handler>
grpc::ServerUnaryReactor* RunUnary(grpc::CallbackServerContext* context,
                                   const ServiceRuntime& runtime, absl::string_view method,
                                   CallGate::Kind kind, const grpc::ByteBuffer* raw_request,
                                   grpc::ByteBuffer* raw_response, Handler handler) {
  struct Unary {
    Unary(grpc::CallbackServerContext* context, const ServiceRuntime& runtime,
          absl::string_view method, CallGate::Kind kind, grpc::ByteBuffer* response_bytes)
        : call(context, runtime, method, kind),
          reactor(context->DefaultReactor()),
          raw_response(response_bytes) {}
    AdmittedCall call;
    grpc::ServerUnaryReactor* const reactor;
    grpc::ByteBuffer* const raw_response;
    Request request;
    Response response;

    void Finish(grpc::Status status) {
      if (status.ok()) {
        bool own_buffer = false;
        status =
            grpc::SerializationTraits<Response>::Serialize(response, raw_response, &own_buffer);
      }
      grpc::ServerUnaryReactor* const answer = reactor;
      answer->Finish(call.Conclude(status));
      delete this;
    }
  };
  auto* unary = new Unary(context, runtime, method, kind, raw_response);
  grpc::ServerUnaryReactor* const reactor = unary->reactor;
  AdmittedCall& call = unary->call;
  if (!call.admission().ok()) {
    unary->Finish(ToGrpcStatus(call.admission()));
    return reactor;
  }
  if (kind != CallGate::Kind::kOperations) {
    if (absl::Status held = call.HoldMemory(2 * raw_request->Length(), "the request"); !held.ok()) {
      unary->Finish(ToGrpcStatus(held));
      return reactor;
    }
  }
  grpc::ByteBuffer bytes(*raw_request);  // shares the received slices; parsing consumes it
  if (!grpc::SerializationTraits<Request>::Deserialize(&bytes, &unary->request).ok()) {
    unary->Finish(ToGrpcStatus(absl::InvalidArgumentError(absl::StrCat(
        call.method(), ": the request is not a valid ", Request::descriptor()->full_name(),
        " (damaged, or from another protocol version)"))));
    return reactor;
  }
  using Result = std::invoke_result_t<Handler&, const Request&, Response*, AdmittedCall&>;
  if constexpr (std::is_same_v<Result, absl::Status>) {
    unary->Finish(ToGrpcStatus(handler(unary->request, &unary->response, call)));
  } else {
    absl::StatusOr<Work> work = handler(unary->request, &unary->response, call);
    if (!work.ok()) {
      unary->Finish(ToGrpcStatus(work.status()));
      return reactor;
    }
    call.Run(*std::move(work),
             [unary](const absl::Status& status) { unary->Finish(ToGrpcStatus(status)); });
  }
  return reactor;
}

// RunUnary for the RPC a struct declares (server/calls/gallery_rpcs.h): its Request, its Response
// and its handler Rpc::Handle(runtime, request, response, call).
template <typename Rpc>
grpc::ServerUnaryReactor* ServeUnary(grpc::CallbackServerContext* context,
                                     const ServiceRuntime& runtime, absl::string_view method,
                                     CallGate::Kind kind, const grpc::ByteBuffer* raw_request,
                                     grpc::ByteBuffer* raw_response) {
  using Request = typename Rpc::Request;
  using Response = typename Rpc::Response;
  return RunUnary<Request, Response>(
      context, runtime, method, kind, raw_request, raw_response,
      [&runtime](const Request& request, Response* response, AdmittedCall& call) {
        return Rpc::Handle(runtime, request, response, call);
      });
}

}  // namespace shapeid

#endif  // SHAPEID_SERVER_CALLS_UNARY_CALL_H_
