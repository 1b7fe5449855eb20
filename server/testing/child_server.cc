#include "server/testing/child_server.h"

#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <fstream>
#include <sstream>

#include "absl/strings/str_cat.h"
#include "absl/time/clock.h"

extern char** environ;

namespace shapeid {

absl::Status ChildServer::Start(const std::string& binary, const std::vector<std::string>& flags,
                                const std::string& stderr_path, absl::Duration timeout) {
  stderr_path_ = stderr_path;
  int out[2];
  if (pipe(out) != 0) return absl::InternalError(absl::StrCat("pipe: ", std::strerror(errno)));
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_adddup2(&actions, out[1], STDOUT_FILENO);
  posix_spawn_file_actions_addclose(&actions, out[0]);
  posix_spawn_file_actions_addopen(&actions, STDERR_FILENO, stderr_path.c_str(),
                                   O_WRONLY | O_CREAT | O_TRUNC, 0644);
  std::vector<std::string> args = {binary};
  args.insert(args.end(), flags.begin(), flags.end());
  std::vector<char*> argv;
  for (std::string& arg : args) argv.push_back(arg.data());
  argv.push_back(nullptr);
  const int spawned = posix_spawn(&pid_, binary.c_str(), &actions, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  close(out[1]);
  if (spawned != 0) {
    close(out[0]);
    pid_ = -1;
    return absl::UnavailableError(
        absl::StrCat("cannot run ", binary, ": ", std::strerror(spawned)));
  }
  std::string line;
  const absl::Time deadline = absl::Now() + timeout;
  fcntl(out[0], F_SETFL, O_NONBLOCK);
  while (absl::Now() < deadline && line.find('\n') == std::string::npos) {
    char buf[256];
    const ssize_t n = read(out[0], buf, sizeof(buf));
    if (n > 0) {
      line.append(buf, static_cast<size_t>(n));
    } else if (n == 0) {
      break;  // it exited: a start-up error
    } else {
      absl::SleepFor(absl::Milliseconds(10));
    }
  }
  close(out[0]);
  const std::string prefix = "listening on ";
  if (line.rfind(prefix, 0) != 0 || line.find('\n') == std::string::npos) {
    return absl::UnavailableError(absl::StrCat(binary, " reported no address within ",
                                               absl::FormatDuration(timeout), "; its stderr:\n",
                                               StderrText()));
  }
  address_ = line.substr(prefix.size(), line.find('\n') - prefix.size());
  return absl::OkStatus();
}

int ChildServer::Poll() {
  if (exited_) return status_;
  int raw = 0;
  if (pid_ > 0 && waitpid(pid_, &raw, WNOHANG) == pid_) {
    exited_ = true;
    status_ = WIFEXITED(raw) ? WEXITSTATUS(raw) : 128 + WTERMSIG(raw);
  }
  return status_;
}

int ChildServer::WaitForExit(absl::Duration timeout) {
  const absl::Time deadline = absl::Now() + timeout;
  while (Poll() < 0 && pid_ > 0 && absl::Now() < deadline) absl::SleepFor(absl::Milliseconds(20));
  return Poll();
}

int ChildServer::Terminate(absl::Duration timeout) {
  if (pid_ > 0 && Poll() < 0) kill(pid_, SIGTERM);
  return WaitForExit(timeout);
}

void ChildServer::Kill() {
  if (pid_ > 0 && Poll() < 0) {
    kill(pid_, SIGKILL);
    int raw = 0;
    waitpid(pid_, &raw, 0);
    exited_ = true;
    status_ = 128 + SIGKILL;
  }
}

std::string ChildServer::StderrText() const {
  std::ifstream in(stderr_path_);
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

int64_t ChildServer::StatusField(const char* key) const {
  std::ifstream in(absl::StrCat("/proc/", pid_, "/status"));
  std::string word;
  while (in >> word) {
    if (word == key) {
      int64_t kib = 0;
      in >> kib;
      return kib * 1024;
    }
    in.ignore(1 << 12, '\n');
  }
  return 0;
}

int64_t ChildServer::ResidentBytes() const { return StatusField("VmRSS:"); }
int64_t ChildServer::PeakResidentBytes() const { return StatusField("VmHWM:"); }

absl::Duration ChildServer::CpuTime() const {
  std::ifstream in(absl::StrCat("/proc/", pid_, "/stat"));
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const size_t paren = text.rfind(')');
  if (paren == std::string::npos) return absl::ZeroDuration();
  std::istringstream fields(text.substr(paren + 2));  // from field 3
  std::string skip;
  for (int i = 3; i < 14; ++i) fields >> skip;
  double utime = 0, stime = 0;
  fields >> utime >> stime;
  return absl::Seconds((utime + stime) / static_cast<double>(sysconf(_SC_CLK_TCK)));
}

}  // namespace shapeid
