#ifndef SHAPEID_SERVER_SERVER_H_
#define SHAPEID_SERVER_SERVER_H_

#include <memory>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "absl/time/time.h"
#include "grpcpp/grpcpp.h"
#include "server/server_options.h"
#include "server/shapeid_service.h"
#include "server/storage/sqlite_gallery_store.h"

namespace shapeid {

// What LoadGalleries found.
struct LoadReport {
  int64_t galleries = 0;
  int64_t samples = 0;
  absl::Duration elapsed;
  bool persistent = false;  // false: options.data_dir was empty
  bool read_only = false;   // the data directory is on a read-only file system
  std::vector<SqliteGalleryStore::SetAside> set_aside;
};

// A running shapeid server: the ShapeId service over a gallery registry kept in a durable
// store, grpc.health.v1 health checking and server reflection, so grpcurl and standard probes
// work.
//
// Start-up is two steps so that probes can watch it: Bind opens the store (taking its lock)
// and listens, with health NOT_SERVING and every RPC refused UNAVAILABLE ("loading");
// LoadGalleries then loads every gallery and only if all load turns SERVING. Start does both.
class ShapeIdServer {
 public:
  // Bind, then LoadGalleries: returns a serving server (load_report() says what loaded).
  static absl::StatusOr<std::unique_ptr<ShapeIdServer>> Start(const ServerOptions& options);

  // Opens the store and binds. Unavailable if the address cannot be bound; the store's
  // errors (another server holds the data directory: FailedPrecondition).
  static absl::StatusOr<std::unique_ptr<ShapeIdServer>> Bind(const ServerOptions& options);

  // Loads every stored gallery, then serves. On error (a damaged store, see
  // ServerOptions::set_aside_damaged) nothing is served; the caller should exit.
  absl::StatusOr<LoadReport> LoadGalleries();
  const LoadReport& load_report() const { return load_report_; }

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

  std::shared_ptr<SqliteGalleryStore> store_;  // null when not persistent
  std::shared_ptr<GalleryRegistry> registry_;
  std::unique_ptr<ShapeIdService> service_;
  std::unique_ptr<grpc::Server> server_;
  std::string address_;
  int port_ = 0;
  LoadReport load_report_;
  bool shut_down_ = false;
};

}  // namespace shapeid

#endif  // SHAPEID_SERVER_SERVER_H_
