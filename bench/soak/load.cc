#include "bench/soak/load.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <thread>

#include "absl/strings/str_format.h"
#include "absl/strings/str_join.h"
#include "absl/time/time.h"
#include "bench/host_info.h"
#include "bench/percentile.h"

namespace shapeid::soak {
namespace {

using Clock = std::chrono::steady_clock;

double SecondsSince(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

}  // namespace

std::string WindowJson(int index, const Window& w) {
  std::vector<std::string> kinds;
  for (int k = 0; k < kNumKinds; ++k) {
    kinds.push_back(absl::StrFormat(R"("%s":{"n":%d,"p50_ms":%.3f,"p99_ms":%.3f})", kKindNames[k],
                                    w.kind_n[k], w.kind_p50_ms[k], w.kind_p99_ms[k]));
  }
  const double span = w.t1 - w.t0;
  return absl::StrFormat(
      R"({"window":%d,"t_start_s":%.2f,"t_end_s":%.2f,"requests":%d,"per_second":%.1f,)"
      R"("errors":%d,"p50_ms":%.3f,"p99_ms":%.3f,"rss_kib":%d,"server_cores":%.2f,)"
      R"("loadavg_1m":%.2f,"kinds":{%s}})",
      index, w.t0, w.t1, w.requests, span > 0 ? w.requests / span : 0.0, w.errors, w.p50_ms,
      w.p99_ms, w.rss_kib, w.server_cores, w.load1, absl::StrJoin(kinds, ","));
}

double QuantileMs(const std::vector<int64_t>& ns, double q) {
  return static_cast<double>(bench::Percentile(ns, q)) / 1e6;
}

LoadResult RunLoad(std::vector<std::unique_ptr<SoakClient>>& clients, ChildServer& server,
                   double seconds, double window_seconds, ErrorLog& errors) {
  const int n_clients = static_cast<int>(clients.size());
  Recorder recorder(n_clients);
  std::atomic<int> ready{0};
  std::atomic<bool> go{false}, stop{false};
  Clock::time_point start, end;
  std::vector<std::thread> threads;
  for (int c = 0; c < n_clients; ++c) {
    threads.emplace_back([&, c] {
      SoakClient& client = *clients[static_cast<size_t>(c)];
      if (absl::Status s = client.SetUp(); !s.ok()) {
        errors.Add(0, c, kCreateGallery, s);
        recorder.Record(c, kCreateGallery, 0, false);
        (void)client.Resync();
      }
      ++ready;
      while (!go.load(std::memory_order_acquire)) {
        std::this_thread::sleep_for(std::chrono::milliseconds(1));
      }
      while (!stop.load(std::memory_order_relaxed) && Clock::now() < end) {
        const Kind kind = client.Next();
        const auto t0 = Clock::now();
        const absl::Status s = client.Run(kind);
        const int64_t ns =
            std::chrono::duration_cast<std::chrono::nanoseconds>(Clock::now() - t0).count();
        recorder.Record(c, kind, ns, s.ok());
        if (!s.ok()) {
          errors.Add(SecondsSince(start), c, kind, s);
          if (!client.Resync().ok()) std::this_thread::sleep_for(std::chrono::milliseconds(100));
        }
      }
    });
  }
  while (ready.load() < n_clients) std::this_thread::sleep_for(std::chrono::milliseconds(5));
  LoadResult r;
  r.setup_errors = errors.count();
  recorder.Take();  // set-up calls are not part of the windows
  start = Clock::now();
  end = start + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(seconds));
  go.store(true, std::memory_order_release);

  double cpu_before = absl::ToDoubleSeconds(server.CpuTime());
  r.rss_start_kib = (server.ResidentBytes() / 1024);
  std::printf("\n%8s %9s %8s %7s %9s %9s %9s %6s %6s\n", "t (s)", "requests", "req/s", "errors",
              "p50 ms", "p99 ms", "RSS MiB", "cores", "load");
  for (int index = 0; !stop.load(); ++index) {
    Window w;
    w.t0 = index * window_seconds;
    w.t1 = std::min(seconds, (index + 1) * window_seconds);
    std::this_thread::sleep_until(
        start + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(w.t1)));
    Tally tally = recorder.Take();
    std::vector<int64_t> window_ns;
    for (int k = 0; k < kNumKinds; ++k) {
      w.kind_n[k] = static_cast<int64_t>(tally.ns[k].size());
      r.kind_total[k] += w.kind_n[k];
      w.kind_p50_ms[k] = QuantileMs(tally.ns[k], 0.50);
      w.kind_p99_ms[k] = QuantileMs(tally.ns[k], 0.99);
      window_ns.insert(window_ns.end(), tally.ns[k].begin(), tally.ns[k].end());
      r.kind_all[k].insert(r.kind_all[k].end(), tally.ns[k].begin(), tally.ns[k].end());
    }
    w.requests = static_cast<int64_t>(window_ns.size());
    w.errors = tally.errors;
    w.p50_ms = QuantileMs(window_ns, 0.50);
    w.p99_ms = QuantileMs(window_ns, 0.99);
    r.all_ns.insert(r.all_ns.end(), window_ns.begin(), window_ns.end());
    w.rss_kib = (server.ResidentBytes() / 1024);
    const double cpu = absl::ToDoubleSeconds(server.CpuTime());
    w.server_cores = (cpu - cpu_before) / (w.t1 - w.t0);
    cpu_before = cpu;
    w.load1 = bench::LoadAverage1();
    r.windows.push_back(w);
    std::printf("%8.0f %9lld %8.0f %7lld %9.2f %9.2f %9.1f %6.2f %6.2f\n", w.t1,
                static_cast<long long>(w.requests), w.requests / (w.t1 - w.t0),
                static_cast<long long>(w.errors), w.p50_ms, w.p99_ms, w.rss_kib / 1024.0,
                w.server_cores, w.load1);
    std::fflush(stdout);
    if ((r.server_died = server.Poll()) >= 0) {
      std::printf("the server exited (status %d) during the load\n", r.server_died);
      stop = true;
    }
    if (w.t1 >= seconds) stop = true;
  }
  for (std::thread& t : threads) t.join();
  // Calls in flight at the end: counted in the totals, not in any window.
  Tally drained = recorder.Take();
  for (int k = 0; k < kNumKinds; ++k) {
    r.drained += static_cast<int64_t>(drained.ns[k].size());
    r.kind_total[k] += static_cast<int64_t>(drained.ns[k].size());
    r.kind_all[k].insert(r.kind_all[k].end(), drained.ns[k].begin(), drained.ns[k].end());
    r.all_ns.insert(r.all_ns.end(), drained.ns[k].begin(), drained.ns[k].end());
  }
  r.elapsed = SecondsSince(start);
  return r;
}

}  // namespace shapeid::soak
