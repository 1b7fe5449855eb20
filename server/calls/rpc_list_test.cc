#include "server/calls/rpc_list.h"

#include <map>
#include <string>

#include "google/protobuf/descriptor.h"
#include "gtest/gtest.h"
#include "shapeid/v1/shapeid.pb.h"

namespace shapeid {
namespace {

const google::protobuf::ServiceDescriptor& ShapeIdService() {
  const google::protobuf::ServiceDescriptor* service =
      v1::DescribeRequest::descriptor()->file()->FindServiceByName("ShapeId");
  EXPECT_NE(service, nullptr);
  return *service;
}

TEST(RpcListTest, EveryMethodOfTheProtoIsListedOnceAndNothingElse) {
  std::map<std::string, int> listed;
  for (const RpcMethod& method : kRpcMethods) ++listed[std::string(method.full_name)];
  const google::protobuf::ServiceDescriptor& service = ShapeIdService();
  for (int i = 0; i < service.method_count(); ++i) {
    const std::string full = "/shapeid.v1.ShapeId/" + service.method(i)->name();
    EXPECT_EQ(listed[full], 1) << full << ": a new RPC needs its line in server/calls/rpc_list.h";
  }
  EXPECT_EQ(listed.size(), static_cast<size_t>(service.method_count()))
      << "server/calls/rpc_list.h names a method the proto does not have";
}

// The list's shapes serve what gRPC expects of each method: a kCloud entry's Name is a client
// stream and NameCloud one message each way; kStream a client stream; kServerStream a server
// stream; kUnary and kOperations one message each way.
#define SHAPEID_TEST_SHAPE_kCloud(name) {#name, "client"}, {#name "Cloud", "unary"},
#define SHAPEID_TEST_SHAPE_kStream(name) {#name, "client"},
#define SHAPEID_TEST_SHAPE_kServerStream(name) {#name, "server"},
#define SHAPEID_TEST_SHAPE_kUnary(name) {#name, "unary"},
#define SHAPEID_TEST_SHAPE_kOperations(name) {#name, "unary"},
#define SHAPEID_TEST_SHAPE(name, scope, shape) SHAPEID_TEST_SHAPE_##shape(name)

TEST(RpcListTest, EachShapeMatchesTheMethodsStreaming) {
  const std::map<std::string, std::string> shapes = {SHAPEID_RPCS(SHAPEID_TEST_SHAPE)};
  const google::protobuf::ServiceDescriptor& service = ShapeIdService();
  for (int i = 0; i < service.method_count(); ++i) {
    const google::protobuf::MethodDescriptor& method = *service.method(i);
    ASSERT_EQ(method.client_streaming() && method.server_streaming(), false) << method.name();
    const std::string streaming = method.client_streaming()   ? "client"
                                  : method.server_streaming() ? "server"
                                                              : "unary";
    ASSERT_TRUE(shapes.count(method.name())) << method.name();
    EXPECT_EQ(shapes.at(method.name()), streaming) << method.name();
  }
}

}  // namespace
}  // namespace shapeid
