#ifndef SHAPEID_CORE_DESCRIPTORS_COST_MODEL_H_
#define SHAPEID_CORE_DESCRIPTORS_COST_MODEL_H_

// Pieces shared by the descriptors' EstimateCost (core/descriptor.h). Their CPU constants
// come from bench/describe_cost_bench on the machine docs/performance.md names.

#include <cstddef>

#include "absl/time/time.h"

namespace shapeid::cost_model {

// What glibc adds to the blocks of one describe beyond their sizes: a header and 16-byte
// rounding per block and a page for each block it maps, for the few dozen blocks a call
// allocates.
inline constexpr size_t kHeapSlack = size_t{64} << 10;

// The capacity a std::vector reaches by push_back of n elements (libstdc++ doubles from 1).
inline size_t GrownCapacity(size_t n) {
  size_t capacity = n > 0 ? 1 : 0;
  while (capacity < n) capacity *= 2;
  return capacity;
}

// Bytes a vector holds at its worst while push_back grows it to n elements of `size` bytes:
// the old and the new block at the last doubling.
inline size_t GrownBytes(size_t n, size_t size) {
  const size_t capacity = GrownCapacity(n);
  return (capacity + capacity / 2) * size;
}

inline absl::Duration Nanoseconds(double ns) { return absl::Nanoseconds(ns); }

}  // namespace shapeid::cost_model

#endif  // SHAPEID_CORE_DESCRIPTORS_COST_MODEL_H_
