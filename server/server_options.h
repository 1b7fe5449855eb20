#ifndef SHAPEID_SERVER_SERVER_OPTIONS_H_
#define SHAPEID_SERVER_SERVER_OPTIONS_H_

#include <string>

#include "absl/time/time.h"
#include "core/gallery/gallery_learner.h"
#include "core/gallery/gallery_options.h"
#include "server/calls/service_options.h"
#include "server/ops/logger.h"
#include "server/ops/metrics.h"
#include "server/security/security_options.h"

namespace shapeid {

// Everything `shapeid-server` is started with; main.cc fills it from flags and SHAPEID_*
// environment variables.
struct ServerOptions {
  // HOST:PORT to listen on. Port 0 lets the system pick (the chosen one is in
  // ShapeIdServer::address()). The loopback default keeps a laptop's server private.
  std::string listen = "127.0.0.1:50051";
  // HOST:PORT of a second, plaintext port that serves only grpc.health.v1 (no keys, no TLS),
  // mirroring the main port's status. Empty, the default: none. For Kubernetes' native gRPC
  // probes, which can speak neither TLS nor send metadata, when `listen` has TLS. It tells
  // anyone who reaches it only SERVING or NOT_SERVING.
  std::string health_listen;
  // Largest single gRPC message. Clouds stream in chunks, so this bounds one chunk, not a
  // cloud; 16 MiB leaves clients room for chunks far above the recommended 192 KiB.
  int max_message_bytes = 16 << 20;
  // Where galleries persist (server/storage/sqlite_gallery_store.h); created if missing.
  // Empty, the default for embedding (tests, benchmarks): galleries live in memory only and
  // are lost when the server stops. shapeid-server's --data_dir defaults to "shapeid-data".
  std::string data_dir;
  // Start even if some gallery files cannot be loaded, moving them to <data_dir>/damaged/
  // (reported at start-up). Off by default: a damaged store stops the server, so that no
  // gallery silently disappears from service.
  bool set_aside_damaged = false;
  // A shared store instead of data_dir: "postgres://..." or "postgresql://..." (any libpq
  // connection string starting so) keeps galleries in PostgreSQL, which any number of
  // replicas share (server/storage/postgres_gallery_store.h); data_dir is then unused. Empty,
  // the default: data_dir.
  std::string store;
  // How stale a replica over PostgreSQL may get: other replicas' changes arrive by
  // LISTEN/NOTIFY at once and by polling at least this often, and a replica that has not
  // reached PostgreSQL for this long stops serving (health NOT_SERVING, calls UNAVAILABLE)
  // until it is back and caught up.
  absl::Duration store_refresh = absl::Seconds(1);
  // TLS, API keys, and whether a server open to the network may start (docs/security.md).
  SecurityOptions security;
  ServiceOptions service;
  // Points per cloud (every RPC's), samples per gallery and number of galleries.
  GalleryLimits gallery_limits;
  // Fit every gallery a trained head in the background (core/gallery/gallery_learner.h), with
  // these options. Off by default for embedding (tests, benchmarks: answers that stay the
  // kNN vote's); shapeid-server's --learn defaults to mlp.
  bool learn = false;
  GalleryLearnerOptions learner;
  // The log (a line per call at info) and the Prometheus endpoint (docs/operations.md).
  LoggerOptions log;
  MetricsOptions metrics;
};

}  // namespace shapeid

#endif  // SHAPEID_SERVER_SERVER_OPTIONS_H_
