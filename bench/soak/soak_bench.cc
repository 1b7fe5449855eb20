// Soak test: the real shapeid-server binary, started as a child process on a loopback port
// with a fresh data directory (the SQLite store, fsync'd as in production), under a long mixed
// load from many clients. Each client has its own channel and TCP connection and, in a closed
// loop, trains into a gallery of its own, removes its oldest samples once the gallery passes
// --gallery_samples (so the server's data stays bounded and its memory should be flat),
// classifies and describes (one-message and streamed calls), reads, lists and exports its
// gallery, and now and then deletes a scratch gallery and recreates it (created and trained,
// or imported from its last export). Every answer is checked against what the client knows
// its galleries hold; every non-OK status or failed check is an error.
//
//   soak_bench                                   32 clients, 600 s
//   soak_bench --seconds 6 --clients 8 --window_seconds 1 --skip_memory_check   (CI smoke)
//
// Per window (--window_seconds) it records requests and latency by kind, errors, and the
// server's resident memory (VmRSS of the child) and CPU; it writes the windows as JSON lines
// (--out), draws them as an SVG (--svg), and prints a summary. PASS: no error, RSS growth from
// the end of the warm-up to the end under 5 %, and exit 0 after SIGTERM. Exit 0 pass, 1 fail,
// 2 usage error. Figures: docs/reliability.md.
//
// The parts: cloud_pool (the clouds), soak_client (one robot), recording and load (the
// clients' threads and the windows), report and plot (the verdict and its outputs).

#include <stdlib.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "CLI/CLI.hpp"
#include "absl/status/status.h"
#include "absl/strings/str_cat.h"
#include "absl/time/time.h"
#include "bench/host_info.h"
#include "bench/soak/cloud_pool.h"
#include "bench/soak/load.h"
#include "bench/soak/recording.h"
#include "bench/soak/report.h"
#include "bench/soak/soak_client.h"
#include "client/client.h"
#include "server/testing/child_server.h"

