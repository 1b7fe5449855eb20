#ifndef SHAPEID_SERVER_SERVER_H_
#define SHAPEID_SERVER_SERVER_H_

#include <atomic>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "absl/time/time.h"
#include "core/gallery/gallery_learner.h"
#include "grpcpp/generic/async_generic_service.h"
#include "grpcpp/grpcpp.h"
#include "prometheus/exposer.h"
#include "server/calls/shapeid_service.h"
#include "server/ops/logger.h"
#include "server/ops/metrics.h"
#include "server/replication/replication_follower.h"
#include "server/server_options.h"
#include "server/storage/postgres_gallery_store.h"
#include "server/storage/sqlite_gallery_store.h"

namespace shapeid {

// The grpc.health.v1 service name that answers SERVING as long as the process runs and is not
// shutting down, for liveness probes; "" (every other name) is readiness: SERVING only while
// calls are served (loaded, not draining, the shared store reachable).
inline constexpr char kLivenessHealthService[] = "shapeid.liveness";

// What LoadGalleries found.
struct LoadReport {
  int64_t galleries = 0;
  int64_t samples = 0;
  absl::Duration elapsed;
  bool persistent = false;  // false: options.data_dir was empty
  bool read_only = false;   // the data directory is on a read-only file system
  // Where galleries live, for the start-up log: the data directory, "PostgreSQL
  // HOST:PORT/DB" (never a password), or empty (memory only).
  std::string store;
  std::vector<SqliteGalleryStore::SetAside> set_aside;
  // Galleries loaded but not writable (a full disk, a read-only file, an I/O error).
  std::vector<SqliteGalleryStore::ReadOnlyGallery> read_only_galleries;
};

// A running shapeid server: the ShapeId service over a gallery registry kept in a durable
// store, grpc.health.v1 health checking and server reflection, so grpcurl and standard probes
// work. Health and reflection need no API key (docs/security.md); health may also be served on
// a plaintext port of its own (ServerOptions::health_listen).
//
// Start-up is two steps so that probes can watch it: Bind opens the store (taking its lock)
// and listens, with health NOT_SERVING and every RPC refused UNAVAILABLE ("loading");
// LoadGalleries then loads every gallery and only if all load turns SERVING. Start does both.
class ShapeIdServer {
 public:
  // Bind, then LoadGalleries: returns a serving server (load_report() says what loaded).
  static absl::StatusOr<std::unique_ptr<ShapeIdServer>> Start(const ServerOptions& options);

  // Loads the API keys and TLS files (server/security/security.h), opens the store and binds.
  // FailedPrecondition for a non-loopback address with neither TLS nor keys (unless
  // options.security.insecure); InvalidArgument / NotFound for a bad key or TLS file;
  // Unavailable if the address cannot be bound; the store's errors (another server holds the
  // data directory: FailedPrecondition).
  static absl::StatusOr<std::unique_ptr<ShapeIdServer>> Bind(const ServerOptions& options);

  // Loads every stored gallery, then serves. On error (a damaged store, see
  // ServerOptions::set_aside_damaged) nothing is served; the caller should exit.
  absl::StatusOr<LoadReport> LoadGalleries();
  const LoadReport& load_report() const { return load_report_; }

  ~ShapeIdServer();

  // How callers are checked, for the start-up log: "TLS, 2 API keys (...)". No secrets.
  const std::string& security() const { return security_; }
  // Calls of the ShapeId service admitted and not yet done (streams until gRPC is done with
  // them, a moment after their answer).
  int64_t calls_in_flight() const { return service_->calls_in_flight(); }
  // "HOST:PORT" of the health-only port (ServerOptions::health_listen), or empty.
  const std::string& health_address() const { return health_address_; }
  // "HOST:PORT" of the Prometheus endpoint (ServerOptions::metrics.listen), or empty.
  const std::string& metrics_address() const { return metrics_address_; }
  // The server's log, for the embedding program's own lines (start-up, shutdown).
  const std::shared_ptr<Logger>& logger() const { return logger_; }
  ServerMetrics& metrics() { return *metrics_; }
  // Its workers and memory budget, for the start-up log and tests.
  const ShapeIdService& service() const { return *service_; }

  // "HOST:PORT" with the port actually bound (useful after listening on port 0).
  const std::string& address() const { return address_; }
  int port() const { return port_; }

  // Health turns NOT_SERVING; new calls are refused with UNAVAILABLE; calls in flight may
  // finish until `grace` has passed, then the rest are cancelled and the server stops.
  // Returns as soon as the last call ends. Idempotent.
  void Shutdown(absl::Duration grace);

 private:
  ShapeIdServer() = default;

  std::shared_ptr<SqliteGalleryStore> store_;             // null unless galleries live in data_dir
  std::shared_ptr<PostgresGalleryStore> postgres_store_;  // null unless options.store is set
  // Applies the other replicas' changes; with postgres_store_. Shared with the galleries'
  // catch-up function, which holds it weakly.
  std::shared_ptr<ReplicationFollower> follower_;
  std::string store_description_;
  std::shared_ptr<GalleryRegistry> registry_;
  std::unique_ptr<ShapeIdService> service_;
  // With options.learn, from LoadGalleries on; stopped first, before what it uses.
  std::optional<GalleryLearnerOptions> learner_options_;
  std::unique_ptr<GalleryLearner> learner_;
  // learner_ for the metrics' scrapes, which may come before it exists; it is stopped, never
  // destroyed, before the metrics' sources are cleared.
  std::atomic<const GalleryLearner*> learner_for_metrics_{nullptr};
  // Points the metrics at this server's state and, with `options.listen`, serves them.
  absl::Status StartMetrics(const MetricsOptions& options);
  // Sets the health of the main port and of the health-only port alike.
  void SetServing(bool serving);

  std::unique_ptr<grpc::Server> server_;
  // Only with options.health_listen; health_only_ answers its other methods and outlives it.
  std::unique_ptr<grpc::CallbackGenericService> health_only_;
  std::unique_ptr<grpc::Server> health_server_;
  std::string health_address_;
  std::shared_ptr<Logger> logger_;
  std::shared_ptr<ServerMetrics> metrics_;
  std::unique_ptr<prometheus::Exposer> exposer_;  // only with options.metrics.listen
  std::string metrics_address_;
  std::string address_;
  std::string security_;
  int port_ = 0;
  LoadReport load_report_;
  bool shut_down_ = false;
};

}  // namespace shapeid

#endif  // SHAPEID_SERVER_SERVER_H_
