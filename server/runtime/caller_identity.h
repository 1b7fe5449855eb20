#ifndef SHAPEID_SERVER_RUNTIME_CALLER_IDENTITY_H_
#define SHAPEID_SERVER_RUNTIME_CALLER_IDENTITY_H_

// Who a call is for, for the server's fair shares: the scheduler's queues and backlog bound
// (server/runtime/work_scheduler.h) and the memory budget (server/runtime/memory_budget.h) are
// shared per caller. In order:
//   "key:NAME"   the API key the call presented (a server with keys);
//   "cert:CN"    else the common name of a verified client certificate (mutual TLS);
//   "HOST"       else the peer's address, without its port ("127.0.0.1", "::1").
// Only a caller known by its host may add an id of its own (kCallerIdMetadata, whose rule is
// core/request_id.h's IsValidCallerId):
// "127.0.0.1/arm-left". That splits a fleet of robots that share one host and no key into
// callers of their own, so one robot's burst of work cannot refuse its neighbors. Keys and
// certificates are identities the operator issued: an id cannot split them (a key holder
// could otherwise multiply its share by inventing ids); give each robot its own key instead.

#include <string>

#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "grpcpp/grpcpp.h"

namespace shapeid {

// The caller as above. `key_name` is the name of the key the call was admitted with, empty
// without one. InvalidArgument naming the metadata when a caller id is malformed.
absl::StatusOr<std::string> CallerOf(const grpc::ServerContextBase& context,
                                     absl::string_view key_name);

// The same from its parts, for tests: `peer` as gRPC gives it ("ipv4:127.0.0.1:5555"),
// `certificate_name` the verified certificate's common name (empty: none), `caller_id` the
// metadata's value (empty: none).
absl::StatusOr<std::string> CallerOf(absl::string_view key_name, absl::string_view certificate_name,
                                     absl::string_view peer, absl::string_view caller_id);

}  // namespace shapeid

#endif  // SHAPEID_SERVER_RUNTIME_CALLER_IDENTITY_H_
