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
//   soak_bench --server_flag=--max_caller_backlog_seconds=1 --flooders 1 [--keys 3]
//                                                a shared server for longer than its limits
//
// Without --keys every robot calls from the same loopback host, as one caller: the case that
// once locked every local client out once the leaked backlog passed the bound. With --keys N
// the robots share N keys. --flooders adds hostile callers (server/runtime/caller_identity.h: a
// caller id of their own, or a read key each) that keep their share of the cheap lane full;
// they must be refused themselves while no robot call fails. After the load the server's
// caller backlog (GetServerStats) must be back to zero.
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
#include "absl/strings/str_join.h"
#include "absl/time/time.h"
#include "bench/flooder.h"
#include "bench/host_info.h"
#include "bench/soak/cloud_pool.h"
#include "bench/soak/load.h"
#include "bench/soak/recording.h"
#include "bench/soak/report.h"
#include "bench/soak/soak_client.h"
#include "client/client.h"
#include "server/security/api_keys.h"
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

// Creates gallery `name` and trains it with every cloud of `pool`, as `admin`.
absl::Status SetUpGallery(const std::string& address, const ClientSettings& admin, const Pool& pool,
                          const std::string& name) {
  auto stub =
      v1::ShapeId::NewStub(grpc::CreateChannel(address, grpc::InsecureChannelCredentials()));
  grpc::ClientContext create_context;
  PrepareContext(admin, create_context);
  v1::CreateGalleryRequest create;
  create.set_name(name);
  v1::Gallery created;
  if (grpc::Status s = stub->CreateGallery(&create_context, create, &created); !s.ok()) {
    return FromGrpcStatus(s);
  }
  grpc::ClientContext train_context;
  PrepareContext(admin, train_context);
  v1::TrainResponse trained;
  auto writer = stub->Train(&train_context, &trained);
  v1::TrainRequest request;
  request.mutable_header()->set_gallery(name);
  bool open = writer->Write(request);
  for (size_t i = 0; open && i < pool.xyz.size(); ++i) {
    request.Clear();
    request.mutable_sample()->set_label(pool.labels[i]);
    open = writer->Write(request);
    request.Clear();
    request.mutable_points()->set_xyz(pool.xyz[i]);
    open = open && writer->Write(request);
  }
  writer->WritesDone();
  return FromGrpcStatus(writer->Finish());
}

