// shapeid-server: flags (and SHAPEID_* environment variables) -> ServerOptions -> a running
// server, until SIGTERM or SIGINT; then a graceful shutdown and exit 0.

#include <unistd.h>

#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <string>
#include <vector>

#include "absl/flags/flag.h"
#include "absl/flags/parse.h"
#include "absl/flags/reflection.h"
#include "absl/flags/usage.h"
#include "absl/strings/ascii.h"
#include "absl/strings/str_cat.h"
#include "absl/time/time.h"
#include "client/client_options.h"
#include "core/gallery/gallery_options.h"
#include "server/security/api_keys.h"
#include "server/security/security.h"
#include "server/server.h"

ABSL_FLAG(std::string, listen, "127.0.0.1:50051",
          "HOST:PORT to listen on; port 0 picks a free port (printed at start). "
          "Env: SHAPEID_LISTEN");
ABSL_FLAG(std::string, health_listen, "",
          "HOST:PORT of a second, plaintext port serving only grpc.health.v1 (no key, no TLS), "
          "for probes that cannot do TLS (Kubernetes' gRPC probes). Empty: none. "
          "Env: SHAPEID_HEALTH_LISTEN");
ABSL_FLAG(int64_t, max_points_per_cloud,
          static_cast<int64_t>(shapeid::GalleryLimits{}.max_points_per_cloud),
          "largest cloud, in points, any call accepts. Env: SHAPEID_MAX_POINTS_PER_CLOUD");
ABSL_FLAG(int32_t, max_message_bytes, 16 << 20,
          "largest single gRPC message (clouds stream in chunks, so this bounds a chunk). "
          "Env: SHAPEID_MAX_MESSAGE_BYTES");
ABSL_FLAG(int64_t, max_answer_bytes, 32 << 20,
          "largest answer the server sends: ListSamples pages are cut to fit it, a larger "
          "answer is refused RESOURCE_EXHAUSTED saying what to ask for instead. 1 MiB to "
          "256 MiB (the project's clients read answers up to 256 MiB). "
          "Env: SHAPEID_MAX_ANSWER_BYTES");
ABSL_FLAG(std::string, data_dir, "shapeid-data",
          "directory where galleries persist (created if missing; one server per directory). "
          "Empty: keep galleries in memory only, lost at exit. Env: SHAPEID_DATA_DIR");
ABSL_FLAG(std::string, store, "",
          "where galleries live instead of --data_dir: a PostgreSQL connection URI, "
          "postgres://[user@]host[:port]/database[?sslmode=...], shared by any number of "
          "replicas (docs/scaling.md). Put the password in PGPASSWORD or ~/.pgpass, not here. "
          "Empty: --data_dir. Env: SHAPEID_STORE");
ABSL_FLAG(int32_t, store_refresh_ms, 1000,
          "with --store=postgres: other replicas' changes arrive at once (LISTEN/NOTIFY) and at "
          "most this late by polling; a replica that cannot reach PostgreSQL for this long "
          "answers UNAVAILABLE (health NOT_SERVING) until it is back. Env: "
          "SHAPEID_STORE_REFRESH_MS");
ABSL_FLAG(bool, set_aside_damaged, false,
          "start even if some gallery files are damaged: move them to <data_dir>/damaged/ and "
          "serve the rest (without it, a damaged gallery stops start-up with an error naming "
          "the file). Env: SHAPEID_SET_ASIDE_DAMAGED");
ABSL_FLAG(int64_t, approximate_min_vectors, shapeid::ApproximateOptions::kServedMinVectors,
          "search a gallery approximately (inverted lists over k-means cells, recall measured "
          "in docs/performance.md) once it holds this many vectors (samples x views); 0: every "
          "search exact. A Classify may still ask for an exact search. "
          "Env: SHAPEID_APPROXIMATE_MIN_VECTORS");
ABSL_FLAG(int32_t, approximate_lists, 0,
          "cells of the approximate index; 0: about sqrt(vectors). Env: SHAPEID_APPROXIMATE_LISTS");
ABSL_FLAG(int32_t, approximate_probes, 0,
          "cells an approximate search reads per query vector; 0: 32. More: better recall, "
          "slower. Env: SHAPEID_APPROXIMATE_PROBES");
