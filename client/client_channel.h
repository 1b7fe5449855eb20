#ifndef SHAPEID_CLIENT_CLIENT_CHANNEL_H_
#define SHAPEID_CLIENT_CLIENT_CHANNEL_H_

// The gRPC channel a Client talks over. Internal to the client library (not installed).

#include <memory>

#include "absl/status/statusor.h"
#include "client/client_options.h"
#include "grpcpp/channel.h"

namespace shapeid {

// The channel for `options`: its target (ResolveChannelTarget, channel_target.h), balancing
// (round_robin watching health where there are replicas to turn to, or pick_first), receive
// limit and credentials (plain, or TLS with the CA, client certificate and key read from
// their PEM files). InvalidArgument, naming the option or file, for an unknown balancing, a
// TLS option without TLS, a certificate without its key (or the reverse), a PEM file that
// cannot be read or is not PEM, and replicas on several hosts under TLS without
// tls_server_name; the target's errors as ResolveChannelTarget's.
absl::StatusOr<std::shared_ptr<grpc::Channel>> MakeChannel(const ClientOptions& options);

}  // namespace shapeid

#endif  // SHAPEID_CLIENT_CLIENT_CHANNEL_H_
