#ifndef SHAPEID_SERVER_CALLS_CLOUD_CALL_H_
#define SHAPEID_SERVER_CALLS_CLOUD_CALL_H_

// The two handlers every cloud RPC shares (server/calls/rpc_list.h, shape kCloud): the client
// stream (a header, then points in chunks of any size) and the one-message call (header and points
// together). Both check the header before any point is read, assemble the cloud with the same
// checks and messages (server/wire/cloud_assembler.h), and hand the RPC's work to the scheduler.
//
// A cloud RPC is declared by a struct (server/calls/cloud_rpcs.h):
// clang-format off
//   struct NameRpc {
//     using StreamRequest = v1::NameRequest;      // oneof kind { Header header; PointChunk points; }
//     using CloudRequest = v1::NameCloudRequest;  // Header header; PointChunk points;
//     using Header = ...;
//     using Response = ...;
//     static constexpr bool kHeaderRequired = ...;  // false: an absent header asks for defaults
//     struct Plan { ...; WireCloudFormat format; };
//     // What the header asks for, checked, with the one gallery snapshot the call uses;
//     // names the gallery in `record`.
//     static absl::StatusOr<Plan> PlanOf(const ServiceRuntime&, const Header&, CallRecord&);
//     // The work on the cloud `cloud` gives (`points` points, for the estimate).
//     static Work WorkOf(Plan, size_t points, CloudSource cloud, AdmittedCall&, Response*);
//   };
// clang-format on

#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <utility>

#include "absl/status/statusor.h"
#include "absl/strings/str_cat.h"
#include "core/gallery/gallery_registry.h"
#include "core/point_cloud.h"
#include "core/status_macros.h"
#include "grpcpp/grpcpp.h"
#include "server/calls/admitted_call.h"
#include "server/calls/stream_reactor.h"
#include "server/calls/unary_call.h"
#include "server/wire/cloud_assembler.h"

namespace shapeid {

// Gives the call's cloud once its points have arrived (the assembler's checks run here).
using CloudSource = std::function<absl::StatusOr<PointCloud>()>;

// The cloud of a one-message call: the streams' assembler with a single chunk, so the same
// checks and the same messages. Its memory is the call's (RunUnary holds the request's).
absl::StatusOr<PointCloud> CloudInOneMessage(const ServiceRuntime& runtime,
                                             uint64_t expected_points,
                                             const WireCloudFormat& format, absl::string_view xyz);

// A stream that assembles clouds: the call's runtime and an assembler over the memory budget,
// whose held bytes count as the call's. The most-derived reactor calls StartReading() as the
// last step of its constructor: a read that completed earlier would reach a half-built one.
template <typename Request, typename Response>
class CloudAssemblingReactor : public StreamReactor<Request, Response> {
 protected:
  CloudAssemblingReactor(grpc::CallbackServerContext* context, const ServiceRuntime& runtime,
                         absl::string_view method, grpc::ByteBuffer* response)
      : StreamReactor<Request, Response>(context, runtime, method, response),
        runtime_(runtime),
        assembler_(runtime.registry->limits().max_points_per_cloud, runtime.budget,
                   this->call().caller()) {
    this->call().CountHeld([this] { return assembler_.held_bytes(); });
  }

