#ifndef SHAPEID_BENCH_SOAK_PLOT_H_
#define SHAPEID_BENCH_SOAK_PLOT_H_

// The soak test's picture: an SVG of latency and server memory over time.

#include <cstdint>
#include <string>
#include <vector>

#include "bench/soak/load.h"

namespace shapeid::soak {

// Two panels over time: p50 and p99 latency of all requests per window (log scale), and the
// server's resident memory with the pass band (+max_growth_percent over `rss_warm_kib`, the
// value at `warmup_end` seconds). `rss_start_kib` (0: none) starts the memory line at t = 0.
std::string Plot(const std::vector<Window>& windows, double warmup_end, int64_t rss_start_kib,
                 int64_t rss_warm_kib, double max_growth_percent, const std::string& title,
                 const std::string& subtitle);

}  // namespace shapeid::soak

#endif  // SHAPEID_BENCH_SOAK_PLOT_H_
