#include "server/server.h"

#include <chrono>
#include <utility>

#include "absl/strings/str_cat.h"
#include "absl/time/clock.h"
#include "grpcpp/ext/proto_server_reflection_plugin.h"
#include "grpcpp/health_check_service_interface.h"

namespace shapeid {

absl::StatusOr<std::unique_ptr<ShapeIdServer>> ShapeIdServer::Start(const ServerOptions& options) {
  // Both must be set before the builder exists.
  grpc::EnableDefaultHealthCheckService(true);
  grpc::reflection::InitProtoReflectionServerBuilderPlugin();

  std::unique_ptr<ShapeIdServer> server(new ShapeIdServer);
  GalleryLimits limits = options.gallery_limits;
  limits.max_points_per_cloud = options.service.max_points_per_cloud;
  server->registry_ = std::make_shared<GalleryRegistry>(limits);
  server->service_ = std::make_unique<ShapeIdService>(options.service, server->registry_);

  grpc::ServerBuilder builder;
  // TLS arrives with the security issue; until then the server must only be exposed where
  // that is acceptable (the default listens on loopback).
  builder.AddListeningPort(options.listen, grpc::InsecureServerCredentials(), &server->port_);
  builder.RegisterService(server->service_.get());
  builder.SetMaxReceiveMessageSize(options.max_message_bytes);
  // No thread-count option: gRPC 1.51's callback API runs reactions on its own executor,
  // which ResourceQuota::SetMaxThreads does not govern (measured: 0, 2 and 8 threads gave the
  // same throughput with 16 clients).
  server->server_ = builder.BuildAndStart();
  if (server->server_ == nullptr || server->port_ == 0) {
    return absl::UnavailableError(absl::StrCat(
        "cannot listen on ", options.listen, " (address in use, or not an address of this host)"));
  }
  const size_t colon = options.listen.rfind(':');
  server->address_ = absl::StrCat(options.listen.substr(0, colon), ":", server->port_);
  server->server_->GetHealthCheckService()->SetServingStatus(true);
  return server;
}

void ShapeIdServer::Shutdown(absl::Duration grace) {
  if (shut_down_ || server_ == nullptr) return;
  shut_down_ = true;
  server_->GetHealthCheckService()->SetServingStatus(false);
  // Drain ourselves, then shut gRPC down at once: Server::Shutdown(deadline) alone would also
  // wait for idle client connections and so always take the whole grace period.
  service_->StartDraining();
  const absl::Time deadline = absl::Now() + grace;
  while (service_->calls_in_flight() > 0 && absl::Now() < deadline) {
    absl::SleepFor(absl::Milliseconds(5));
  }
  server_->Shutdown(std::chrono::system_clock::now());  // cancels whatever is left
  server_->Wait();
}

ShapeIdServer::~ShapeIdServer() { Shutdown(absl::ZeroDuration()); }

}  // namespace shapeid
