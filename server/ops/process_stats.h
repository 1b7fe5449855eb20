#ifndef SHAPEID_SERVER_OPS_PROCESS_STATS_H_
#define SHAPEID_SERVER_OPS_PROCESS_STATS_H_

// What Linux says about this process (/proc/self), for the process_* metrics that Prometheus'
// own clients export under these names, and for GetServerStats.

#include <cstdint>

#include "absl/status/statusor.h"

namespace shapeid {

struct ProcessStats {
  double cpu_seconds = 0;      // user + system
  int64_t resident_bytes = 0;  // RSS
  int64_t virtual_bytes = 0;
  int64_t threads = 0;
  int64_t open_fds = 0;
  int64_t max_fds = 0;            // the soft RLIMIT_NOFILE
  double start_time_seconds = 0;  // since the Unix epoch
};

// Unavailable when /proc is not mounted (the metrics then leave the process_* series out).
absl::StatusOr<ProcessStats> ReadProcessStats();

}  // namespace shapeid

#endif  // SHAPEID_SERVER_OPS_PROCESS_STATS_H_