ABSL_FLAG(int64_t, max_samples_per_gallery, 1'000'000,
          "samples one gallery may hold (training and import past it: RESOURCE_EXHAUSTED). "
          "Env: SHAPEID_MAX_SAMPLES_PER_GALLERY");
ABSL_FLAG(int64_t, max_galleries, 1024,
          "galleries the server may hold. Env: SHAPEID_MAX_GALLERIES");
ABSL_FLAG(int64_t, max_samples_per_train, 10'000,
          "samples one Train stream may carry; 0: no limit. Env: SHAPEID_MAX_SAMPLES_PER_TRAIN");
ABSL_FLAG(int32_t, max_streams_per_client, 64,
          "streams one client (IP address) may have open at once; 0: no limit. "
          "Env: SHAPEID_MAX_STREAMS_PER_CLIENT");
ABSL_FLAG(int32_t, max_call_seconds, 600,
          "a stream still running after this long (its client asked for a later deadline, or "
          "none) is ended DEADLINE_EXCEEDED; 0: no limit. Env: SHAPEID_MAX_CALL_SECONDS");
ABSL_FLAG(std::string, learn, "mlp",
          "mlp: fit every gallery of 20 samples or more, of two labels or more, a trained head "
          "in the background once it has been quiet for 2 s (a small network over its vectors, "
          "at the lowest CPU priority, inside the memory budget), which then answers Classify "
          "with the kNN vote; off: the kNN vote alone. Env: SHAPEID_LEARN");
ABSL_FLAG(int64_t, memory_budget_mib, 0,
          "memory calls may hold beyond the galleries: clouds in transit and describing's "
          "working memory. A call past it is refused RESOURCE_EXHAUSTED (or its work waits for "
          "memory others give back); one caller may hold --memory_caller_share of it. 0: half "
          "of the memory the process may use (its cgroup limit, else the machine's). "
          "Env: SHAPEID_MEMORY_BUDGET_MIB");
ABSL_FLAG(double, memory_caller_share, 0.5,
          "the part of --memory_budget_mib one caller (an API key, else a client host) may "
          "hold, in (0, 1]. Env: SHAPEID_MEMORY_CALLER_SHARE");
ABSL_FLAG(int32_t, workers, 0,
          "threads for cheap work (describing and searching small clouds); 0: one per core the "
          "process may use (its CPUs, capped by its cgroup's CPU quota), at least 2. "
          "Env: SHAPEID_WORKERS");
ABSL_FLAG(int32_t, heavy_workers, 0,
          "threads for heavy work (huge clouds, huge galleries), at a lower OS priority; 0: "
          "three quarters of the cores, at least 1, always one fewer than the cores. "
          "Env: SHAPEID_HEAVY_WORKERS");
ABSL_FLAG(int32_t, store_workers, 2,
          "threads for writes to the gallery store. Env: SHAPEID_STORE_WORKERS");
ABSL_FLAG(int32_t, heavy_work_ms, 20,
          "work estimated to take this much CPU time or more is heavy. Env: SHAPEID_HEAVY_WORK_MS");
ABSL_FLAG(int64_t, max_queued_work, 4096,
          "pieces of work that may wait in one lane; more is refused RESOURCE_EXHAUSTED. "
          "Env: SHAPEID_MAX_QUEUED_WORK");
ABSL_FLAG(int32_t, max_caller_backlog_seconds, 120,
          "estimated CPU time of work one caller may have waiting; more is refused "
          "RESOURCE_EXHAUSTED. Env: SHAPEID_MAX_CALLER_BACKLOG_SECONDS");
ABSL_FLAG(std::string, tls_cert, "",
          "PEM certificate (chain) of the server: with --tls_key, serve TLS only. "
          "Env: SHAPEID_TLS_CERT");
ABSL_FLAG(std::string, tls_key, "", "PEM private key of --tls_cert. Env: SHAPEID_TLS_KEY");
ABSL_FLAG(std::string, tls_client_ca, "",
          "PEM CA certificates for mutual TLS: every client must present a certificate they "
          "sign. Env: SHAPEID_TLS_CLIENT_CA");
