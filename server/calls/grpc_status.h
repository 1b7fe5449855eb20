#ifndef SHAPEID_SERVER_CALLS_GRPC_STATUS_H_
#define SHAPEID_SERVER_CALLS_GRPC_STATUS_H_

#include "absl/status/status.h"
#include "grpcpp/support/status.h"

namespace shapeid {

// The one place where an absl::Status from core/ becomes what a client sees. The canonical
// codes are the same numbers in both libraries.
inline grpc::Status ToGrpcStatus(const absl::Status& status) {
  if (status.ok()) return grpc::Status::OK;
  return grpc::Status(static_cast<grpc::StatusCode>(status.code()), std::string(status.message()));
}

}  // namespace shapeid

#endif  // SHAPEID_SERVER_CALLS_GRPC_STATUS_H_
