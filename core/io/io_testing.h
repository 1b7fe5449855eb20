#ifndef SHAPEID_CORE_IO_IO_TESTING_H_
#define SHAPEID_CORE_IO_IO_TESTING_H_

// Test-only helpers: files written into testing::TempDir(), named after the running test so
// that tests run in parallel (ctest -j) never share one.

#include <unistd.h>

#include <cstdint>
#include <cstring>
#include <fstream>
#include <string>

#include "absl/status/statusor.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/string_view.h"
#include "core/io/read_options.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"

namespace shapeid {

// Writes `contents` to a fresh file whose name ends with `name` and returns its path.
inline std::string WriteTempFile(absl::string_view name, absl::string_view contents) {
  const testing::TestInfo* info = testing::UnitTest::GetInstance()->current_test_info();
  const std::string path = absl::StrCat(testing::TempDir(), "shapeid_", info->test_suite_name(),
                                        "_", info->name(), "_", ::getpid(), "_", name);
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(contents.data(), static_cast<std::streamsize>(contents.size()));
  out.close();
  EXPECT_TRUE(out.good()) << "cannot write " << path;
  return path;
}

// Appends the bytes of `value` in host byte order, as PCD binary data stores it.
template <typename T>
void AppendBytes(std::string* out, T value) {
  char bytes[sizeof(T)];
  std::memcpy(bytes, &value, sizeof(T));
  out->append(bytes, sizeof(T));
}

// Options that keep the file's coordinates (no recentering), so tests compare them exactly.
inline ReadOptions Raw() {
  ReadOptions options;
  options.recenter = false;
  return options;
}

// Asserts the error code and that the message names the file and the location.
inline void ExpectError(const absl::StatusOr<ReadResult>& result, absl::StatusCode code,
                        const std::string& path, const std::string& where) {
  ASSERT_FALSE(result.ok());
  EXPECT_EQ(result.status().code(), code) << result.status();
  EXPECT_THAT(std::string(result.status().message()), ::testing::HasSubstr(path));
  EXPECT_THAT(std::string(result.status().message()), ::testing::HasSubstr(where));
}

// Parses every prefix of `file` (the file cut at each byte, the whole file too) and checks that
// every rejection names `name`. `parse(contents)` returns absl::StatusOr<ReadResult>; as for
// ExpectCorruptionsNameTheFile, never crashing is the other half of the check.
template <typename Parse>
void ExpectPrefixesNameTheFile(const std::string& file, const std::string& name, Parse parse) {
  for (size_t n = 0; n <= file.size(); ++n) {
    const absl::StatusOr<ReadResult> r = parse(file.substr(0, n));
    if (!r.ok()) {
      EXPECT_THAT(std::string(r.status().message()), ::testing::HasSubstr(name)) << "prefix " << n;
    }
  }
}

// Parses `trials` copies of `file`, each with 3 bytes replaced by characters drawn from
// `replacements` (a seeded LCG whose state carries across calls), and checks that every
// rejection names `name`. `parse(contents)` returns absl::StatusOr<ReadResult>. Never
// crashing is the other half of the check: the dev preset runs this under ASan.
template <typename Parse>
void ExpectCorruptionsNameTheFile(const std::string& file, const std::string& name,
                                  absl::string_view replacements, uint64_t* state, Parse parse,
                                  int trials = 2000) {
  for (int trial = 0; trial < trials; ++trial) {
    std::string corrupt = file;
    for (int e = 0; e < 3; ++e) {
      *state = *state * 6364136223846793005ull + 1442695040888963407ull;
      corrupt[(*state >> 33) % corrupt.size()] = replacements[(*state >> 17) % replacements.size()];
    }
    const absl::StatusOr<ReadResult> r = parse(corrupt);
    if (!r.ok()) {
      EXPECT_THAT(std::string(r.status().message()), ::testing::HasSubstr(name));
    }
  }
}

}  // namespace shapeid

#endif  // SHAPEID_CORE_IO_IO_TESTING_H_
