// shapeid-server: flags (and SHAPEID_* environment variables) -> ServerOptions -> a running
// server, until SIGTERM or SIGINT; then a graceful shutdown and exit 0.

#include <unistd.h>

#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "absl/flags/flag.h"
#include "absl/flags/parse.h"
#include "absl/flags/reflection.h"
#include "absl/flags/usage.h"
#include "absl/strings/ascii.h"
#include "absl/strings/str_cat.h"
#include "absl/time/time.h"
#include "server/server.h"

ABSL_FLAG(std::string, listen, "127.0.0.1:50051",
          "HOST:PORT to listen on; port 0 picks a free port (printed at start). "
          "Env: SHAPEID_LISTEN");
ABSL_FLAG(int64_t, max_points_per_cloud, 10'000'000,
          "largest cloud, in points, any call accepts. Env: SHAPEID_MAX_POINTS_PER_CLOUD");
ABSL_FLAG(int32_t, max_message_bytes, 16 << 20,
          "largest single gRPC message (clouds stream in chunks, so this bounds a chunk). "
          "Env: SHAPEID_MAX_MESSAGE_BYTES");
ABSL_FLAG(std::string, data_dir, "shapeid-data",
          "directory where galleries persist (created if missing; one server per directory). "
          "Empty: keep galleries in memory only, lost at exit. Env: SHAPEID_DATA_DIR");
ABSL_FLAG(bool, set_aside_damaged, false,
          "start even if some gallery files are damaged: move them to <data_dir>/damaged/ and "
          "serve the rest (without it, a damaged gallery stops start-up with an error naming "
          "the file). Env: SHAPEID_SET_ASIDE_DAMAGED");
ABSL_FLAG(int64_t, approximate_min_vectors, 1'000'000,
          "search a gallery approximately (inverted lists over k-means cells, recall measured "
          "in docs/performance.md) once it holds this many vectors (samples x views); 0: every "
          "search exact. A Classify may still ask for an exact search. "
          "Env: SHAPEID_APPROXIMATE_MIN_VECTORS");
ABSL_FLAG(int32_t, approximate_lists, 0,
          "cells of the approximate index; 0: about sqrt(vectors). Env: SHAPEID_APPROXIMATE_LISTS");
ABSL_FLAG(int32_t, approximate_probes, 0,
          "cells an approximate search reads per query vector; 0: 32. More: better recall, "
          "slower. Env: SHAPEID_APPROXIMATE_PROBES");
ABSL_FLAG(int32_t, shutdown_grace_seconds, 10,
          "on SIGTERM/SIGINT, how long in-flight calls may run before they are cancelled. "
          "Env: SHAPEID_SHUTDOWN_GRACE_SECONDS");

namespace {

int g_stop_pipe[2] = {-1, -1};

void OnStopSignal(int signal) {
  const unsigned char byte = static_cast<unsigned char>(signal);
  [[maybe_unused]] const ssize_t written = write(g_stop_pipe[1], &byte, 1);  // async-signal-safe
}

// Every flag may come from SHAPEID_<FLAG NAME IN CAPITALS>; a command-line flag wins.
bool ApplyEnvironment() {
  for (const char* name :
       {"listen", "data_dir", "set_aside_damaged", "max_points_per_cloud", "max_message_bytes",
        "approximate_min_vectors", "approximate_lists", "approximate_probes",
        "shutdown_grace_seconds"}) {
    const std::string var = absl::StrCat("SHAPEID_", absl::AsciiStrToUpper(name));
    const char* value = std::getenv(var.c_str());
    if (value == nullptr) continue;
    std::string error;
    if (!absl::FindCommandLineFlag(name)->ParseFrom(value, &error)) {
      std::fprintf(stderr, "shapeid-server: %s=%s: %s\n", var.c_str(), value, error.c_str());
      return false;
    }
  }
  return true;
}

}  // namespace

