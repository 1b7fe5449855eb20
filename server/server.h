#ifndef SHAPEID_SERVER_SERVER_H_
#define SHAPEID_SERVER_SERVER_H_

#include <memory>
#include <string>

#include "absl/status/statusor.h"
#include "absl/time/time.h"
#include "grpcpp/grpcpp.h"
#include "server/server_options.h"
#include "server/shapeid_service.h"

namespace shapeid {

// A running shapeid server: the ShapeId service over an in-memory gallery registry,
// grpc.health.v1 health checking (SERVING once
// started) and server reflection, so grpcurl and standard probes work.
class ShapeIdServer {
 public:
  // Binds and starts serving. Unavailable if the address cannot be bound.
  static absl::StatusOr<std::unique_ptr<ShapeIdServer>> Start(const ServerOptions& options);

  ~ShapeIdServer();

  // "HOST:PORT" with the port actually bound (useful after listening on port 0).
  const std::string& address() const { return address_; }
  int port() const { return port_; }

  // Health turns NOT_SERVING; new calls are refused with UNAVAILABLE; calls in flight may
  // finish until `grace` has passed, then the rest are cancelled and the server stops.
  // Returns as soon as the last call ends. Idempotent.
  void Shutdown(absl::Duration grace);

 private:
  ShapeIdServer() = default;

  // Galleries live in memory for now; the durable store plugs into the registry (issue 5).
  std::shared_ptr<GalleryRegistry> registry_;
  std::unique_ptr<ShapeIdService> service_;
  std::unique_ptr<grpc::Server> server_;
  std::string address_;
  int port_ = 0;
  bool shut_down_ = false;
};

}  // namespace shapeid

#endif  // SHAPEID_SERVER_SERVER_H_
