#ifndef SHAPEID_BENCH_HOST_INFO_H_
#define SHAPEID_BENCH_HOST_INFO_H_

// What the benchmarks print about the machine they ran on.

#include <fstream>
#include <string>

#include "absl/strings/str_cat.h"

namespace shapeid::bench {

// The first "model name" of /proc/cpuinfo, or "unknown".
inline std::string CpuModel() {
  std::ifstream in("/proc/cpuinfo");
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind("model name", 0) == 0 && line.find(':') != std::string::npos) {
      return line.substr(line.find(':') + 2);
    }
  }
  return "unknown";
}

// The 1-, 5- and 15-minute load averages as /proc/loadavg gives them ("0.52 0.61 0.70").
inline std::string LoadAverages() {
  std::ifstream in("/proc/loadavg");
  std::string a, b, c;
  in >> a >> b >> c;
  return absl::StrCat(a, " ", b, " ", c);
}

// The 1-minute load average; 0 where unreadable.
inline double LoadAverage1() {
  std::ifstream in("/proc/loadavg");
  double one = 0;
  in >> one;
  return one;
}

// The process's thread count (Linux; 0 elsewhere), to show that nothing ran in parallel.
inline double ProcessThreads() {
  std::ifstream status("/proc/self/status");
  std::string key;
  while (status >> key) {
    if (key == "Threads:") {
      double threads = 0;
      status >> threads;
      return threads;
    }
  }
  return 0;
}

}  // namespace shapeid::bench

#endif  // SHAPEID_BENCH_HOST_INFO_H_
