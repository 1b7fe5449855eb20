#ifndef SHAPEID_BENCH_SOAK_LOAD_H_
#define SHAPEID_BENCH_SOAK_LOAD_H_

// The timed part of the soak test: every client in a closed loop on a thread of its own, and
// a sampler that closes a window every --window_seconds with the requests, latencies and
// errors of the window and the server's resident memory and CPU.

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "bench/soak/recording.h"
#include "bench/soak/soak_client.h"
#include "server/testing/child_server.h"

namespace shapeid::soak {

struct Window {
  double t0 = 0, t1 = 0;  // seconds since the load started
  int64_t requests = 0;
  int64_t errors = 0;
  double p50_ms = 0, p99_ms = 0;
  int64_t kind_n[kNumKinds] = {};
  double kind_p50_ms[kNumKinds] = {}, kind_p99_ms[kNumKinds] = {};
  int64_t rss_kib = 0;      // server VmRSS at the window's end
  double server_cores = 0;  // server CPU seconds per second over the window
  double load1 = 0;         // 1-minute load average at the window's end
};

// Window `index` as one JSON object, without a newline.
std::string WindowJson(int index, const Window& w);

// The q-quantile (nearest rank) of latencies `ns`, in milliseconds; 0 when empty.
double QuantileMs(const std::vector<int64_t>& ns, double q);

struct LoadResult {
  std::vector<Window> windows;
  std::vector<int64_t> all_ns;  // latency of every successful request of the load
  int64_t kind_total[kNumKinds] = {};
  std::vector<int64_t> kind_all[kNumKinds];
  int64_t drained = 0;        // calls in flight at the end: in the totals, in no window
  int64_t setup_errors = 0;   // errors of SetUp, before the load
  int64_t rss_start_kib = 0;  // server VmRSS with the galleries set up, before the load
  int server_died = -1;       // the server's exit status if it exited during the load
  double elapsed = 0;         // seconds from the start of the load to the last client's end
};

// Sets every client up in parallel (errors logged, not timed), then runs them for `seconds`
// against `server`, printing one row per window on stdout. Stops early if the server exits.
// Errors go to `errors` with the client and the time since the load started.
LoadResult RunLoad(std::vector<std::unique_ptr<SoakClient>>& clients, ChildServer& server,
                   double seconds, double window_seconds, ErrorLog& errors);

}  // namespace shapeid::soak

#endif  // SHAPEID_BENCH_SOAK_LOAD_H_
