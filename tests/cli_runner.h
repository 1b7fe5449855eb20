#ifndef SHAPEID_TESTS_CLI_RUNNER_H_
#define SHAPEID_TESTS_CLI_RUNNER_H_

// Runs the real `shapeid` binary (SHAPEID_CLI_PATH, defined by the build) for end-to-end tests.

#include <sys/wait.h>

#include <cstdlib>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "absl/strings/str_cat.h"
#include "core/io/io_testing.h"

namespace shapeid {

struct RunResult {
  int exit_code = -1;
  std::string out;
  std::string err;
};

inline std::string ShellQuote(const std::string& arg) {
  std::string quoted = "'";
  for (char c : arg) quoted += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return quoted + "'";
}

inline std::string Slurp(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

// Runs the built `shapeid` with `args` through the shell, capturing both streams; standard
// input is `stdin_path` when given.
inline RunResult Shapeid(const std::vector<std::string>& args, const std::string& stdin_path = "") {
  const std::string out_path = WriteTempFile("stdout", "");
  const std::string err_path = WriteTempFile("stderr", "");
  std::string command = ShellQuote(SHAPEID_CLI_PATH);
  for (const std::string& arg : args) absl::StrAppend(&command, " ", ShellQuote(arg));
  absl::StrAppend(&command, " >", ShellQuote(out_path), " 2>", ShellQuote(err_path));
  if (!stdin_path.empty()) absl::StrAppend(&command, " <", ShellQuote(stdin_path));
  const int status = std::system(command.c_str());
  RunResult run;
  run.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  run.out = Slurp(out_path);
  run.err = Slurp(err_path);
  return run;
}

}  // namespace shapeid

#endif  // SHAPEID_TESTS_CLI_RUNNER_H_
