#ifndef SHAPEID_SERVER_SHAPEID_SERVICE_H_
#define SHAPEID_SERVER_SHAPEID_SERVICE_H_

#include "server/service_options.h"
#include "shapeid/v1/shapeid.grpc.pb.h"

namespace shapeid {

// The gRPC edge of shapeid: each method turns its messages into calls on core/ and the
// result into one status, through ToGrpcStatus (server/grpc_status.h). Stateless apart from
// its options; thread-safe. Methods not overridden answer UNIMPLEMENTED.
class ShapeIdService final : public v1::ShapeId::CallbackService {
 public:
  explicit ShapeIdService(ServiceOptions options) : options_(std::move(options)) {}

  grpc::ServerReadReactor<v1::DescribeRequest>* Describe(grpc::CallbackServerContext* context,
                                                         v1::DescribeResponse* response) override;

  grpc::ServerUnaryReactor* ListDescriptors(grpc::CallbackServerContext* context,
                                            const v1::ListDescriptorsRequest* request,
                                            v1::ListDescriptorsResponse* response) override;

 private:
  const ServiceOptions options_;
};

}  // namespace shapeid

#endif  // SHAPEID_SERVER_SHAPEID_SERVICE_H_
