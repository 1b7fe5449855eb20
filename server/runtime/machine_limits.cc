#include "server/runtime/machine_limits.h"

#include <sched.h>
#include <unistd.h>

#include <algorithm>
#include <cstdint>
#include <fstream>
#include <string>
#include <thread>
#include <vector>

#include "absl/strings/numbers.h"
#include "absl/strings/str_split.h"
#include "absl/strings/strip.h"

namespace shapeid {
namespace {

std::string FirstLine(const char* path) {
  std::ifstream file(path);
  std::string text;
  if (!file || !std::getline(file, text)) return "";
  return text;
}

int64_t ReadInteger(const char* path) {
  int64_t value = 0;
  return absl::SimpleAtoi(absl::StripAsciiWhitespace(FirstLine(path)), &value) ? value : 0;
}

int CoresFromQuota(int64_t quota, int64_t period) {
  if (quota <= 0 || period <= 0) return 0;
  return static_cast<int>((quota + period - 1) / period);
}

int SchedulableCpus() {
  cpu_set_t set;
  CPU_ZERO(&set);
  if (sched_getaffinity(0, sizeof(set), &set) == 0) {
    const int count = CPU_COUNT(&set);
    if (count > 0) return count;
  }
  return std::max(1, static_cast<int>(std::thread::hardware_concurrency()));
}

}  // namespace

size_t ParseCgroupMemoryLimit(absl::string_view text) {
  uint64_t bytes = 0;
  if (!absl::SimpleAtoi(absl::StripAsciiWhitespace(text), &bytes)) return 0;  // "max"
  if (bytes >= (uint64_t{1} << 60)) return 0;
  return static_cast<size_t>(bytes);
}

int ParseCgroupCpuMax(absl::string_view text) {
  const std::vector<absl::string_view> fields =
      absl::StrSplit(absl::StripAsciiWhitespace(text), ' ', absl::SkipEmpty());
  if (fields.size() != 2) return 0;
  int64_t quota = 0;
  int64_t period = 0;
  if (!absl::SimpleAtoi(fields[0], &quota) || !absl::SimpleAtoi(fields[1], &period)) return 0;
  return CoresFromQuota(quota, period);
}

size_t MemoryLimitBytes() {
  const long pages = sysconf(_SC_PHYS_PAGES);
  const long page_size = sysconf(_SC_PAGESIZE);
  size_t limit = pages > 0 && page_size > 0 ? static_cast<size_t>(pages) * page_size : 0;
  for (const char* path : {"/sys/fs/cgroup/memory.max",                       // cgroup v2
                           "/sys/fs/cgroup/memory/memory.limit_in_bytes"}) {  // cgroup v1
    const size_t cgroup = ParseCgroupMemoryLimit(FirstLine(path));
    if (cgroup > 0) limit = limit == 0 ? cgroup : std::min(limit, cgroup);
  }
  return limit > 0 ? limit : size_t{4} << 30;
}

int UsableCores() {
  int cores = SchedulableCpus();
  int quota = ParseCgroupCpuMax(FirstLine("/sys/fs/cgroup/cpu.max"));  // cgroup v2
  if (quota == 0) {                                                    // cgroup v1
    quota = CoresFromQuota(ReadInteger("/sys/fs/cgroup/cpu/cpu.cfs_quota_us"),
                           ReadInteger("/sys/fs/cgroup/cpu/cpu.cfs_period_us"));
  }
  if (quota > 0) cores = std::min(cores, quota);
  return std::max(1, cores);
}

}  // namespace shapeid
