#ifndef SHAPEID_FUZZ_FUZZ_ORACLE_H_
#define SHAPEID_FUZZ_FUZZ_ORACLE_H_

#include <cstdio>
#include <cstdlib>

#include "absl/status/status.h"

namespace shapeid::fuzz {

// Stops the run with a message: libFuzzer records the input as a crash. Every target's
// oracles beyond "no crash" report through this.
inline void Fail(const char* what, const absl::Status& status = absl::OkStatus()) {
  std::fprintf(stderr, "fuzz oracle failed: %s: %s\n", what, status.ToString().c_str());
  std::abort();
}

}  // namespace shapeid::fuzz

#endif  // SHAPEID_FUZZ_FUZZ_ORACLE_H_
