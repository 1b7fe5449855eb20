#ifndef SHAPEID_SERVER_CALLS_RPC_LIST_H_
#define SHAPEID_SERVER_CALLS_RPC_LIST_H_

#include "absl/strings/string_view.h"
#include "server/security/api_keys.h"

// Every RPC of shapeid.v1.ShapeId, declared once, gRPC-free. Each entry is
//   X(Name, scope, shape)
// `scope` is what a key needs to call it (server/security/authorization.h). `shape` says how the
// service serves it, each from the struct NameRpc that declares its work:
//   kCloud         a cloud RPC: the client stream Name and the one-message NameCloud, both
//                  served by one template from NameRpc's Plan and Work (server/calls/cloud_call.h);
//   kStream        a client stream of its own, NameRpc::Start (Train, ImportGallery);
//   kServerStream  a server stream, NameRpc::Start (ExportGallery);
//   kUnary         one message in, one out: NameRpc::Handle (server/calls/unary_call.h);
//   kOperations    kUnary, admitted in every server state and outside the memory budget.
// The scope table, the service's handlers (server/calls/shapeid_service.{h,cc}) and the gate's kind
// of each call come from this list; rpc_list_test checks it against the proto's service.
// Adding an RPC: the proto, one line here, its NameRpc, and its core function.
#define SHAPEID_RPCS(X)                   \
  X(Describe, kRead, kCloud)              \
  X(Classify, kRead, kCloud)              \
  X(RecognizeScene, kRead, kCloud)        \
  X(Train, kWrite, kStream)               \
  X(CreateGallery, kWrite, kUnary)        \
  X(GetGallery, kRead, kUnary)            \
  X(ListGalleries, kRead, kUnary)         \
  X(DeleteGallery, kAdmin, kUnary)        \
  X(RemoveSamples, kWrite, kUnary)        \
  X(ListSamples, kRead, kUnary)           \
  X(ExportGallery, kWrite, kServerStream) \
  X(ImportGallery, kWrite, kStream)       \
  X(ListDescriptors, kRead, kUnary)       \
  X(GetServerStats, kRead, kOperations)   \
  X(SetLogLevel, kAdmin, kOperations)

namespace shapeid {

// The full name of ShapeId's RPC `name` ("/shapeid.v1.ShapeId/Train"), as the scope table, the
// handlers' call records and gRPC know it.
#define SHAPEID_METHOD(name) "/shapeid.v1.ShapeId/" #name

// One method as gRPC names it, with the scope it needs.
struct RpcMethod {
  absl::string_view full_name;
  Scope scope;
};

#define SHAPEID_RPC_METHODS_kCloud(name, scope) \
  {SHAPEID_METHOD(name), Scope::scope}, {SHAPEID_METHOD(name##Cloud), Scope::scope},
#define SHAPEID_RPC_METHODS_kStream(name, scope) {SHAPEID_METHOD(name), Scope::scope},
#define SHAPEID_RPC_METHODS_kServerStream SHAPEID_RPC_METHODS_kStream
#define SHAPEID_RPC_METHODS_kUnary SHAPEID_RPC_METHODS_kStream
#define SHAPEID_RPC_METHODS_kOperations SHAPEID_RPC_METHODS_kStream
#define SHAPEID_RPC_METHODS(name, scope, shape) SHAPEID_RPC_METHODS_##shape(name, scope)

// Every method of the list: a kCloud entry gives two (Name and NameCloud).
inline constexpr RpcMethod kRpcMethods[] = {SHAPEID_RPCS(SHAPEID_RPC_METHODS)};

}  // namespace shapeid

#endif  // SHAPEID_SERVER_CALLS_RPC_LIST_H_
