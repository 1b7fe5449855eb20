#ifndef SHAPEID_CLIENT_CLIENT_OPTIONS_H_
#define SHAPEID_CLIENT_CLIENT_OPTIONS_H_

#include <cstddef>
#include <string>

#include "absl/time/time.h"

namespace shapeid {

// How a Client reaches a shapeid server. Every field has a usable default.
struct ClientOptions {
  // gRPC target: "HOST:PORT", "dns:///host:port", "unix:///path"...
  std::string target = "127.0.0.1:50051";

  // Budget of one call, retries and backoff included. A call still running when it runs out
  // fails with DEADLINE_EXCEEDED and the server stops the work.
  absl::Duration deadline = absl::Seconds(30);

  // Attempts per call when the server is UNAVAILABLE (1: no retry). Only calls that are safe
  // to repeat are retried: Describe, Classify, GetGallery, ListGalleries, ListDescriptors,
  // CheckHealth, ExportGallery until its first chunk reached the caller, and Train when every
  // sample carries a client-chosen id (so a repeated stream cannot add a sample twice).
  // CreateGallery, DeleteGallery, RemoveSamples and ImportGallery are sent once.
  int max_attempts = 3;

  // Wait before the second attempt; doubled before each further one (bounded by the deadline).
  absl::Duration initial_backoff = absl::Milliseconds(100);

  // Points per PointChunk message. The proto recommends 16,384 (192 KiB): far below any
  // message limit, large enough that per-message cost is negligible. Must be >= 1.
  size_t chunk_points = 16384;

  // Transport security (docs/security.md). TLS is on when `tls` is true or any file below
  // is given; otherwise the channel is plaintext, which a server with --tls_cert refuses.
  bool tls = false;
  // PEM file of the CA certificates that may sign the server's certificate. Empty: the
  // system's roots (or the file GRPC_DEFAULT_SSL_ROOTS_FILE_PATH names).
  std::string tls_ca_file;
  // PEM files of this client's certificate (chain) and private key, for a server that
  // requires client certificates (mutual TLS). Both or neither.
  std::string tls_cert_file;
  std::string tls_key_file;
  // The name the server's certificate must carry when it is not the target's host (a tunnel,
  // an IP address the certificate does not list). Empty: the target's host.
  std::string tls_server_name;

  // API key sent with every call as "authorization: Bearer KEY" (a server with API keys
  // answers UNAUTHENTICATED without one, PERMISSION_DENIED when its scope is too small).
  // Empty: none. Never put in an error message. Over plaintext on a network it can be read
  // by anyone on the path: use TLS.
  std::string api_key;
};

}  // namespace shapeid

#endif  // SHAPEID_CLIENT_CLIENT_OPTIONS_H_
