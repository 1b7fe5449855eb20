#include "client/client_channel.h"

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <string>
#include <utility>

#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/string_view.h"
#include "client/channel_target.h"
#include "grpcpp/create_channel.h"
#include "grpcpp/security/credentials.h"
#include "grpcpp/support/channel_arguments.h"

namespace shapeid {
namespace {

absl::StatusOr<std::string> ReadPemFile(const std::string& path, absl::string_view what) {
  std::FILE* f = std::fopen(path.c_str(), "rb");
  if (f == nullptr) {
    return absl::InvalidArgumentError(
        absl::StrCat("cannot read the ", what, " '", path, "': ", std::strerror(errno)));
  }
  std::string text;
  char buf[4096];
  size_t n;
  while ((n = std::fread(buf, 1, sizeof(buf), f)) > 0 && text.size() <= (1 << 20)) {
    text.append(buf, n);
  }
  std::fclose(f);
  if (text.find("-----BEGIN ") == std::string::npos) {
    return absl::InvalidArgumentError(
        absl::StrCat("the ", what, " '", path, "' is not a PEM file"));
  }
  return text;
}

}  // namespace

absl::StatusOr<std::shared_ptr<grpc::Channel>> MakeChannel(const ClientOptions& options) {
  absl::StatusOr<ChannelTarget> target = ResolveChannelTarget(options.target);
  if (!target.ok()) return target.status();
  grpc::ChannelArguments args;
  // The default service config (the DNS resolver's TXT lookup, which could replace it, is off
  // by default). loadBalancingConfig rather than the older grpc.lb_policy_name argument: it
  // is what gRPC documents now. healthCheckConfig makes round_robin leave out a replica that
  // is loading or draining (NOT_SERVING) rather than send it calls to refuse; pick_first
  // ignores it in gRPC 1.51.
  // Health is watched only where there is another replica to turn to (a list, or a dns:
  // target, whose name may have several records): a client of one server keeps reaching it
  // while it loads or drains, and so reads the server's own reason ("loading its
  // galleries") rather than gRPC's "backend unhealthy".
  const bool replicas =
      absl::StrContains(options.target, ',') || absl::StartsWith(options.target, "dns:");
  if (options.load_balancing == "round_robin" && replicas) {
    args.SetServiceConfigJSON(
        R"({"loadBalancingConfig":[{"round_robin":{}}],"healthCheckConfig":{"serviceName":""}})");
  } else if (options.load_balancing == "round_robin") {
    args.SetServiceConfigJSON(R"({"loadBalancingConfig":[{"round_robin":{}}]})");
  } else if (options.load_balancing == "pick_first") {
    args.SetServiceConfigJSON(R"({"loadBalancingConfig":[{"pick_first":{}}]})");
  } else {
    return absl::InvalidArgumentError(
        absl::StrCat("ClientOptions.load_balancing must be round_robin or pick_first, got \"",
                     options.load_balancing, "\""));
  }
  if (!target->authority.empty()) args.SetString(GRPC_ARG_DEFAULT_AUTHORITY, target->authority);
  args.SetMaxReceiveMessageSize(static_cast<int>(options.max_receive_bytes));
  const bool tls = options.tls || !options.tls_ca_file.empty() || !options.tls_cert_file.empty() ||
                   !options.tls_key_file.empty();
  if (!tls) {
    if (!options.tls_server_name.empty()) {
      return absl::InvalidArgumentError("ClientOptions.tls_server_name is set but TLS is off");
    }
    return grpc::CreateCustomChannel(target->target, grpc::InsecureChannelCredentials(), args);
  }
  if (!target->one_host && options.tls_server_name.empty()) {
    return absl::InvalidArgumentError(absl::StrCat(
        "ClientOptions.target '", options.target,
        "' lists replicas on different hosts and TLS checks one name for all of them: set "
        "tls_server_name to a name every replica's certificate carries"));
  }
  if (options.tls_cert_file.empty() != options.tls_key_file.empty()) {
    return absl::InvalidArgumentError(
        "a client certificate needs its key, and a key its certificate: give both TLS files "
        "or neither");
  }
  grpc::SslCredentialsOptions ssl;
  if (!options.tls_ca_file.empty()) {
    absl::StatusOr<std::string> ca = ReadPemFile(options.tls_ca_file, "TLS CA file");
    if (!ca.ok()) return ca.status();
    ssl.pem_root_certs = *std::move(ca);
  }
  if (!options.tls_cert_file.empty()) {
    absl::StatusOr<std::string> cert =
        ReadPemFile(options.tls_cert_file, "TLS client certificate file");
    if (!cert.ok()) return cert.status();
    absl::StatusOr<std::string> key = ReadPemFile(options.tls_key_file, "TLS client key file");
    if (!key.ok()) return key.status();
    ssl.pem_cert_chain = *std::move(cert);
    ssl.pem_private_key = *std::move(key);
  }
  if (!options.tls_server_name.empty()) args.SetSslTargetNameOverride(options.tls_server_name);
  return grpc::CreateCustomChannel(target->target, grpc::SslCredentials(ssl), args);
}

}  // namespace shapeid
