#ifndef SHAPEID_SERVER_STORAGE_TESTING_POSTGRES_INSTANCE_H_
#define SHAPEID_SERVER_STORAGE_TESTING_POSTGRES_INSTANCE_H_

// A private, throwaway PostgreSQL server for tests: Debian's own binaries (package
// `postgresql`), a fresh cluster in a temporary directory, listening on 127.0.0.1 on a free
// port, trust authentication, gone with the object. Tests that need one call
// PostgresInstance::StartOrSkip; CI installs the package and sets
// SHAPEID_REQUIRE_POSTGRES=1, so that there a missing PostgreSQL fails instead of skipping.

#include <glob.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <memory>
#include <string>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"

namespace shapeid {

class PostgresInstance {
 public:
  // Unavailable (saying what is missing or what failed, with the server's log) if no cluster
  // can be started.
  static absl::StatusOr<std::unique_ptr<PostgresInstance>> Start() {
    const std::string bin = FindBinDir();
    if (bin.empty()) {
      return absl::UnavailableError(
          "PostgreSQL's server binaries (/usr/lib/postgresql/*/bin/initdb) are not installed; "
          "apt-get install postgresql");
    }
    char pattern[] = "/tmp/shapeid_pg_XXXXXX";
    if (mkdtemp(pattern) == nullptr) return absl::UnavailableError("mkdtemp failed");
    std::unique_ptr<PostgresInstance> pg(new PostgresInstance(bin, pattern, FreePort()));
    // initdb refuses to run as root: run the server as Debian's `postgres` user then.
    if (geteuid() == 0) {
      pg->as_user_ = "runuser -u postgres -- ";
      if (!Run(absl::StrCat("chown postgres '", pg->dir_, "'")).ok()) {
        return absl::UnavailableError("cannot hand the cluster directory to user postgres");
      }
    }
    if (absl::Status s = pg->RunAsOwner(absl::StrCat("'", bin, "/initdb' -D '", pg->dir_,
                                                     "/data' -U shapeid --auth=trust -E UTF8 "
                                                     "--no-sync >'",
                                                     pg->dir_, "/initdb.log' 2>&1"));
        !s.ok()) {
      return absl::UnavailableError(absl::StrCat("initdb failed: ", pg->ReadFile("initdb.log")));
    }
    for (int attempt = 1;; ++attempt) {
      absl::Status started = pg->StartServer();
      if (started.ok()) break;
      // The port was free when chosen, but another process (a test running beside this one)
      // bound it before PostgreSQL did: choose another.
      if (attempt < 5 && absl::StrContains(started.message(), "Address already in use")) {
        pg->port_ = FreePort();
        continue;
      }
      return started;
    }
    return pg;
  }

  // Start, or the reason to skip; fails instead of skipping under SHAPEID_REQUIRE_POSTGRES.
  static bool Required() {
    const char* value = std::getenv("SHAPEID_REQUIRE_POSTGRES");
    return value != nullptr && std::string(value) == "1";
  }

  ~PostgresInstance() {
    (void)RunAsOwner(absl::StrCat("'", bin_, "/pg_ctl' -D '", dir_,
                                  "/data' -m immediate -w stop >/dev/null 2>&1"));
    (void)Run(absl::StrCat("rm -rf '", dir_, "'"));
  }

  // libpq connection string for database `postgres` as superuser shapeid.
  std::string conninfo() const {
    return absl::StrCat("postgresql://shapeid@127.0.0.1:", port_, "/postgres");
  }
  int port() const { return port_; }

  // Stops the server (fast shutdown: clients are disconnected) / starts it again, same port.
  absl::Status Stop() {
    return RunAsOwner(absl::StrCat("'", bin_, "/pg_ctl' -D '", dir_, "/data' -m fast -w stop >>'",
                                   dir_, "/server.log' 2>&1"));
  }
  absl::Status StartServer() {
    const absl::Status started = RunAsOwner(absl::StrCat(
        "'", bin_, "/pg_ctl' -D '", dir_, "/data' -l '", dir_, "/server.log' -w -t 30 -o \"",
        "-c listen_addresses=127.0.0.1 -p ", port_, " -k '", dir_,
        "' -c fsync=off -c max_connections=200\" start >/dev/null 2>&1"));
    if (!started.ok()) {
      return absl::UnavailableError(
          absl::StrCat("PostgreSQL did not start: ", ReadFile("server.log")));
    }
    return absl::OkStatus();
  }

 private:
  PostgresInstance(std::string bin, std::string dir, int port)
      : bin_(std::move(bin)), dir_(std::move(dir)), port_(port) {}

  static std::string FindBinDir() {
    glob_t found{};
    std::string dir;
    if (glob("/usr/lib/postgresql/*/bin/initdb", 0, nullptr, &found) == 0 && found.gl_pathc > 0) {
      dir = found.gl_pathv[found.gl_pathc - 1];  // the newest version
      dir.resize(dir.size() - std::string("/initdb").size());
    }
    globfree(&found);
    return dir;
  }

  static int FreePort() {
    const int fd = socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in address{};
    address.sin_family = AF_INET;
    address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    socklen_t length = sizeof(address);
    int port = 0;
    if (bind(fd, reinterpret_cast<sockaddr*>(&address), sizeof(address)) == 0 &&
        getsockname(fd, reinterpret_cast<sockaddr*>(&address), &length) == 0) {
      port = ntohs(address.sin_port);
    }
    close(fd);
    return port;
  }

  static absl::Status Run(const std::string& command) {
    const int code = std::system(command.c_str());
    if (code != 0) return absl::InternalError(absl::StrCat("`", command, "` exited ", code));
    return absl::OkStatus();
  }
  absl::Status RunAsOwner(const std::string& command) const {
    return Run(as_user_.empty() ? command
                                : absl::StrCat(as_user_, "sh -c \"", Escape(command), "\""));
  }
  static std::string Escape(const std::string& command) {
    std::string out;
    for (char c : command) {
      if (c == '"' || c == '\\' || c == '$' || c == '`') out += '\\';
      out += c;
    }
    return out;
  }
  std::string ReadFile(const std::string& name) const {
    std::string text;
    if (FILE* f = std::fopen((dir_ + "/" + name).c_str(), "r")) {
      char buf[4096];
      size_t n;
      while ((n = std::fread(buf, 1, sizeof(buf), f)) > 0) text.append(buf, n);
      std::fclose(f);
    }
    return text;
  }

  const std::string bin_;
  const std::string dir_;
  int port_;  // fixed once the server has started
  std::string as_user_;
};

}  // namespace shapeid

#endif  // SHAPEID_SERVER_STORAGE_TESTING_POSTGRES_INSTANCE_H_
