#ifndef SHAPEID_BENCH_SOAK_REPORT_H_
#define SHAPEID_BENCH_SOAK_REPORT_H_

// The soak test's verdict and its outputs: the summary on stdout, the windows as JSON lines,
// the SVG plot and one closing "JSON {...}" line.

#include <string>

#include "absl/status/status.h"
#include "bench/soak/load.h"
#include "bench/soak/recording.h"

namespace shapeid::soak {

// What the run was asked to do, as the report states it.
struct ReportSettings {
  int clients = 0;
  double seconds = 0;
  double warmup = 0;  // seconds; the RSS reference is the first window ending after it
  double max_growth_percent = 5;
  bool skip_memory_check = false;
  std::string out;       // JSON-lines file of the windows; empty: none
  std::string svg_path;  // SVG plot; empty: none
};

// How the server and the machine ended the run.
struct Ending {
  absl::Status health;   // the server's health check after the load
  absl::Status backlog;  // the callers' backlog once idle: OK when back to zero
  int exit_status = -1;  // after SIGTERM; -1 if still running after 30 s (then killed)
  std::string load_before, load_after;  // load averages before and after the run
};

// Prints the summary, writes the files and returns whether the run passed: no error, the
// server alive, SERVING and exiting 0 on SIGTERM, the files written and (unless skipped) RSS
// growth after the warm-up under the bound. `server_stderr_tail` is printed on failure.
bool Report(const ReportSettings& settings, const LoadResult& load, const ErrorLog& errors,
            const Ending& ending, const std::string& server_stderr_tail);

}  // namespace shapeid::soak

#endif  // SHAPEID_BENCH_SOAK_REPORT_H_