ABSL_FLAG(std::string, api_keys_file, "",
          "file of API keys, one per line: NAME SCOPE SHA256-HEX (scope read, write or admin; "
          "see --new_api_key). Given, every call but health checks needs a key. "
          "Env: SHAPEID_API_KEYS_FILE");
ABSL_FLAG(std::string, api_keys, "",
          "API keys inline, as in --api_keys_file, entries separated by ';' or newlines. "
          "Env: SHAPEID_API_KEYS");
ABSL_FLAG(bool, insecure, false,
          "allow listening on a non-loopback address with neither TLS nor API keys (open to "
          "anyone who reaches the port). Env: SHAPEID_INSECURE");
ABSL_FLAG(std::string, new_api_key, "",
          "NAME:SCOPE: print a new random API key (line 1, for the client) and its line for "
          "the keys file (line 2), then exit");
ABSL_FLAG(bool, hash_api_key, false,
          "read an API key from stdin, print its SHA-256 (the keys file's third field), exit");
ABSL_FLAG(std::string, metrics_listen, "",
          "HOST:PORT of a plaintext HTTP endpoint serving Prometheus metrics at /metrics (no key, "
          "no TLS: it shows call counts, latencies, gallery names and sizes, never points or "
          "keys). Empty: none; 9464 is the usual port. Env: SHAPEID_METRICS_LISTEN");
ABSL_FLAG(int32_t, metrics_max_galleries, 50,
          "galleries that get a `gallery` label of their own in the metrics; later ones are "
          "counted together as gallery=\"_other\" (bounds the series a Prometheus stores). "
          "Env: SHAPEID_METRICS_MAX_GALLERIES");
ABSL_FLAG(std::string, log_format, "text",
          "text (lines for people) or json (one JSON object per line, for a log pipeline). "
          "Env: SHAPEID_LOG_FORMAT");
ABSL_FLAG(std::string, log_level, "info",
          "debug, info (a line per call), warning (failed calls and warnings) or error; change it "
          "while running with `shapeid log-level`. Env: SHAPEID_LOG_LEVEL");
ABSL_FLAG(int32_t, shutdown_grace_seconds, 10,
          "on SIGTERM/SIGINT, how long in-flight calls may run before they are cancelled. "
          "Env: SHAPEID_SHUTDOWN_GRACE_SECONDS");

