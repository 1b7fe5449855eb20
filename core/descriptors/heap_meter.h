#ifndef SHAPEID_CORE_DESCRIPTORS_HEAP_METER_H_
#define SHAPEID_CORE_DESCRIPTORS_HEAP_METER_H_

// The peak heap of a stretch of code, for the tests and benchmarks that check
// Descriptor::EstimateCost's working_bytes against what a Compute really allocates. Linking
// this file into a program replaces malloc, free and friends in that program with glibc's own
// (__libc_malloc, ...) plus a count of the bytes live while a meter runs; every allocation
// goes through them: operator new, Eigen's aligned_malloc, std::vector. Never linked into a
// library: only test and benchmark executables.
//
// Counts usable sizes (malloc_usable_size, what glibc really reserves, not what was asked),
// so the peak is never below the true one. Not available under AddressSanitizer or
// ThreadSanitizer, which replace malloc themselves: Available() is false there and the meter
// counts nothing.

#include <cstddef>
#include <cstdint>

namespace shapeid::heap_meter {

// False where the allocator could not be replaced (sanitizer builds).
bool Available();

// Starts a measurement: the live and peak counts restart from 0. One measurement at a time,
// process-wide; blocks freed meanwhile that were allocated before Start lower the live count.
void Start();
// Ends it and returns the peak of (bytes allocated - bytes freed) since Start.
int64_t Stop();
// (bytes allocated - bytes freed) since Start, now: what the code measured still holds.
int64_t Live();

}  // namespace shapeid::heap_meter

#endif  // SHAPEID_CORE_DESCRIPTORS_HEAP_METER_H_
