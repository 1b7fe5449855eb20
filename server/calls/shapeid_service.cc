#include "server/calls/shapeid_service.h"

#include <memory>
#include <utility>

#include "server/calls/cloud_call.h"
#include "server/calls/cloud_rpcs.h"
#include "server/calls/gallery_rpcs.h"
#include "server/calls/operations_rpcs.h"
#include "server/calls/transfer_rpcs.h"
#include "server/calls/unary_call.h"

namespace shapeid {
namespace {

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
      runtime_{&gate_,    &observer_,      &scheduler_,  budget_.get(),
               &options_, registry_.get(), &description_} {}

ShapeIdService::~ShapeIdService() { scheduler_.Stop(); }

// The handler definitions of each shape of server/calls/rpc_list.h: each hands the call to the
// template of its shape with its declaration NameRpc.
#define SHAPEID_SERVICE_DEFINE_kCloud(name)                                                   \
  grpc::ServerReadReactor<grpc::ByteBuffer>* ShapeIdService::name(                            \
      grpc::CallbackServerContext* context, grpc::ByteBuffer* response) {                     \
    return ServeCloudStream<name##Rpc>(context, runtime_, SHAPEID_METHOD(name), response);    \
  }                                                                                           \
  grpc::ServerUnaryReactor* ShapeIdService::name##Cloud(grpc::CallbackServerContext* context, \
                                                        const grpc::ByteBuffer* raw_request,  \
                                                        grpc::ByteBuffer* raw_response) {     \
    return ServeCloudMessage<name##Rpc>(context, runtime_, SHAPEID_METHOD(name##Cloud),       \
                                        raw_request, raw_response);                           \
  }
#define SHAPEID_SERVICE_DEFINE_kStream(name)                                    \
  grpc::ServerReadReactor<grpc::ByteBuffer>* ShapeIdService::name(              \
      grpc::CallbackServerContext* context, grpc::ByteBuffer* response) {       \
    return name##Rpc::Start(context, runtime_, SHAPEID_METHOD(name), response); \
  }
#define SHAPEID_SERVICE_DEFINE_kServerStream(name)                               \
  grpc::ServerWriteReactor<name##Rpc::Response>* ShapeIdService::name(           \
      grpc::CallbackServerContext* context, const name##Rpc::Request* request) { \
    return name##Rpc::Start(context, runtime_, SHAPEID_METHOD(name), *request);  \
  }
#define SHAPEID_SERVICE_DEFINE_UNARY(name, kind)                                             \
  grpc::ServerUnaryReactor* ShapeIdService::name(grpc::CallbackServerContext* context,       \
                                                 const grpc::ByteBuffer* raw_request,        \
                                                 grpc::ByteBuffer* raw_response) {           \
    return ServeUnary<name##Rpc>(context, runtime_, SHAPEID_METHOD(name), kind, raw_request, \
                                 raw_response);                                              \
  }
#define SHAPEID_SERVICE_DEFINE_kUnary(name) \
  SHAPEID_SERVICE_DEFINE_UNARY(name, CallGate::Kind::kUnary)
#define SHAPEID_SERVICE_DEFINE_kOperations(name) \
  SHAPEID_SERVICE_DEFINE_UNARY(name, CallGate::Kind::kOperations)
#define SHAPEID_SERVICE_DEFINE(name, scope, shape) SHAPEID_SERVICE_DEFINE_##shape(name)

SHAPEID_RPCS(SHAPEID_SERVICE_DEFINE)

}  // namespace shapeid
