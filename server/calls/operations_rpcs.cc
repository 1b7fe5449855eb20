#include "server/calls/operations_rpcs.h"

#include <string>

#include "core/status_macros.h"
#include "server/ops/logger.h"
#include "server/ops/server_stats.h"

namespace shapeid {

absl::Status GetServerStatsRpc::Handle(const ServiceRuntime& runtime, const Request& /*request*/,
                                       Response* response, AdmittedCall& /*call*/) {
  BuildServerStats(
      {runtime.description, &runtime.gate->tracker(), runtime.registry, runtime.scheduler,
       runtime.budget, runtime.observer->metrics(), runtime.observer->logger()},
      response);
  return absl::OkStatus();
}

absl::Status SetLogLevelRpc::Handle(const ServiceRuntime& runtime, const Request& request,
                                    Response* response, AdmittedCall& call) {
  SHAPEID_ASSIGN_OR_RETURN(const LogLevel level, ParseLogLevel(request.level()));
  Logger* logger = runtime.observer->logger();
  if (logger == nullptr) {
    return absl::FailedPreconditionError("SetLogLevel: this service keeps no log");
  }
  const LogLevel previous = logger->SetLevel(level);
  // A warning, so that the change shows at every level but error.
  logger->Warning("log level changed", {{"from", LogLevelName(previous)},
                                        {"to", LogLevelName(level)},
                                        {"peer", call.record().peer},
                                        {"request_id", call.record().request_id}});
  response->set_previous_level(std::string(LogLevelName(previous)));
  response->set_level(std::string(LogLevelName(level)));
  return absl::OkStatus();
}

}  // namespace shapeid
