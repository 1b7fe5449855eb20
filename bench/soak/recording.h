#ifndef SHAPEID_BENCH_SOAK_RECORDING_H_
#define SHAPEID_BENCH_SOAK_RECORDING_H_

// What the soak clients did: the kinds of request, their latencies per client (swapped out
// by the sampler at each window's end) and the first errors in full. Thread-safe.

#include <cstdint>
#include <mutex>
#include <string>
#include <vector>

#include "absl/status/status.h"

namespace shapeid::soak {

enum Kind {
  kTrain,
  kClassifyCloud,
  kClassifyStream,
  kDescribeCloud,
  kDescribeStream,
  kCreateGallery,
  kGetGallery,
  kListGalleries,
  kRemoveSamples,
  kDeleteGallery,
  kExportGallery,
  kImportGallery,
  kRecognizeScene,
  kNumKinds
};

// The name of each Kind in the output.
extern const char* const kKindNames[kNumKinds];

// What the clients did since the last window: latencies (ns) of successful requests by kind
// and the number of errors.
struct Tally {
  std::vector<int64_t> ns[kNumKinds];
  int64_t errors = 0;
};

// Every client's Tally; a client records into a slot of its own, so clients do not contend.
class Recorder {
 public:
  explicit Recorder(int clients) : slots_(static_cast<size_t>(clients)) {}

  // `client` in [0, clients). `ns` counts only when `ok`.
  void Record(int client, Kind kind, int64_t ns, bool ok);
  // Everything recorded since the last Take, all clients merged; the slots start empty again.
  Tally Take();

 private:
  struct Slot {
    std::mutex mu;
    Tally tally;
  };
  std::vector<Slot> slots_;
};

// The first 10 errors in full, and how many there were.
class ErrorLog {
 public:
  void Add(double at_s, int client, Kind kind, const absl::Status& status);
  int64_t count() const;
  std::vector<std::string> first() const;

 private:
  mutable std::mutex mu_;
  int64_t count_ = 0;
  std::vector<std::string> first_;
};

}  // namespace shapeid::soak

#endif  // SHAPEID_BENCH_SOAK_RECORDING_H_
