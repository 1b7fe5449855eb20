#ifndef SHAPEID_CORE_PARALLEL_RANGES_H_
#define SHAPEID_CORE_PARALLEL_RANGES_H_

#include <algorithm>
#include <cstdint>
#include <thread>
#include <vector>

namespace shapeid {

// How many parts ParallelRanges splits `count` items into: at most `threads`, and none
// smaller than `min_per_part` items (small jobs stay on the calling thread: starting a thread
// costs tens of microseconds). Always >= 1.
inline int ParallelParts(int64_t count, int threads, int64_t min_per_part) {
  return static_cast<int>(
      std::clamp<int64_t>(count / std::max<int64_t>(min_per_part, 1), 1, std::max(threads, 1)));
}

// Runs body(part, begin, end) over [0, count) split into ParallelParts(...) contiguous ranges
// in order (part p covers [count * p / parts, count * (p + 1) / parts)); the calling thread
// takes part 0, and the call returns when every part has. Returns the number of parts, so a
// caller that keeps per-part state can size it with ParallelParts first.
template <typename Body>
int ParallelRanges(int64_t count, int threads, int64_t min_per_part, const Body& body) {
  const int parts = ParallelParts(count, threads, min_per_part);
  std::vector<std::thread> workers;
  workers.reserve(static_cast<size_t>(parts - 1));
  for (int p = 1; p < parts; ++p) {
    workers.emplace_back(body, p, count * p / parts, count * (p + 1) / parts);
  }
  body(0, int64_t{0}, count / parts);
  for (std::thread& worker : workers) worker.join();
  return parts;
}

}  // namespace shapeid

#endif  // SHAPEID_CORE_PARALLEL_RANGES_H_
