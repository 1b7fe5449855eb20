#ifndef SHAPEID_SERVER_TESTING_CHILD_SERVER_H_
#define SHAPEID_SERVER_TESTING_CHILD_SERVER_H_

// A shapeid-server binary run as a child process, for end-to-end tests and benchmarks: its
// stdout read for the "listening on HOST:PORT" line it prints once its galleries are loaded,
// its stderr (the log) written to a file. Killed (SIGKILL) if still running when destroyed.
// gtest-free, so benches use it as tests do.

#include <sys/types.h>

#include <cstdint>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/time/time.h"

namespace shapeid {

class ChildServer {
 public:
  ChildServer() = default;
  ChildServer(const ChildServer&) = delete;
  ChildServer& operator=(const ChildServer&) = delete;
  ~ChildServer() { Kill(); }

  // Runs `binary` with `flags`, its stderr to `stderr_path`, and waits up to `timeout` for
  // its address. Unavailable (with what it wrote to stderr) if it could not be run or did not
  // report an address in time (a start-up error: it exited).
  absl::Status Start(const std::string& binary, const std::vector<std::string>& flags,
                     const std::string& stderr_path, absl::Duration timeout = absl::Seconds(30));

  // "HOST:PORT" from the server's "listening on" line; empty until Start succeeded.
  const std::string& address() const { return address_; }
  pid_t pid() const { return pid_; }

  // The exit status if the process has ended (128 + signal if killed), else -1.
  int Poll();
  // Waits for the process to exit by itself; its exit status, or -1 after `timeout`.
  int WaitForExit(absl::Duration timeout);
  // SIGTERM, then WaitForExit(timeout).
  int Terminate(absl::Duration timeout);
  // SIGKILL, as a crash or a power cut would stop it (nothing flushed, no shutdown).
  void Kill();

  // What the server wrote to stderr so far (its start-up report, log lines, errors).
  std::string StderrText() const;
  // Resident memory now and at its peak (VmRSS and VmHWM of /proc/PID/status), in bytes; 0
  // if unreadable.
  int64_t ResidentBytes() const;
  int64_t PeakResidentBytes() const;
  // User and system CPU time the process has used.
  absl::Duration CpuTime() const;

 private:
  int64_t StatusField(const char* key) const;

  pid_t pid_ = -1;
  bool exited_ = false;
  int status_ = -1;
  std::string address_;
  std::string stderr_path_;
};

}  // namespace shapeid

#endif  // SHAPEID_SERVER_TESTING_CHILD_SERVER_H_