namespace {

// The smallest --max_answer_bytes: far above one sample with the largest provenance
// (core/gallery/sample_provenance.h: 8 KiB of source and metadata), or one neighbor.
constexpr int64_t kMinAnswerBytes = 1 << 20;

int g_stop_pipe[2] = {-1, -1};

void OnStopSignal(int signal) {
  const unsigned char byte = static_cast<unsigned char>(signal);
  [[maybe_unused]] const ssize_t written = write(g_stop_pipe[1], &byte, 1);  // async-signal-safe
}

// Every flag may come from SHAPEID_<FLAG NAME IN CAPITALS>; a command-line flag wins.
bool ApplyEnvironment() {
  for (const char* name : {"listen",
                           "health_listen",
                           "data_dir",
                           "store",
                           "store_refresh_ms",
                           "set_aside_damaged",
                           "max_points_per_cloud",
                           "max_message_bytes",
                           "max_answer_bytes",
                           "approximate_min_vectors",
                           "approximate_lists",
                           "approximate_probes",
                           "max_samples_per_gallery",
                           "max_galleries",
                           "max_samples_per_train",
                           "max_streams_per_client",
                           "max_call_seconds",
                           "learn",
                           "memory_budget_mib",
                           "memory_caller_share",
                           "workers",
                           "heavy_workers",
                           "store_workers",
                           "heavy_work_ms",
                           "max_queued_work",
                           "max_caller_backlog_seconds",
                           "tls_cert",
                           "tls_key",
                           "tls_client_ca",
                           "api_keys_file",
                           "api_keys",
                           "insecure",
                           "shutdown_grace_seconds",
                           "metrics_listen",
                           "metrics_max_galleries",
                           "log_format",
                           "log_level"}) {
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

// --new_api_key=NAME:SCOPE. The key goes to stdout only; it is stored nowhere.
int PrintNewApiKey(const std::string& spec) {
  const size_t colon = spec.find(':');
  if (colon == std::string::npos) {
    std::fprintf(stderr, "shapeid-server: --new_api_key=NAME:SCOPE, e.g. robot-1:read\n");
    return 2;
  }
  absl::StatusOr<std::string> key = shapeid::NewApiKey();
  if (!key.ok()) {
    std::fprintf(stderr, "shapeid-server: %s\n", std::string(key.status().message()).c_str());
    return 1;
  }
  const std::string line = absl::StrCat(spec.substr(0, colon), " ", spec.substr(colon + 1), " ",
                                        shapeid::Sha256Hex(*key));
  // Checked as the server will read it: name and scope.
  if (absl::StatusOr<std::vector<shapeid::ApiKeyEntry>> parsed =
          shapeid::ParseApiKeys(line, "--new_api_key");
      !parsed.ok()) {
    std::fprintf(stderr, "shapeid-server: %s\n", std::string(parsed.status().message()).c_str());
    return 2;
  }
  std::printf("%s\n%s\n", key->c_str(), line.c_str());
  std::fprintf(stderr,
               "shapeid-server: line 1 is the key: give it to the client (SHAPEID_API_KEY); it "
               "is shown once and stored nowhere. Line 2 goes in the keys file "
               "(--api_keys_file) or SHAPEID_API_KEYS.\n");
  return 0;
}

// --hash_api_key: the key from stdin (one trailing newline dropped), its SHA-256 to stdout.
int PrintKeyHash() {
  std::string key;
  char buf[4096];
  size_t n;
  while ((n = std::fread(buf, 1, sizeof(buf), stdin)) > 0 && key.size() < (1 << 16)) {
    key.append(buf, n);
  }
  if (!key.empty() && key.back() == '\n') key.pop_back();
  if (!key.empty() && key.back() == '\r') key.pop_back();
  for (char c : key) {
    if (c <= ' ' || c == 0x7f) {
      std::fprintf(stderr,
                   "shapeid-server: --hash_api_key: the key holds a space or control character; "
                   "clients could not send it\n");
      return 2;
    }
  }
  if (key.size() < shapeid::kMinApiKeyChars) {
    std::fprintf(stderr,
                 "shapeid-server: --hash_api_key: the key has %zu characters; use at least %zu "
                 "random ones (--new_api_key makes one)\n",
                 key.size(), shapeid::kMinApiKeyChars);
    return 2;
  }
  std::printf("%s\n", shapeid::Sha256Hex(key).c_str());
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  absl::SetProgramUsageMessage(
      "shapeid-server: the shapeid gRPC recognition server.\n"
      "Usage: shapeid-server [--listen=HOST:PORT] [--flag=value...]\n"
      "Every flag can also be set by an environment variable SHAPEID_<FLAG>; flags win.");
  if (!ApplyEnvironment()) return 2;
  absl::ParseCommandLine(argc, argv);
  if (!absl::GetFlag(FLAGS_new_api_key).empty()) {
    return PrintNewApiKey(absl::GetFlag(FLAGS_new_api_key));
  }
  if (absl::GetFlag(FLAGS_hash_api_key)) return PrintKeyHash();

  shapeid::ServerOptions options;
  options.listen = absl::GetFlag(FLAGS_listen);
  options.health_listen = absl::GetFlag(FLAGS_health_listen);
  if (absl::GetFlag(FLAGS_max_points_per_cloud) < 3 ||
      absl::GetFlag(FLAGS_max_message_bytes) < 1024) {
    std::fprintf(stderr,
                 "shapeid-server: --max_points_per_cloud must be >= 3 and "
                 "--max_message_bytes >= 1024\n");
    return 2;
  }
  options.gallery_limits.max_points_per_cloud =
      static_cast<size_t>(absl::GetFlag(FLAGS_max_points_per_cloud));
  options.max_message_bytes = absl::GetFlag(FLAGS_max_message_bytes);
  if (absl::GetFlag(FLAGS_max_answer_bytes) < kMinAnswerBytes ||
      absl::GetFlag(FLAGS_max_answer_bytes) >
          static_cast<int64_t>(shapeid::kClientMaxReceiveBytes)) {
    std::fprintf(stderr,
                 "shapeid-server: --max_answer_bytes must be from %lld (1 MiB, more than one "
                 "sample with the largest provenance) to %zu (256 MiB, the most the project's "
                 "clients read); got %lld\n",
                 static_cast<long long>(kMinAnswerBytes), shapeid::kClientMaxReceiveBytes,
                 static_cast<long long>(absl::GetFlag(FLAGS_max_answer_bytes)));
    return 2;
  }
  options.service.max_answer_bytes = static_cast<size_t>(absl::GetFlag(FLAGS_max_answer_bytes));
  options.data_dir = absl::GetFlag(FLAGS_data_dir);
  options.store = absl::GetFlag(FLAGS_store);
  if (absl::GetFlag(FLAGS_store_refresh_ms) < 10) {
    std::fprintf(stderr, "shapeid-server: --store_refresh_ms must be >= 10\n");
    return 2;
  }
  options.store_refresh = absl::Milliseconds(absl::GetFlag(FLAGS_store_refresh_ms));
  options.set_aside_damaged = absl::GetFlag(FLAGS_set_aside_damaged);
  options.gallery_limits.approximate.min_vectors = absl::GetFlag(FLAGS_approximate_min_vectors);
  options.gallery_limits.approximate.lists = absl::GetFlag(FLAGS_approximate_lists);
  options.gallery_limits.approximate.probes = absl::GetFlag(FLAGS_approximate_probes);
  if (const absl::Status s =
          shapeid::ValidateApproximateOptions(options.gallery_limits.approximate);
      !s.ok()) {
    std::fprintf(stderr, "shapeid-server: --approximate_*: %s\n", std::string(s.message()).c_str());
    return 2;
  }
  if (absl::GetFlag(FLAGS_max_samples_per_gallery) < 1 || absl::GetFlag(FLAGS_max_galleries) < 1 ||
      absl::GetFlag(FLAGS_max_samples_per_train) < 0 ||
      absl::GetFlag(FLAGS_max_streams_per_client) < 0 ||
      absl::GetFlag(FLAGS_max_call_seconds) < 0) {
    std::fprintf(stderr,
                 "shapeid-server: --max_samples_per_gallery and --max_galleries must be >= 1; "
                 "--max_samples_per_train, --max_streams_per_client and --max_call_seconds >= 0 "
                 "(0: no limit)\n");
    return 2;
  }
  options.gallery_limits.max_samples_per_gallery = absl::GetFlag(FLAGS_max_samples_per_gallery);
  options.gallery_limits.max_galleries = static_cast<size_t>(absl::GetFlag(FLAGS_max_galleries));
  options.service.max_samples_per_train = absl::GetFlag(FLAGS_max_samples_per_train);
  options.service.max_streams_per_client = absl::GetFlag(FLAGS_max_streams_per_client);
  options.service.max_call = absl::Seconds(absl::GetFlag(FLAGS_max_call_seconds));
  if (absl::GetFlag(FLAGS_memory_budget_mib) < 0 ||
      !(absl::GetFlag(FLAGS_memory_caller_share) > 0) ||
      absl::GetFlag(FLAGS_memory_caller_share) > 1 || absl::GetFlag(FLAGS_workers) < 0 ||
      absl::GetFlag(FLAGS_heavy_workers) < 0 || absl::GetFlag(FLAGS_store_workers) < 1 ||
      absl::GetFlag(FLAGS_heavy_work_ms) < 1 || absl::GetFlag(FLAGS_max_queued_work) < 1 ||
      absl::GetFlag(FLAGS_max_caller_backlog_seconds) < 1) {
    std::fprintf(stderr,
                 "shapeid-server: --memory_budget_mib, --workers and --heavy_workers must be >= 0 "
                 "(0: automatic); --memory_caller_share in (0, 1]; --store_workers, "
                 "--heavy_work_ms, --max_queued_work and --max_caller_backlog_seconds >= 1\n");
    return 2;
  }
  options.service.memory_budget_bytes = static_cast<size_t>(absl::GetFlag(FLAGS_memory_budget_mib))
                                        << 20;
  options.service.memory_caller_share = absl::GetFlag(FLAGS_memory_caller_share);
  const std::string learn = absl::GetFlag(FLAGS_learn);
  if (learn != "mlp" && learn != "off") {
    std::fprintf(stderr, "shapeid-server: --learn=%s: use mlp or off\n", learn.c_str());
    return 2;
  }
  options.learn = learn == "mlp";
  options.service.work.cheap_workers = absl::GetFlag(FLAGS_workers);
  options.service.work.heavy_workers = absl::GetFlag(FLAGS_heavy_workers);
  options.service.work.store_workers = absl::GetFlag(FLAGS_store_workers);
  options.service.work.heavy_cost = absl::Milliseconds(absl::GetFlag(FLAGS_heavy_work_ms));
  options.service.work.max_queued = absl::GetFlag(FLAGS_max_queued_work);
  options.service.work.max_caller_backlog =
      absl::Seconds(absl::GetFlag(FLAGS_max_caller_backlog_seconds));
  options.security.tls_cert_file = absl::GetFlag(FLAGS_tls_cert);
  options.security.tls_key_file = absl::GetFlag(FLAGS_tls_key);
  options.security.tls_client_ca_file = absl::GetFlag(FLAGS_tls_client_ca);
  options.security.api_keys_file = absl::GetFlag(FLAGS_api_keys_file);
  options.security.api_keys = absl::GetFlag(FLAGS_api_keys);
  options.security.insecure = absl::GetFlag(FLAGS_insecure);
  options.metrics.listen = absl::GetFlag(FLAGS_metrics_listen);
  options.metrics.max_gallery_labels = absl::GetFlag(FLAGS_metrics_max_galleries);
  if (options.metrics.max_gallery_labels < 0) {
    std::fprintf(stderr, "shapeid-server: --metrics_max_galleries must be >= 0\n");
    return 2;
  }
  {
    const absl::StatusOr<shapeid::LogFormat> format =
        shapeid::ParseLogFormat(absl::GetFlag(FLAGS_log_format));
    const absl::StatusOr<shapeid::LogLevel> level =
        shapeid::ParseLogLevel(absl::GetFlag(FLAGS_log_level));
    if (!format.ok() || !level.ok()) {
      std::fprintf(stderr, "shapeid-server: --log_format / --log_level: %s\n",
                   std::string((format.ok() ? level.status() : format.status()).message()).c_str());
      return 2;
    }
    options.log.format = *format;
    options.log.level = *level;
  }
  // Configuration errors are usage errors (exit 2), told before anything is opened; Bind
  // checks the same again.
  absl::StatusOr<std::shared_ptr<const shapeid::ApiKeyStore>> keys =
      shapeid::LoadApiKeys(options.security);
  absl::Status config = keys.status();
  if (config.ok()) {
    config = shapeid::CheckExposure(options.listen, options.security, !(*keys)->empty());
  }
  if (config.ok()) config = shapeid::ListeningCredentials(options.security).status();
  if (!config.ok()) {
    std::fprintf(stderr, "shapeid-server: %s\n", std::string(config.message()).c_str());
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
  const std::string where =
      !options.store.empty()
          ? absl::StrCat("PostgreSQL ", shapeid::DescribeConninfo(options.store))
          : (options.data_dir.empty() ? "nowhere (in-memory)" : options.data_dir);
  const shapeid::Logger& log = *(*server)->logger();
  log.Info(absl::StrCat("bound ", (*server)->address(), "; loading galleries from ", where));
  log.Info(absl::StrCat("security: ", (*server)->security()));
  {
    const shapeid::ShapeIdService& service = (*server)->service();
    const auto workers = [&](shapeid::WorkLane lane) {
      return service.scheduler().stats(lane).workers;
    };
    log.Info(absl::StrCat("workers: ", workers(shapeid::WorkLane::kCheap), " cheap, ",
                          workers(shapeid::WorkLane::kHeavy), " heavy (nice ",
                          service.scheduler().options().heavy_nice, "), ",
                          workers(shapeid::WorkLane::kStore), " store; memory budget ",
                          service.budget().total_bytes() >> 20, " MiB (",
                          service.budget().caller_bytes() >> 20, " MiB a caller)"));
  }
  if (!(*server)->health_address().empty()) {
    log.Info(absl::StrCat("health checks also on ", (*server)->health_address(),
                          " (plaintext, health only)"));
  }
  if (!(*server)->metrics_address().empty()) {
    log.Info(absl::StrCat("metrics on http://", (*server)->metrics_address(), "/metrics"),
             {{"metrics_address", (*server)->metrics_address()}});
    // The endpoint has no key and no TLS: on a network address it tells anyone who reaches
    // it gallery names and sizes and the traffic by status (no keys, no points).
    if (!shapeid::IsLoopbackAddress(options.metrics.listen) &&
        (!(*keys)->empty() || !options.security.tls_cert_file.empty())) {
      log.Warning(absl::StrCat(
          "--metrics_listen=", options.metrics.listen,
          " is reachable without a key or TLS and shows gallery names, sizes and call counts; "
          "keep that port inside the cluster (docs/operations.md)"));
    }
  }
  // The CLI's variables are one letter away from the server's; say so rather than run open.
  for (const char* cli_var : {"SHAPEID_API_KEY", "SHAPEID_API_KEY_FILE"}) {
    if ((*keys)->empty() && std::getenv(cli_var) != nullptr) {
      log.Warning(absl::StrCat(cli_var,
                               " is set but is the CLI's; the server's keys come from "
                               "SHAPEID_API_KEYS_FILE / SHAPEID_API_KEYS, and it has none"));
    }
  }
  for (const std::string& warning :
       shapeid::SecurityWarnings(options.listen, options.security, **keys)) {
    log.Warning(warning);
  }
  absl::StatusOr<shapeid::LoadReport> loaded = (*server)->LoadGalleries();
  if (!loaded.ok()) {
    log.Error(loaded.status().message());
    if (options.store.empty() &&
        (loaded.status().code() == absl::StatusCode::kDataLoss ||
         loaded.status().code() == absl::StatusCode::kFailedPrecondition)) {
      log.Error(absl::StrCat(
          "refusing to start rather than serve without that gallery. Restore it from an "
          "export, or start with --set_aside_damaged to move it to ",
          options.data_dir, "/damaged/ and serve the others."));
    }
    (*server)->Shutdown(absl::ZeroDuration());
    return 1;
  }
  for (const auto& aside : loaded->set_aside) {
    log.Warning(absl::StrCat("gallery '", aside.name, "' set aside to ", aside.moved_to, ": ",
                             aside.reason));
  }
  if (!options.store.empty()) {
    log.Info(absl::StrCat("galleries in ", loaded->store,
                          "; other replicas' changes applied within ",
                          absl::GetFlag(FLAGS_store_refresh_ms), " ms (--store_refresh_ms)"));
  }
  if (!loaded->persistent) {
    log.Warning(
        "--data_dir is empty: galleries live in memory only and are lost when the server "
        "stops");
  }
  if (loaded->read_only) {
    log.Warning(absl::StrCat(options.data_dir,
                             " is read-only: galleries are served, every change fails "
                             "UNAVAILABLE"));
  }
  for (const auto& gallery : loaded->read_only_galleries) {
    log.Warning(absl::StrCat("gallery '", gallery.name,
                             "' is served read-only (its file cannot be opened for writing, a "
                             "disk condition, not damage; it is written again once the disk "
                             "allows): ",
                             gallery.reason.message()));
  }
  log.Info(absl::StrCat("loaded ", loaded->galleries, " galleries (", loaded->samples,
                        " samples) in ", absl::FormatDuration(loaded->elapsed)),
           {{"galleries", loaded->galleries}, {"samples", loaded->samples}});
  // The line scripts wait for: from here on, every RPC is served.
  std::printf("listening on %s\n", (*server)->address().c_str());
  std::fflush(stdout);

  unsigned char received = 0;
  while (read(g_stop_pipe[0], &received, 1) != 1) {
  }
  log.Info(absl::StrCat(received == SIGTERM ? "SIGTERM" : "SIGINT", ", shutting down"));
  (*server)->Shutdown(absl::Seconds(absl::GetFlag(FLAGS_shutdown_grace_seconds)));
  return 0;
}
