#ifndef SHAPEID_CLIENT_CLIENT_OPTIONS_H_
#define SHAPEID_CLIENT_CLIENT_OPTIONS_H_

#include <cstddef>
#include <string>

#include "absl/time/time.h"

namespace shapeid {

// The largest answer the project's clients (this library, the shapeid CLI, the Python
// package's shapeid.MAX_RECEIVE_BYTES) accept by default: 256 MiB. A server sends at most its
// --max_answer_bytes (32 MiB by default), which it refuses to set above this, so every answer
// of a shapeid server can be read.
inline constexpr size_t kClientMaxReceiveBytes = size_t{256} << 20;

// The port a target without one gets: shapeid-server's default --listen port.
inline constexpr int kDefaultPort = 50051;

// How a Client reaches a shapeid server. Every field has a usable default.
struct ClientOptions {
  // Where the server is: one gRPC target, or a list of replicas.
  // A host without a port ("127.0.0.1", "[::1]", "::1", "localhost", "dns:///NAME", a list
  // entry) gets kDefaultPort.
  //  - One target: "HOST:PORT" (gRPC looks HOST up in DNS, again whenever connections fail),
  //    "dns:///NAME:PORT" (every A / AAAA record of NAME is a replica: the way to reach a set
  //    of replicas that changes, such as a Kubernetes headless Service), "unix:///PATH",
  //    "ipv4:A:P,B:P", or any other target gRPC knows.
  //  - A list: "HOST:PORT,HOST:PORT,..." (IPv6 in brackets, "[::1]:50051") or
  //    "unix:PATH,unix:PATH,...", never both kinds. Connect looks the host names up once
  //    (each address is a replica) and the list stays fixed for the Client's life. With TLS,
  //    every replica's certificate is checked against the first entry's host, so a list of
  //    different hosts needs tls_server_name (a name all their certificates carry).
  // Calls are spread over the replicas as `load_balancing` says.
  std::string target = "127.0.0.1:50051";

  // How calls are spread over the target's addresses:
  //  - "round_robin" (the default): a connection to each address, calls taken in turn by the
  //    replicas that are connected and SERVING (grpc.health.v1, watched on each connection).
  //    A replica that is down, still loading its galleries or shutting down gets no calls,
  //    and a call that one refused UNAVAILABLE (or cancelled) is retried on another. When no
  //    replica serves, calls fail UNAVAILABLE in the client ("backend unhealthy" when some
  //    are up but loading) without reaching a server. Health is watched only for a list or
  //    a "dns:" target: a client of one server reaches it whatever its state, and gets its
  //    own reason for a refusal ("loading its galleries").
  //  - "pick_first": one connection, to the first address that answers, used for every call
  //    until it breaks; then the next address that answers. Spreads nothing: for a primary
  //    with standbys. Health is not watched: a retry may go back to the same server.
  std::string load_balancing = "round_robin";

  // Budget of one call, retries and backoff included. A call still running when it runs out
  // fails with DEADLINE_EXCEEDED and the server stops the work.
  absl::Duration deadline = absl::Seconds(30);

  // Attempts per call while the server answers UNAVAILABLE or cancels the call (as one that
  // shuts down does to calls it has not started); 1: no retry. Only calls that are safe
  // to repeat are retried: Describe, Classify, GetGallery, ListGalleries, ListDescriptors,
  // GetServerStats, SetLogLevel (setting a level twice is setting it once), CheckHealth,
  // ExportGallery until its first chunk reached the caller, and Train when every sample
  // carries a client-chosen id (so a repeated stream cannot add a sample twice).
  // CreateGallery, DeleteGallery, RemoveSamples and ImportGallery are sent once.
  //
  // A retried Train may find its first attempt committed after all (the server added the
  // samples, then the answer was lost). Train is all-or-nothing, so the retry then fails
  // ALREADY_EXISTS on a sample id; the client cannot tell that apart from ids another call
  // took, so it returns that ALREADY_EXISTS, its message saying that an earlier attempt
  // got no answer and may have committed the samples (check the gallery before training
  // them again).
  //
  // RESOURCE_EXHAUSTED is returned at once, also when the server was only busy (its memory
  // budget, a queue or the caller's backlog full): only the message tells busy from a size
  // limit that never succeeds, and a busy server stays busy longer than this backoff. Retry
  // those later, from the caller (docs/cli.md, "Busy servers").
  int max_attempts = 3;

  // Wait before the second attempt; doubled before each further one (bounded by the deadline).
  // Under round_robin a retry goes to another replica, and a replica stops getting calls as
  // soon as it reports NOT_SERVING or its connection drops: one going down costs this wait
  // to the call or two sent to it just then, not a wait per call.
  absl::Duration initial_backoff = absl::Milliseconds(100);

  // The largest answer this client reads, in bytes (1 to 2^31 - 1). A larger one fails
  // RESOURCE_EXHAUSTED in this client, whatever the server did: IsClientReceiveLimit (client.h)
  // tells it from a server's refusal. The default reads any answer a shapeid server sends.
  size_t max_receive_bytes = kClientMaxReceiveBytes;

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

  // Sent with every call, retries included, as the metadata "x-request-id": the server writes
  // it in its log line of the call and sends it back, so one id finds every call of a job in
  // the logs of every replica. 1 to 128 characters of A-Z a-z 0-9 . _ : / + = - (Connect
  // refuses anything else: the server would replace it). Empty (the default): none is sent,
  // and the server makes a random id for each call.
  std::string request_id;

  // Sent with every call as the metadata "shapeid-caller-id": on a server without API keys
  // this client is then a caller of its own ("HOST/ID") for the server's fair shares, rather
  // than one with every other process of its host (a fleet of robots on one machine: give
  // each its own id). With a key or a client certificate it changes nothing: the key is the
  // caller. 1 to 64 characters of A-Z a-z 0-9 . _ : - (Connect refuses anything else).
  // Empty: none.
  std::string caller_id;
};

}  // namespace shapeid

#endif  // SHAPEID_CLIENT_CLIENT_OPTIONS_H_
