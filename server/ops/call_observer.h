#ifndef SHAPEID_SERVER_OPS_CALL_OBSERVER_H_
#define SHAPEID_SERVER_OPS_CALL_OBSERVER_H_

// What the server tells about each call: one log line (server/ops/logger.h) and the metrics
// (server/ops/metrics.h), both written when the call is answered, from one CallRecord the handler
// fills in as it goes. Also the request id: the client's "x-request-id", or a fresh one, sent
// back in the initial metadata so a client can quote it and an operator find the line.
//
// Never logged: points, descriptor values, API keys (only a key's name), metadata other than
// the request id.

#include <cstdint>
#include <memory>
#include <string>

#include "absl/strings/string_view.h"
#include "absl/time/time.h"
#include "grpcpp/grpcpp.h"
#include "server/ops/logger.h"
#include "server/ops/metrics.h"

namespace shapeid {

inline constexpr char kRequestIdMetadata[] = "x-request-id";

// One call, as its handler saw it.
struct CallRecord {
  absl::string_view method;  // "ClassifyCloud"
  absl::Time start;
  std::string request_id;
  std::string peer;     // "ipv4:10.0.0.7:53410"
  std::string caller;   // the API key's name once admitted (never the key)
  std::string gallery;  // the gallery the call names, if any
  int64_t points = 0;   // received in its clouds
  int64_t samples = 0;  // trained, removed, deleted, imported or exported
  absl::Duration describe_time;
  absl::Duration search_time;
  // Time its work waited for a worker of the scheduler (server/runtime/work_scheduler.h).
  absl::Duration wait_time;
  bool finished = false;
};

// Thread-safe; shared by every call of a service. Either part may be null (nothing logged,
// nothing counted), as for a service built without a server around it.
class CallObserver {
 public:
  CallObserver() = default;
  CallObserver(std::shared_ptr<ServerMetrics> metrics, std::shared_ptr<Logger> logger)
      : metrics_(std::move(metrics)), logger_(std::move(logger)) {}

  // At the call's arrival, before anything can fail: its record, with the request id added
  // to the initial metadata (sent with the answer, or the first message of a stream).
  CallRecord Start(grpc::CallbackServerContext& context, absl::string_view full_method) const;

  // When the call is answered; once per record (a second call does nothing).
  void Finish(CallRecord& record, const grpc::Status& status) const;

  // One cloud described (by a descriptor of kind `kind`) or searched, within `record`'s call.
  void Described(CallRecord& record, absl::string_view kind, absl::Duration elapsed) const;
  void Searched(CallRecord& record, bool approximate, absl::Duration elapsed) const;
  // One piece of the call's work waited `waited` in the scheduler's `lane` ("cheap").
  void Waited(CallRecord& record, absl::string_view lane, absl::Duration waited) const;

  ServerMetrics* metrics() const { return metrics_.get(); }
  Logger* logger() const { return logger_.get(); }

 private:
  std::shared_ptr<ServerMetrics> metrics_;
  std::shared_ptr<Logger> logger_;
};

}  // namespace shapeid

#endif  // SHAPEID_SERVER_OPS_CALL_OBSERVER_H_
