#ifndef SHAPEID_CLIENT_CLI_CLI_TESTING_H_
#define SHAPEID_CLIENT_CLI_CLI_TESTING_H_

// Test-only helpers for the CLI's tests: a scratch folder per process and test, a small
// labeled dataset a classifier gets partly wrong, captured output streams, JSON Lines parsed
// back by python3, and eval's JSON output with its timings blanked (the one part that differs
// from run to run).

#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <regex>
#include <string>

#include "absl/strings/str_cat.h"
#include "core/io/pcd_writer.h"
#include "core/testing/test_clouds.h"
#include "gtest/gtest.h"

namespace shapeid::cli_testing {

namespace fs = std::filesystem;

// A fresh folder unique to this process and test (ctest runs tests in parallel processes).
inline fs::path ScratchDir(const std::string& prefix) {
  const fs::path dir =
      fs::path(::testing::TempDir()) /
      absl::StrCat(prefix, "_", ::getpid(), "_",
                   ::testing::UnitTest::GetInstance()->current_test_info()->name());
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

// DIR/<label>/{train,test}/NN.pcd (split) or DIR/<label>/NN.pcd, `per_label` clouds per label
// (a third of them test clouds when split), labels box, sphere and rod
// (testing_clouds::ShapeCloud), 150 to 350 points. Every fourth cloud has the shape of the
// next label: label noise, so that the predictions include mistakes.
inline void WriteLabeledDataset(const fs::path& dir, bool split, int per_label = 9) {
  for (int label = 0; label < 3; ++label) {
    for (int i = 0; i < per_label; ++i) {
      fs::path folder = dir / testing_clouds::kShapeNames[label];
      if (split) folder /= (i % 3 == 2 ? "test" : "train");
      fs::create_directories(folder);
      const int shape = i % 4 == 3 ? (label + 1) % 3 : label;
      const uint32_t seed = static_cast<uint32_t>(100 * label + i + 1);
      const size_t points = 150 + static_cast<size_t>((37 * i + 11 * label) % 201);
      const absl::Status written =
          WritePcd((folder / absl::StrCat(i / 10, i % 10, ".pcd")).string(),
                   testing_clouds::ShapeCloud(shape, seed, points));
      ASSERT_TRUE(written.ok()) << written;
    }
  }
}

// A FILE* whose contents tests can read back.
class Captured {
 public:
  Captured() : file_(std::tmpfile()) {}
  ~Captured() { std::fclose(file_); }
  Captured(const Captured&) = delete;
  Captured& operator=(const Captured&) = delete;
  std::FILE* get() const { return file_; }
  std::string contents() const {
    std::fflush(file_);
    std::rewind(file_);
    std::string text;
    char buffer[4096];
    size_t n;
    while ((n = std::fread(buffer, 1, sizeof buffer, file_)) > 0) text.append(buffer, n);
    return text;
  }

 private:
  std::FILE* file_;
};

// JSON Lines output parsed back by Debian's python3, as a script would: returns what the
// python snippet prints for the parsed list `rows`.
inline std::string PythonOnJsonLines(const std::string& text, const std::string& expression) {
  // One file per process and test: ctest runs the tests of a file in parallel processes.
  const std::string path =
      absl::StrCat(::testing::TempDir(), "/cli_json_lines_", ::getpid(), "_",
                   ::testing::UnitTest::GetInstance()->current_test_info()->name(), ".jsonl");
  std::ofstream(path, std::ios::binary) << text;
  const std::string command = absl::StrCat(
      "/usr/bin/python3 -c 'import json,sys; rows=[json.loads(l) for l in open(sys.argv[1])]; "
      "print(",
      expression, ")' ", path, " 2>&1");
  std::string out;
  if (std::FILE* pipe = ::popen(command.c_str(), "r")) {
    char buffer[4096];
    size_t n;
    while ((n = std::fread(buffer, 1, sizeof buffer, pipe)) > 0) out.append(buffer, n);
    ::pclose(pipe);
  }
  while (!out.empty() && out.back() == '\n') out.pop_back();
  return out;
}

// `json` with every "...seconds" value replaced by 0: what two equal evaluations share.
inline std::string WithoutTimes(const std::string& json) {
  static const std::regex kSeconds(R"re(("[a-z_]*seconds[a-z_]*"):[-+0-9.eE]+)re");
  return std::regex_replace(json, kSeconds, "$1:0");
}

}  // namespace shapeid::cli_testing

#endif  // SHAPEID_CLIENT_CLI_CLI_TESTING_H_
