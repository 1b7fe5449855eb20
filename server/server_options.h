#ifndef SHAPEID_SERVER_SERVER_OPTIONS_H_
#define SHAPEID_SERVER_SERVER_OPTIONS_H_

#include <string>

#include "server/service_options.h"

namespace shapeid {

// Everything `shapeid-server` is started with; main.cc fills it from flags and SHAPEID_*
// environment variables.
struct ServerOptions {
  // HOST:PORT to listen on. Port 0 lets the system pick (the chosen one is in
  // ShapeIdServer::address()). The loopback default keeps a laptop's server private.
  std::string listen = "127.0.0.1:50051";
  // Largest single gRPC message. Clouds stream in chunks, so this bounds one chunk, not a
  // cloud; 16 MiB leaves clients room for chunks far above the recommended 192 KiB.
  int max_message_bytes = 16 << 20;
  // Threads serving calls; 0: gRPC's default (one per core).
  int worker_threads = 0;
  ServiceOptions service;
};

}  // namespace shapeid

#endif  // SHAPEID_SERVER_SERVER_OPTIONS_H_
