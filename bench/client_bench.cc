// The C++ client's side of bench/python_client_bench.py (issue 24): Classify through
// shapeid::Client against a server that is already running, as a user's program makes the
// call, so that the two clients are timed the same way against the same server in one run.
//
//   client_bench --server 127.0.0.1:PORT --gallery bench --clouds queries.f32
//
// --clouds is raw little-endian float32 x y z, --points_per_cloud points per cloud, clouds one
// after another (what the Python bench writes); they are classified in turn, cycling.
// Measures (1) single-thread latency: --warmup calls, then --requests calls timed one by one
// (p50, p90, p99; --latencies adds every one); (2) throughput: --threads threads sharing one
// Client for --seconds (0: skipped). Prints one JSON line. Exit 1 on any failed call.

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <string>
#include <thread>
#include <vector>

#include "CLI/CLI.hpp"
#include "absl/strings/str_format.h"
#include "bench/percentile.h"
#include "client/client.h"
#include "core/point_cloud.h"

namespace shapeid {
namespace {

using Clock = std::chrono::steady_clock;

std::vector<PointCloud> ReadClouds(const std::string& path, size_t points_per_cloud) {
  std::ifstream in(path, std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const size_t cloud_bytes = points_per_cloud * 12;
  std::vector<PointCloud> clouds;
  for (size_t at = 0; cloud_bytes > 0 && at + cloud_bytes <= bytes.size(); at += cloud_bytes) {
    std::vector<float> xyz(points_per_cloud * 3);
    std::copy_n(bytes.data() + at, cloud_bytes, reinterpret_cast<char*>(xyz.data()));
    clouds.emplace_back(std::move(xyz));
  }
  return clouds;
}

int Run(int argc, char** argv) {
  CLI::App app{"Classify latency and throughput of the C++ client against a running server"};
  ClientOptions options;
  std::string gallery = "bench";
  std::string clouds_path;
  size_t points_per_cloud = 1024;
  int warmup = 200;
  int requests = 2000;
  int threads = 16;
  double seconds = 3.0;
  bool latencies = false;
  app.add_option("--server", options.target, "the server")->required();
  app.add_option("--gallery", gallery, "gallery to classify against")->capture_default_str();
  app.add_option("--clouds", clouds_path, "raw float32 xyz, clouds one after another")->required();
  app.add_option("--points_per_cloud", points_per_cloud)->capture_default_str();
  app.add_option("--warmup", warmup, "calls before timing")->capture_default_str();
  app.add_option("--requests", requests, "single-thread calls timed")->capture_default_str();
  app.add_option("--threads", threads, "threads sharing one client")->capture_default_str();
  app.add_option("--seconds", seconds, "duration of the threaded run (0: none)")
      ->capture_default_str();
  app.add_flag("--latencies", latencies, "also print every timed call's microseconds");
  CLI11_PARSE(app, argc, argv);

  const std::vector<PointCloud> clouds = ReadClouds(clouds_path, points_per_cloud);
  if (clouds.empty() || requests < 1 || threads < 1) {
    std::fprintf(stderr, "client_bench: no clouds in %s, or sizes not positive\n",
                 clouds_path.c_str());
    return 2;
  }
  auto connected = Client::Connect(options);
  if (!connected.ok()) {
    std::fprintf(stderr, "client_bench: %s\n", connected.status().ToString().c_str());
    return 2;
  }
  Client& client = **connected;

  std::atomic<int> failures{0};
  auto classify = [&](size_t i) {
    auto answer = client.Classify(gallery, clouds[i % clouds.size()]);
    if (!answer.ok() && failures.fetch_add(1) == 0) {
      std::fprintf(stderr, "client_bench: %s\n", answer.status().ToString().c_str());
    }
  };
  for (int i = 0; i < warmup; ++i) classify(static_cast<size_t>(i));
  std::vector<double> micros;
  micros.reserve(static_cast<size_t>(requests));
  for (int i = 0; i < requests; ++i) {
    const auto start = Clock::now();
    classify(static_cast<size_t>(i));
    micros.push_back(std::chrono::duration<double, std::micro>(Clock::now() - start).count());
  }

  std::atomic<long> calls{0};
  std::atomic<bool> stop{false};
  std::vector<std::thread> workers;
  const auto start = Clock::now();
  for (int t = 0; seconds > 0 && t < threads; ++t) {
    workers.emplace_back([&, t] {
      for (size_t i = static_cast<size_t>(t); !stop.load(std::memory_order_relaxed); i += 7) {
        classify(i);
        calls.fetch_add(1, std::memory_order_relaxed);
      }
    });
  }
  std::this_thread::sleep_for(std::chrono::duration<double>(seconds));
  stop = true;
  for (std::thread& w : workers) w.join();
  const double elapsed = std::chrono::duration<double>(Clock::now() - start).count();

  std::string all;
  for (size_t i = 0; latencies && i < micros.size(); ++i) {
    absl::StrAppendFormat(&all, "%s%.1f", i == 0 ? "" : ",", micros[i]);
  }
  std::printf("%s\n",
              absl::StrFormat("{\"client\":\"c++\",\"p50_us\":%.1f,\"p90_us\":%.1f,"
                              "\"p99_us\":%.1f,\"threads\":%d,\"per_second\":%.0f,"
                              "\"failures\":%d,\"latencies_us\":[%s]}",
                              bench::Percentile(micros, 0.5), bench::Percentile(micros, 0.9),
                              bench::Percentile(micros, 0.99), threads,
                              seconds > 0 ? static_cast<double>(calls.load()) / elapsed : 0.0,
                              failures.load(), all)
                  .c_str());
  return failures.load() == 0 ? 0 : 1;
}

}  // namespace
}  // namespace shapeid

int main(int argc, char** argv) { return shapeid::Run(argc, argv); }
