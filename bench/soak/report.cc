#include "bench/soak/report.h"

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <fstream>
#include <thread>
#include <vector>

#include "absl/strings/str_format.h"
#include "bench/soak/plot.h"

namespace shapeid::soak {

bool Report(const ReportSettings& settings, const LoadResult& load, const ErrorLog& errors,
            const Ending& ending, const std::string& server_stderr_tail) {
  const std::vector<Window>& windows = load.windows;
  const double elapsed = load.elapsed;
  int64_t rss_warm = 0, rss_end = 0, rss_peak = 0;
  double warmup_end = 0;
  for (const Window& w : windows) {
    if (rss_warm == 0 && w.t1 >= settings.warmup - 1e-9 && w.rss_kib > 0) {
      rss_warm = w.rss_kib;
      warmup_end = w.t1;
    }
    if (rss_warm > 0) rss_peak = std::max(rss_peak, w.rss_kib);
  }
  if (!windows.empty()) rss_end = windows.back().rss_kib;
  const double growth = rss_warm > 0 ? 100.0 * (rss_end - rss_warm) / rss_warm : 0;
  const int64_t total = static_cast<int64_t>(load.all_ns.size());
  const int64_t error_count = errors.count();
  double mean_load = 0, mean_cores = 0;
  for (const Window& w : windows) {
    mean_load += w.load1 / static_cast<double>(windows.size());
    mean_cores += w.server_cores / static_cast<double>(windows.size());
  }
  const double p50 = QuantileMs(load.all_ns, 0.50), p99 = QuantileMs(load.all_ns, 0.99);

  std::printf("\nBy kind over the run:\n  %-16s %9s %8s %9s %9s\n", "", "requests", "req/s",
              "p50 ms", "p99 ms");
  for (int k = 0; k < kNumKinds; ++k) {
    std::printf("  %-16s %9lld %8.1f %9.2f %9.2f\n", kKindNames[k],
                static_cast<long long>(load.kind_total[k]), load.kind_total[k] / elapsed,
                QuantileMs(load.kind_all[k], 0.50), QuantileMs(load.kind_all[k], 0.99));
  }
  std::printf("\nSummary\n");
  std::printf("  requests          %lld in %.1f s (%lld in flight at the end counted), %.1f /s\n",
              static_cast<long long>(total), elapsed, static_cast<long long>(load.drained),
              total / elapsed);
  std::printf("  errors            %lld (%lld during set-up)\n",
              static_cast<long long>(error_count), static_cast<long long>(load.setup_errors));
  for (const std::string& e : errors.first()) std::printf("    %s\n", e.c_str());
  if (error_count > static_cast<int64_t>(errors.first().size())) {
    std::printf("    ... and %lld more\n",
                static_cast<long long>(error_count - static_cast<int64_t>(errors.first().size())));
  }
  std::printf("  latency           p50 %.2f ms, p99 %.2f ms (all requests)\n", p50, p99);
  std::printf("  server RSS        %.1f MiB at the start of the load (galleries set up)\n",
              load.rss_start_kib / 1024.0);
  std::printf(
      "  server RSS        %.1f MiB after warm-up (at %.0f s), %.1f MiB at the end, "
      "peak %.1f MiB after warm-up; growth %+.2f %%\n",
      rss_warm / 1024.0, warmup_end, rss_end / 1024.0, rss_peak / 1024.0, growth);
  std::printf("  server CPU        %.2f cores on average\n", mean_cores);
  std::printf("  load average      before %s; mean 1-min during %.2f; after %s\n",
              ending.load_before.c_str(), mean_load, ending.load_after.c_str());
  std::printf("  health at the end %s\n",
              ending.health.ok() ? "SERVING" : ending.health.ToString().c_str());
  std::printf("  backlog when idle %s\n", ending.backlog.ok() ? "0 (every admitted cost given back)"
                                                              : ending.backlog.ToString().c_str());
  std::printf("  SIGTERM           exit status %d%s\n", ending.exit_status,
              ending.exit_status == -1 ? " (still running after 30 s; killed)" : "");

  const bool memory_ok = rss_warm > 0 && growth < settings.max_growth_percent;
  bool pass = error_count == 0 && load.server_died < 0 && ending.health.ok() &&
              ending.backlog.ok() && ending.exit_status == 0;
  if (settings.skip_memory_check) {
    std::printf(
        "  memory check      DISABLED (--skip_memory_check): growth reported, not judged\n");
  } else {
    std::printf("  memory check      growth %+.2f %% %s %.1f %%\n", growth,
                memory_ok ? "<" : ">=", settings.max_growth_percent);
    pass = pass && memory_ok;
  }

  const std::string subtitle = absl::StrFormat(
      "%d clients, %.0f s, %lld requests (%.0f /s), %lld errors; p50 %.2f ms, p99 %.2f ms; "
      "RSS %.1f -> %.1f MiB (%+.2f %%); load %.2f on %u threads",
      settings.clients, settings.seconds, static_cast<long long>(total), total / elapsed,
      static_cast<long long>(error_count), p50, p99, rss_warm / 1024.0, rss_end / 1024.0, growth,
      mean_load, std::thread::hardware_concurrency());
  bool written = true;
  if (!settings.out.empty()) {
    std::ofstream file(settings.out);
    for (size_t i = 0; i < windows.size(); ++i) {
      file << WindowJson(static_cast<int>(i), windows[i]) << "\n";
    }
    written = written && file.good();
    std::printf("  windows           %s\n", settings.out.c_str());
  }
  if (!settings.svg_path.empty()) {
    std::ofstream file(settings.svg_path);
    file << Plot(windows, warmup_end, load.rss_start_kib, rss_warm, settings.max_growth_percent,
                 "shapeid-server soak test", subtitle);
    written = written && file.good();
    std::printf("  plot              %s\n", settings.svg_path.c_str());
  }
  if (!written) {
    std::printf("  could not write %s / %s\n", settings.out.c_str(), settings.svg_path.c_str());
    pass = false;
  }
  if (!pass) std::printf("server stderr (tail):\n%s\n", server_stderr_tail.c_str());
  std::printf(
      "JSON {\"bench\":\"soak\",\"clients\":%d,\"seconds\":%.1f,\"requests\":%lld,"
      "\"per_second\":%.1f,\"errors\":%lld,\"p50_ms\":%.3f,\"p99_ms\":%.3f,"
      "\"rss_start_kib\":%lld,\"rss_warm_kib\":%lld,\"rss_end_kib\":%lld,\"rss_peak_kib\":%lld,"
      "\"rss_growth_percent\":%.3f,\"memory_checked\":%s,\"server_exit\":%d,"
      "\"loadavg_before\":\"%s\",\"loadavg_mean_1m\":%.2f,\"loadavg_after\":\"%s\","
      "\"pass\":%s}\n",
      settings.clients, elapsed, static_cast<long long>(total), total / elapsed,
      static_cast<long long>(error_count), p50, p99, static_cast<long long>(load.rss_start_kib),
      static_cast<long long>(rss_warm), static_cast<long long>(rss_end),
      static_cast<long long>(rss_peak), growth, settings.skip_memory_check ? "false" : "true",
      ending.exit_status, ending.load_before.c_str(), mean_load, ending.load_after.c_str(),
      pass ? "true" : "false");
  std::printf("%s\n", pass ? "PASS" : "FAIL");
  return pass;
}

}  // namespace shapeid::soak
