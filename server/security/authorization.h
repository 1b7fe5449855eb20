#ifndef SHAPEID_SERVER_SECURITY_AUTHORIZATION_H_
#define SHAPEID_SERVER_SECURITY_AUTHORIZATION_H_

// Which scope each RPC needs, and the decision for one call (docs/security.md). gRPC-free:
// the call gate (server/runtime/call_gate.h) hands in the method name and the metadata.

#include <optional>

#include "absl/status/status.h"
#include "absl/strings/string_view.h"
#include "server/calls/rpc_list.h"
#include "server/security/api_keys.h"

namespace shapeid {

// The metadata key that carries "Bearer KEY" (lowercase, as gRPC metadata keys are).
inline constexpr absl::string_view kAuthorizationMetadata = "authorization";

// The scope a call of `full_method` ("/shapeid.v1.ShapeId/Train") needs: its entry in
// server/calls/rpc_list.h (docs/security.md lists them); admin for every method the list does not
// name. nullopt: open to every caller, key or not: grpc.health.v1 (Kubernetes' gRPC probes
// cannot send metadata).
std::optional<Scope> RequiredScope(absl::string_view full_method);

// Whether a call of `full_method` may run, given the value of its `authorization` metadata
// (nullopt when absent) and the server's keys:
//   OK                 no keys configured (an open server), an open method, or a key whose
//                      scope covers the method's;
//   UNAUTHENTICATED    "missing API key" (no metadata), "unknown API key" (not in `keys`, or
//                      not of the form "Bearer KEY");
//   PERMISSION_DENIED  "key 'NAME' lacks scope write ...": the key's name, never the key.
// `caller`, when given, is set to the key's entry whenever the key is known (also when its
// scope falls short), for the log line of the call.
absl::Status Authorize(const ApiKeyStore& keys, absl::string_view full_method,
                       std::optional<absl::string_view> authorization,
                       const ApiKeyEntry** caller = nullptr);

}  // namespace shapeid

#endif  // SHAPEID_SERVER_SECURITY_AUTHORIZATION_H_
