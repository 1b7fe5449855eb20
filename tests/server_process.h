#ifndef SHAPEID_TESTS_SERVER_PROCESS_H_
#define SHAPEID_TESTS_SERVER_PROCESS_H_

// The real shapeid-server binary as a child process, for end-to-end tests
// (server/testing/child_server.h, with a data directory of its own). Needs SHAPEID_SERVER_PATH
// defined by the build.

#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstdlib>
#include <string>
#include <vector>

#include "absl/time/time.h"
#include "gtest/gtest.h"
#include "server/testing/child_server.h"

namespace shapeid {

// A shapeid-server child process; killed (SIGKILL) if a test leaves it running.
class ServerProcess {
 public:
  // Starts SHAPEID_SERVER_PATH on 127.0.0.1:0 with `extra_flags`. Without a --data_dir flag
  // there, the server gets a fresh data directory of its own (removed with this object), so
  // that servers of tests running in parallel never share one. address() stays empty if it
  // did not start (StderrText says why).
  explicit ServerProcess(std::vector<std::string> extra_flags = {}) {
    bool has_data_dir = false;
    for (const std::string& flag : extra_flags) {
      if (flag.rfind("--data_dir", 0) == 0) has_data_dir = true;
    }
    static std::atomic<int> counter{0};
    const std::string scratch = ::testing::TempDir() + "/shapeid_server_" +
                                std::to_string(getpid()) + "_" + std::to_string(counter++);
    if (!has_data_dir) {
      owned_data_dir_ = scratch;
      extra_flags.push_back("--data_dir=" + owned_data_dir_);
    }
    stderr_path_ = scratch + ".stderr";
    std::vector<std::string> flags = {"--listen=127.0.0.1:0", "--shutdown_grace_seconds=10"};
    flags.insert(flags.end(), extra_flags.begin(), extra_flags.end());
    (void)child_.Start(SHAPEID_SERVER_PATH, flags, stderr_path_, absl::Seconds(10));
  }

  ~ServerProcess() {
    child_.Kill();
    if (!owned_data_dir_.empty()) {
      std::system(("rm -rf '" + owned_data_dir_ + "'").c_str());
    }
    unlink(stderr_path_.c_str());
  }

  // What the server wrote to stderr so far (its start-up report, warnings, errors).
  std::string StderrText() const { return child_.StderrText(); }

  // Waits for the process to exit by itself; its exit status, or -1 after `timeout`.
  int WaitForExit(std::chrono::seconds timeout) {
    return child_.WaitForExit(absl::FromChrono(timeout));
  }

  const std::string& address() const { return child_.address(); }
  pid_t pid() const { return child_.pid(); }
  const ChildServer& child() const { return child_; }

  // SIGKILL, as a crash or a power cut would stop it (nothing flushed, no shutdown).
  void Kill() { child_.Kill(); }

  // Sends SIGTERM and returns the exit status (-1 if it did not exit within `timeout`).
  // Idle client channels stay open meanwhile, as robots' do; the server must not wait for
  // them (its grace is 10 s, the tests allow 3 s).
  int Terminate(std::chrono::seconds timeout) {
    return child_.Terminate(absl::FromChrono(timeout));
  }

 private:
  ChildServer child_;
  std::string owned_data_dir_;
  std::string stderr_path_;
};

}  // namespace shapeid

#endif  // SHAPEID_TESTS_SERVER_PROCESS_H_
