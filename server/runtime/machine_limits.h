#ifndef SHAPEID_SERVER_RUNTIME_MACHINE_LIMITS_H_
#define SHAPEID_SERVER_RUNTIME_MACHINE_LIMITS_H_

#include <cstddef>

#include "absl/strings/string_view.h"

namespace shapeid {

// What the process may use, as a container runtime limits it: the defaults of the memory
// budget and of the worker pools follow the container, not the host it happens to run on
// (a 2-CPU pod on a 64-core node must not start 64 workers).

// Bytes the process may use: its cgroup's memory limit (v2 or v1) when it has one, else the
// machine's memory; 4 GiB when neither can be read.
size_t MemoryLimitBytes();

// Cores the process may use: the CPUs it may be scheduled on, capped by its cgroup's CPU
// quota (v2 cpu.max or v1 cfs quota), rounded up; at least 1.
int UsableCores();

// A cgroup memory limit file ("max" or a number of bytes): the bytes, 0 when unlimited or
// unreadable (cgroup v1 writes "unlimited" as a huge number).
size_t ParseCgroupMemoryLimit(absl::string_view text);

// A cgroup v2 cpu.max ("max 100000" or "<quota> <period>"): the quota in cores, rounded up;
// 0 when unlimited or unreadable.
int ParseCgroupCpuMax(absl::string_view text);

}  // namespace shapeid

#endif  // SHAPEID_SERVER_RUNTIME_MACHINE_LIMITS_H_