  const ServiceRuntime runtime_;
  CloudAssembler assembler_;
};

template <typename Rpc>
class CloudStreamReactor final
    : public CloudAssemblingReactor<typename Rpc::StreamRequest, typename Rpc::Response> {
  using Request = typename Rpc::StreamRequest;
  using Base = CloudAssemblingReactor<Request, typename Rpc::Response>;
  using Base::assembler_;
  using Base::runtime_;

 public:
  CloudStreamReactor(grpc::CallbackServerContext* context, const ServiceRuntime& runtime,
                     absl::string_view method, grpc::ByteBuffer* response)
      : Base(context, runtime, method, response) {
    this->StartReading();
  }

 private:
  absl::StatusOr<std::optional<Work>> OnMessage(const Request& request) override {
    const std::string& header_name = Rpc::Header::descriptor()->name();
    switch (request.kind_case()) {
      case Request::kHeader: {
        if (plan_.has_value()) {
          return absl::InvalidArgumentError(
              absl::StrCat(this->call().method(), ": a second ", header_name));
        }
        SHAPEID_ASSIGN_OR_RETURN(plan_,
                                 Rpc::PlanOf(runtime_, request.header(), this->call().record()));
        SHAPEID_RETURN_IF_ERROR(
            assembler_.Start(request.header().expected_points(), plan_->format));
        return std::nullopt;
      }
      case Request::kPoints:
        if (!plan_.has_value()) {
          return absl::InvalidArgumentError(absl::StrCat(this->call().method(),
                                                         ": the first message must be a ",
                                                         header_name, "; points came first"));
        }
        SHAPEID_RETURN_IF_ERROR(assembler_.Append(request.points().xyz()));
        this->call().record().points = static_cast<int64_t>(assembler_.points_received());
        return std::nullopt;
      case Request::KIND_NOT_SET:
        break;
    }
    return absl::InvalidArgumentError(
        absl::StrCat(this->call().method(), ": a message with neither header nor points"));
  }

  absl::StatusOr<Work> OnEnd() override {
    if (!plan_.has_value()) {
      return absl::InvalidArgumentError(absl::StrCat(this->call().method(),
                                                     ": the stream ended without a ",
                                                     Rpc::Header::descriptor()->name()));
    }
    return Rpc::WorkOf(
        *std::move(plan_), assembler_.points(), [this] { return assembler_.Finish(); },
        this->call(), this->response());
  }

  std::optional<typename Rpc::Plan> plan_;
};

// The client stream `method` of cloud RPC `Rpc`; deletes itself when gRPC is done with it.
template <typename Rpc>
grpc::ServerReadReactor<grpc::ByteBuffer>* ServeCloudStream(grpc::CallbackServerContext* context,
                                                            const ServiceRuntime& runtime,
                                                            absl::string_view method,
                                                            grpc::ByteBuffer* response) {
  return new CloudStreamReactor<Rpc>(context, runtime, method, response);
}

// The one-message call `method` ("...NameCloud") of cloud RPC `Rpc`.
template <typename Rpc>
grpc::ServerUnaryReactor* ServeCloudMessage(grpc::CallbackServerContext* context,
                                            const ServiceRuntime& runtime, absl::string_view method,
                                            const grpc::ByteBuffer* raw_request,
                                            grpc::ByteBuffer* raw_response) {
  using Request = typename Rpc::CloudRequest;
  using Response = typename Rpc::Response;
  return RunUnary<Request, Response>(
      context, runtime, method, CallGate::Kind::kUnary, raw_request, raw_response,
      [&runtime](const Request& request, Response* response,
                 AdmittedCall& call) -> absl::StatusOr<Work> {
        if (Rpc::kHeaderRequired && !request.has_header()) {
          return absl::InvalidArgumentError(
              absl::StrCat(call.method(), ": the request has no header"));
        }
        SHAPEID_ASSIGN_OR_RETURN(typename Rpc::Plan plan,
                                 Rpc::PlanOf(runtime, request.header(), call.record()));
        const absl::string_view xyz = request.points().xyz();
        // Points in the bytes, for the record and the estimate (a partial point counts
        // nothing; the assembler refuses it).
        call.record().points = static_cast<int64_t>(xyz.size() / plan.format.layout.point_step);
        const WireCloudFormat format = plan.format;
        return Rpc::WorkOf(
            std::move(plan), static_cast<size_t>(call.record().points),
            [&runtime, &request, format] {
              return CloudInOneMessage(runtime, request.header().expected_points(), format,
                                       request.points().xyz());
            },
            call, response);
      });
}

}  // namespace shapeid

#endif  // SHAPEID_SERVER_CALLS_CLOUD_CALL_H_