namespace shapeid::soak {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

// The last `max_bytes` of `text`.
std::string Tail(const std::string& text, size_t max_bytes) {
  return text.size() > max_bytes ? text.substr(text.size() - max_bytes) : text;
}

// OK once the server at `address` answers its health check SERVING, within 30 s.
absl::Status WaitUntilServing(const std::string& address) {
  ClientOptions options;
  options.target = address;
  options.max_attempts = 1;
  options.deadline = absl::Seconds(2);
  absl::Status health = absl::UnavailableError("not asked");
  auto health_client = Client::Connect(options);
  const auto until = Clock::now() + std::chrono::seconds(30);
  while (health_client.ok() && !(health = (*health_client)->CheckHealth()).ok() &&
         Clock::now() < until) {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  return health;
}

// The server's health check after the load, with one attempt and a 5-s deadline.
absl::Status HealthAfter(const std::string& address) {
  ClientOptions options;
  options.target = address;
  options.max_attempts = 1;
  options.deadline = absl::Seconds(5);
  auto health_client = Client::Connect(options);
  return health_client.ok() ? (*health_client)->CheckHealth() : health_client.status();
}

int Run(int argc, char** argv) {
  CLI::App app{"soak_bench: a long mixed load on a real shapeid-server, watching memory"};
  int clients = 32;
  double seconds = 600;
  double window_seconds = 10;
  double warmup_seconds = 60;
  double max_growth = 5;
  bool skip_memory_check = false;
  ClientSettings settings;
  double deadline_seconds = 30;
  size_t per_class = 8;
  std::string out = "soak_bench.jsonl";
  std::string svg_path = "soak_bench.svg";
  std::string server_path = SHAPEID_SERVER_PATH;
  std::string data_dir = fs::path(SHAPEID_SOURCE_DIR) / ".." / "shared" / "data" / "modelnet10";
  std::string scratch_parent = fs::temp_directory_path().string();
  app.add_option("--clients", clients, "client threads, each with its own channel")
      ->capture_default_str();
  app.add_option("--seconds", seconds, "duration of the load")->capture_default_str();
  app.add_option("--window_seconds", window_seconds, "sampling window")->capture_default_str();
  app.add_option("--warmup_seconds", warmup_seconds,
                 "warm-up before the memory reference (at most a fifth of --seconds)")
      ->capture_default_str();
  app.add_option("--max_rss_growth_percent", max_growth,
                 "largest RSS growth from the end of the warm-up to the end that passes")
      ->capture_default_str();
  app.add_flag("--skip_memory_check", skip_memory_check,
               "do not fail on RSS growth (for runs too short to reach a steady state)");
  app.add_option("--gallery_samples", settings.gallery_samples,
                 "bound of each client's gallery (trimmed to 3/4 of it once passed)")
      ->capture_default_str();
  app.add_option("--deadline_seconds", deadline_seconds, "deadline of every call")
      ->capture_default_str();
  app.add_option("--per_class", per_class,
                 "train clouds per class (test clouds: half as many) in the clouds the clients "
                 "draw from")
      ->capture_default_str();
  app.add_option("--out", out, "JSON-lines file of the windows (empty: none)")
      ->capture_default_str();
  app.add_option("--svg", svg_path, "SVG plot of latency and RSS over time (empty: none)")
      ->capture_default_str();
  app.add_option("--server", server_path, "the shapeid-server binary")->capture_default_str();
  app.add_option("--data", data_dir, "ModelNet10 folder (synthetic clouds where absent)")
      ->capture_default_str();
  app.add_option("--tmp", scratch_parent, "where the server's temporary data directory goes")
      ->capture_default_str();
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 2;
  }
  if (clients < 1 || clients > 1000 || !(seconds > 0) || !(window_seconds > 0) ||
      warmup_seconds < 0 || settings.gallery_samples < 8 || !(deadline_seconds > 0) ||
      per_class < 2) {
    std::fprintf(stderr,
                 "soak_bench: --clients 1..1000, --seconds, --window_seconds and "
                 "--deadline_seconds > 0, --warmup_seconds >= 0, --gallery_samples >= 8, "
                 "--per_class >= 2\n");
    return 2;
  }
  settings.deadline = absl::Seconds(deadline_seconds);
  const double warmup = std::min(warmup_seconds, seconds / 5);

  const Pool pool = LoadPool(data_dir, per_class);
  std::string tmp = absl::StrCat(scratch_parent, "/shapeid_soak_XXXXXX");
  if (mkdtemp(tmp.data()) == nullptr) {
    std::fprintf(stderr, "soak_bench: cannot make a directory under %s\n", scratch_parent.c_str());
    return 1;
  }
  const std::string stderr_path = tmp + "/server.stderr";
  Ending ending;
  ending.load_before = bench::LoadAverages();
  std::printf("machine: %u hardware threads, %s; load average before: %s\n",
              std::thread::hardware_concurrency(), bench::CpuModel().c_str(),
              ending.load_before.c_str());
  std::printf("clouds: %s\n", pool.source.c_str());
  ChildServer server;
  if (absl::Status s = server.Start(
          server_path,
          {"--listen=127.0.0.1:0", "--data_dir=" + tmp + "/data", "--shutdown_grace_seconds=10"},
          stderr_path);
      !s.ok()) {
    std::fprintf(stderr, "soak_bench: %s\n%s", std::string(s.message()).c_str(),
                 Tail(server.StderrText(), 2000).c_str());
    return 1;
  }
  if (absl::Status health = WaitUntilServing(server.address()); !health.ok()) {
    std::fprintf(stderr, "soak_bench: the server is not SERVING: %s\n", health.ToString().c_str());
    return 1;
  }
  std::printf("server: %s, pid %d, %s, data directory %s/data (SQLite), health SERVING\n",
              server_path.c_str(), static_cast<int>(server.pid()), server.address().c_str(),
              tmp.c_str());
  std::printf(
      "load: %d clients x %.0f s, windows of %g s, warm-up %g s, galleries of at "
      "most %zu samples, deadline %.0f s per call\n",
      clients, seconds, window_seconds, warmup, settings.gallery_samples, deadline_seconds);
  std::fflush(stdout);

  ErrorLog errors;
  std::vector<std::unique_ptr<SoakClient>> soakers;
  for (int c = 0; c < clients; ++c) {
    soakers.push_back(std::make_unique<SoakClient>(c, server.address(), pool, settings));
  }
  const LoadResult load = RunLoad(soakers, server, seconds, window_seconds, errors);
  ending.load_after = bench::LoadAverages();

  // The server must still answer health checks, then stop cleanly on SIGTERM.
  ending.health = load.server_died < 0 ? HealthAfter(server.address())
                                       : absl::UnavailableError("the server exited");
  soakers.clear();  // close the clients' channels before the server stops
  ending.exit_status = server.Terminate(absl::Seconds(30));

  ReportSettings report;
  report.clients = clients;
  report.seconds = seconds;
  report.warmup = warmup;
  report.max_growth_percent = max_growth;
  report.skip_memory_check = skip_memory_check;
  report.out = out;
  report.svg_path = svg_path;
  const bool pass = Report(report, load, errors, ending, Tail(server.StderrText(), 3000));
  std::error_code ignored;
  fs::remove_all(tmp, ignored);
  return pass ? 0 : 1;
}

}  // namespace
}  // namespace shapeid::soak

int main(int argc, char** argv) { return shapeid::soak::Run(argc, argv); }
