#ifndef SHAPEID_SERVER_CALLS_OPERATIONS_RPCS_H_
#define SHAPEID_SERVER_CALLS_OPERATIONS_RPCS_H_

// The operations RPCs (docs/operations.md; server/calls/rpc_list.h, shape kOperations): answered on
// gRPC's thread in every server state, outside the memory budget.

#include "absl/status/status.h"
#include "server/calls/admitted_call.h"
#include "shapeid/v1/shapeid.pb.h"

namespace shapeid {

// The server's state, galleries, scheduler, memory and call counts (server/ops/server_stats.h).
struct GetServerStatsRpc {
  using Request = v1::GetServerStatsRequest;
  using Response = v1::ServerStats;
  static absl::Status Handle(const ServiceRuntime& runtime, const Request& request,
                             Response* response, AdmittedCall& call);
};

// Changes the observer's log level: INVALID_ARGUMENT for an unknown level, FAILED_PRECONDITION
// for a service without a logger. The change is logged as a warning, with who asked.
struct SetLogLevelRpc {
  using Request = v1::SetLogLevelRequest;
  using Response = v1::SetLogLevelResponse;
  static absl::Status Handle(const ServiceRuntime& runtime, const Request& request,
                             Response* response, AdmittedCall& call);
};

}  // namespace shapeid

#endif  // SHAPEID_SERVER_CALLS_OPERATIONS_RPCS_H_
