#ifndef SHAPEID_TESTS_SERVER_PROCESS_H_
#define SHAPEID_TESTS_SERVER_PROCESS_H_

// The real shapeid-server binary as a child process, for end-to-end tests. Needs
// SHAPEID_SERVER_PATH defined by the build.

#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <thread>
#include <vector>

#include "gtest/gtest.h"

extern char** environ;

namespace shapeid {

// A shapeid-server child process; killed (SIGKILL) if a test leaves it running.
class ServerProcess {
 public:
  using Clock = std::chrono::steady_clock;

  // Starts SHAPEID_SERVER_PATH on 127.0.0.1:0 with `extra_flags`. Without a --data_dir flag
  // there, the server gets a fresh data directory of its own (removed with this object), so
  // that servers of tests running in parallel never share one.
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
    int out[2];
    if (pipe(out) != 0) return;
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_adddup2(&actions, out[1], STDOUT_FILENO);
    posix_spawn_file_actions_addclose(&actions, out[0]);
    posix_spawn_file_actions_addopen(&actions, STDERR_FILENO, stderr_path_.c_str(),
                                     O_WRONLY | O_CREAT | O_TRUNC, 0644);
    std::string binary = SHAPEID_SERVER_PATH;
    std::vector<std::string> args = {binary, "--listen=127.0.0.1:0", "--shutdown_grace_seconds=10"};
    args.insert(args.end(), extra_flags.begin(), extra_flags.end());
    std::vector<char*> argv;
    for (std::string& arg : args) argv.push_back(arg.data());
    argv.push_back(nullptr);
    if (posix_spawn(&pid_, binary.c_str(), &actions, nullptr, argv.data(), environ) != 0) pid_ = -1;
    posix_spawn_file_actions_destroy(&actions);
    close(out[1]);
    // Read "listening on HOST:PORT\n" (printed once the galleries are loaded), for at most
    // 10 s.
    std::string line;
    const auto deadline = Clock::now() + std::chrono::seconds(10);
    fcntl(out[0], F_SETFL, O_NONBLOCK);
    while (Clock::now() < deadline && line.find('\n') == std::string::npos) {
      char buf[256];
      const ssize_t n = read(out[0], buf, sizeof(buf));
      if (n > 0) {
        line.append(buf, static_cast<size_t>(n));
      } else if (n == 0) {
        break;  // the server exited (a start-up error: see StderrText)
      } else {
        std::this_thread::sleep_for(std::chrono::milliseconds(10));
      }
    }
    close(out[0]);
    const std::string prefix = "listening on ";
    if (line.rfind(prefix, 0) == 0)
      address_ = line.substr(prefix.size(), line.find('\n') - prefix.size());
  }

  ~ServerProcess() {
    Kill();
    if (!owned_data_dir_.empty()) {
      std::system(("rm -rf '" + owned_data_dir_ + "'").c_str());
    }
    unlink(stderr_path_.c_str());
  }

  // What the server wrote to stderr so far (its start-up report, warnings, errors).
  std::string StderrText() const {
    std::string text;
    if (FILE* f = std::fopen(stderr_path_.c_str(), "r")) {
      char buf[4096];
      size_t n;
      while ((n = std::fread(buf, 1, sizeof(buf), f)) > 0) text.append(buf, n);
      std::fclose(f);
    }
    return text;
  }

  // Waits for the process to exit by itself; its exit status, or -1 after `timeout`.
  int WaitForExit(std::chrono::seconds timeout) {
    const auto deadline = Clock::now() + timeout;
    while (Clock::now() < deadline) {
      int status = 0;
      if (waitpid(pid_, &status, WNOHANG) == pid_) {
        exited_ = true;
        return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    return -1;
  }

  const std::string& address() const { return address_; }
  pid_t pid() const { return pid_; }

  // SIGKILL, as a crash or a power cut would stop it (nothing flushed, no shutdown).
  void Kill() {
    if (pid_ > 0 && !exited_) {
      kill(pid_, SIGKILL);
      waitpid(pid_, nullptr, 0);
      exited_ = true;
    }
  }

  // Sends SIGTERM and returns the exit status (-1 if it did not exit within `timeout`).
  // Idle client channels stay open meanwhile, as robots' do; the server must not wait for
  // them (its grace is 10 s, the tests allow 3 s).
  int Terminate(std::chrono::seconds timeout) {
    kill(pid_, SIGTERM);
    const auto deadline = Clock::now() + timeout;
    while (Clock::now() < deadline) {
      int status = 0;
      if (waitpid(pid_, &status, WNOHANG) == pid_) {
        exited_ = true;
        return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    return -1;
  }

 private:
  pid_t pid_ = -1;
  bool exited_ = false;
  std::string address_;
  std::string owned_data_dir_;
  std::string stderr_path_;
};

}  // namespace shapeid

#endif  // SHAPEID_TESTS_SERVER_PROCESS_H_
