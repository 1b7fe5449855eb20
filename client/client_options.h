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

  // Transport security: reserved. Connections are plaintext until the security issue lands
  // TLS options here.
};

}  // namespace shapeid

#endif  // SHAPEID_CLIENT_CLIENT_OPTIONS_H_