// Once the server is idle (nothing queued, within 10 s of the load's end), OK if the callers'
// backlog is back to zero: else the scheduler kept cost it had released (issue 39's lockout).
absl::Status IdleBacklog(const std::string& address, const ClientSettings& admin) {
  grpc::ChannelArguments args;
  args.SetInt(GRPC_ARG_USE_LOCAL_SUBCHANNEL_POOL, 1);
  auto stub = v1::ShapeId::NewStub(
      grpc::CreateCustomChannel(address, grpc::InsecureChannelCredentials(), args));
  const auto until = Clock::now() + std::chrono::seconds(10);
  v1::ServerStats stats;
  while (true) {
    grpc::ClientContext context;
    PrepareContext(admin, context);
    if (grpc::Status s = stub->GetServerStats(&context, v1::GetServerStatsRequest(), &stats);
        !s.ok()) {
      return FromGrpcStatus(s);
    }
    int64_t queued = 0, running = 0;
    for (const v1::WorkLaneStats& lane : stats.work()) {
      queued += static_cast<int64_t>(lane.queued());
      running += lane.running();
    }
    // The stats call itself runs on gRPC's thread, never in a lane.
    if ((queued == 0 && running == 0) || Clock::now() > until) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  const int64_t backlog_ns =
      stats.caller_backlog().seconds() * 1'000'000'000 + stats.caller_backlog().nanos();
  if (backlog_ns != 0 || stats.callers_with_backlog() != 0) {
    return absl::InternalError(
        absl::StrCat("idle, yet the server holds ", backlog_ns / 1e6, " ms of caller backlog over ",
                     stats.callers_with_backlog(), " callers: released cost was kept"));
  }
  return absl::OkStatus();
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
  std::vector<std::string> server_flags;
  int keys = 0;
  int flooders = 0;
  int flood_in_flight = 256;
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
  app.add_option(
      "--server_flag", server_flags,
      "a flag for the server (repeatable), e.g. --server_flag=--max_caller_backlog_seconds=1");
  app.add_option("--keys", keys,
                 "robots share this many keys (0: no keys, every robot the same loopback "
                 "caller)")
      ->capture_default_str();
  app.add_option("--flooders", flooders, "hostile callers flooding the cheap lane")
      ->capture_default_str();
  app.add_option("--flood_in_flight", flood_in_flight, "calls each flooder keeps open")
      ->capture_default_str();
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 2;
  }
  if (clients < 1 || clients > 1000 || !(seconds > 0) || !(window_seconds > 0) ||
      warmup_seconds < 0 || settings.gallery_samples < 8 || !(deadline_seconds > 0) ||
      per_class < 2 || keys < 0 || flooders < 0 || flood_in_flight < 1) {
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
  // Keys: the robots', the flooders' (read) and an admin's for set-up and the stats.
  std::vector<std::string> robot_keys, flood_keys;
  ClientSettings admin;
  admin.deadline = absl::Seconds(deadline_seconds);
  std::vector<std::string> server_args = {"--listen=127.0.0.1:0", "--data_dir=" + tmp + "/data",
                                          "--shutdown_grace_seconds=10"};
  if (keys > 0) {
    std::vector<std::string> lines;
    const auto add_key = [&lines](const std::string& name, const std::string& scope) {
      const std::string key = absl::StrCat(name, "-soak-key-0123456789abcdefghijklmnopqrstuvwxyz");
      lines.push_back(absl::StrCat(name, " ", scope, " ", Sha256Hex(key)));
      return key;
    };
    // Admin: the robots delete and recreate their scratch galleries.
    for (int k = 0; k < keys; ++k)
      robot_keys.push_back(add_key(absl::StrCat("robots", k), "admin"));
    for (int f = 0; f < flooders; ++f)
      flood_keys.push_back(add_key(absl::StrCat("flood", f), "read"));
    admin.api_key = add_key("admin", "admin");
    server_args.push_back(absl::StrCat("--api_keys=", absl::StrJoin(lines, ";")));
  }
  server_args.insert(server_args.end(), server_flags.begin(), server_flags.end());
  ChildServer server;
  if (absl::Status s = server.Start(server_path, server_args, stderr_path); !s.ok()) {
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

  if (!server_flags.empty())
    std::printf("server flags: %s\n", absl::StrJoin(server_flags, " ").c_str());
  std::printf("callers: %s; %d flooder(s) keeping %d calls open each\n",
              keys > 0 ? absl::StrCat("robots share ", keys, " key(s)").c_str()
                       : "every robot the same loopback caller (no keys)",
              flooders, flood_in_flight);

  std::vector<std::unique_ptr<bench::Flooder>> flood;
  for (int f = 0; f < flooders; ++f) {
    ClientSettings flood_settings = admin;
    if (keys > 0) {
      flood_settings.api_key = flood_keys[static_cast<size_t>(f)];
    } else {
      flood_settings.caller_id = absl::StrCat("flooder-", f);
    }
    const std::string gallery = absl::StrCat("flood-", f);
    if (absl::Status s = SetUpGallery(server.address(), admin, pool, gallery); !s.ok()) {
      std::fprintf(stderr, "soak_bench: the flooder's gallery: %s\n", s.ToString().c_str());
      return 1;
    }
    auto request = std::make_shared<v1::ClassifyCloudRequest>();
    request->mutable_header()->set_gallery(gallery);
    request->mutable_points()->set_xyz(pool.queries.front());
    flood.push_back(std::make_unique<bench::Flooder>(
        server.address(),
        [flood_settings](grpc::ClientContext& context) { PrepareContext(flood_settings, context); },
        [request](v1::ShapeId::Stub& stub, grpc::ClientContext* context,
                  std::function<void(grpc::Status)> done) {
          auto response = std::make_shared<v1::ClassifyResponse>();
          stub.async()->ClassifyCloud(context, request.get(), response.get(),
                                      [response, done](grpc::Status s) { done(std::move(s)); });
        },
        flood_in_flight));
  }
  ErrorLog errors;
  std::vector<std::unique_ptr<SoakClient>> soakers;
  for (int c = 0; c < clients; ++c) {
    ClientSettings robot = settings;
    if (keys > 0) robot.api_key = robot_keys[static_cast<size_t>(c % keys)];
    soakers.push_back(std::make_unique<SoakClient>(c, server.address(), pool, robot));
  }
  for (auto& flooder : flood) flooder->Start();
  const LoadResult load = RunLoad(soakers, server, seconds, window_seconds, errors);
  for (auto& flooder : flood) flooder->Stop();
  ending.load_after = bench::LoadAverages();
  for (size_t f = 0; f < flood.size(); ++f) {
    const bench::FloodCounts counts = flood[f]->counts();
    std::printf("flooder %zu: %lld answered, %lld refused RESOURCE_EXHAUSTED, %lld other%s%s\n", f,
                static_cast<long long>(counts.ok), static_cast<long long>(counts.refused),
                static_cast<long long>(counts.other), counts.other > 0 ? "; first: " : "",
                counts.first_other.c_str());
  }
  ending.backlog = load.server_died < 0 ? IdleBacklog(server.address(), admin)
                                        : absl::UnavailableError("the server exited");

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