int main(int argc, char** argv) {
  absl::SetProgramUsageMessage(
      "shapeid-server: the shapeid gRPC recognition server.\n"
      "Usage: shapeid-server [--listen=HOST:PORT] [--flag=value...]\n"
      "Every flag can also be set by an environment variable SHAPEID_<FLAG>; flags win.");
  if (!ApplyEnvironment()) return 2;
  absl::ParseCommandLine(argc, argv);

  shapeid::ServerOptions options;
  options.listen = absl::GetFlag(FLAGS_listen);
  if (absl::GetFlag(FLAGS_max_points_per_cloud) < 3 ||
      absl::GetFlag(FLAGS_max_message_bytes) < 1024) {
    std::fprintf(stderr,
                 "shapeid-server: --max_points_per_cloud must be >= 3 and "
                 "--max_message_bytes >= 1024\n");
    return 2;
  }
  options.service.max_points_per_cloud =
      static_cast<size_t>(absl::GetFlag(FLAGS_max_points_per_cloud));
  options.max_message_bytes = absl::GetFlag(FLAGS_max_message_bytes);
  options.data_dir = absl::GetFlag(FLAGS_data_dir);
  options.set_aside_damaged = absl::GetFlag(FLAGS_set_aside_damaged);
  options.gallery_limits.approximate.min_vectors = absl::GetFlag(FLAGS_approximate_min_vectors);
  options.gallery_limits.approximate.lists = absl::GetFlag(FLAGS_approximate_lists);
  options.gallery_limits.approximate.probes = absl::GetFlag(FLAGS_approximate_probes);
  if (const absl::Status s = shapeid::ValidateApproximateOptions(options.gallery_limits.approximate);
      !s.ok()) {
    std::fprintf(stderr, "shapeid-server: --approximate_*: %s\n", std::string(s.message()).c_str());
    return 2;
  }

  // gRPC may own threads whose signal mask we do not control, so a stop signal can land on
  // any thread: the handler only writes the signal number to a pipe that main waits on.
  if (pipe(g_stop_pipe) != 0) {
    std::perror("shapeid-server: pipe");
    return 1;
  }
  struct sigaction action = {};
  action.sa_handler = OnStopSignal;
  sigemptyset(&action.sa_mask);
  sigaction(SIGTERM, &action, nullptr);
  sigaction(SIGINT, &action, nullptr);

  auto server = shapeid::ShapeIdServer::Bind(options);
  if (!server.ok()) {
    std::fprintf(stderr, "shapeid-server: %s\n", std::string(server.status().message()).c_str());
    return 1;
  }
  // Listening already (health answers NOT_SERVING) while the galleries load.
  std::fprintf(stderr, "shapeid-server: bound %s; loading galleries from %s\n",
               (*server)->address().c_str(),
               options.data_dir.empty() ? "nowhere (in-memory)" : options.data_dir.c_str());
  absl::StatusOr<shapeid::LoadReport> loaded = (*server)->LoadGalleries();
  if (!loaded.ok()) {
    std::fprintf(stderr, "shapeid-server: %s\n", std::string(loaded.status().message()).c_str());
    if (loaded.status().code() == absl::StatusCode::kDataLoss ||
        loaded.status().code() == absl::StatusCode::kFailedPrecondition) {
      std::fprintf(stderr,
                   "shapeid-server: refusing to start rather than serve without that gallery. "
                   "Restore it from an export, or start with --set_aside_damaged to move it to "
                   "%s/damaged/ and serve the others.\n",
                   options.data_dir.c_str());
    }
    (*server)->Shutdown(absl::ZeroDuration());
    return 1;
  }
  for (const auto& aside : loaded->set_aside) {
    std::fprintf(stderr, "shapeid-server: WARNING: gallery '%s' set aside to %s: %s\n",
                 aside.name.c_str(), aside.moved_to.c_str(), aside.reason.c_str());
  }
  if (!loaded->persistent) {
    std::fprintf(stderr,
                 "shapeid-server: WARNING: --data_dir is empty: galleries live in memory only "
                 "and are lost when the server stops\n");
  }
  if (loaded->read_only) {
    std::fprintf(stderr,
                 "shapeid-server: WARNING: %s is read-only: galleries are served, every change "
                 "fails UNAVAILABLE\n",
                 options.data_dir.c_str());
  }
  std::fprintf(stderr, "shapeid-server: loaded %lld galleries (%lld samples) in %s\n",
               static_cast<long long>(loaded->galleries), static_cast<long long>(loaded->samples),
               absl::FormatDuration(loaded->elapsed).c_str());
  // The line scripts wait for: from here on, every RPC is served.
  std::printf("listening on %s\n", (*server)->address().c_str());
  std::fflush(stdout);

  unsigned char received = 0;
  while (read(g_stop_pipe[0], &received, 1) != 1) {
  }
  std::fprintf(stderr, "shapeid-server: %s, shutting down\n",
               received == SIGTERM ? "SIGTERM" : "SIGINT");
  (*server)->Shutdown(absl::Seconds(absl::GetFlag(FLAGS_shutdown_grace_seconds)));
  return 0;
}
