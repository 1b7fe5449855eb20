#ifndef SHAPEID_CORE_SIMD_H_
#define SHAPEID_CORE_SIMD_H_

#include "absl/strings/string_view.h"

namespace shapeid {

// Instruction-set levels that hot loops dispatch on at run time. Release binaries are built
// for the x86-64 baseline and must run anywhere; faster kernels are compiled with function
// target attributes and chosen here. Every level computes bit-identical results (same IEEE
// operations in the same order, no FMA contraction), so a gallery does not depend on the
// machine that built it.
enum class SimdLevel { kScalar = 0, kAvx2 = 1, kAvx512 = 2 };

// What this CPU supports.
SimdLevel DetectedSimdLevel();

// The level kernels use: DetectedSimdLevel(), lowered by the environment variable
// SHAPEID_SIMD=scalar|avx2|avx512 when set (never raised above what the CPU supports).
// Read once; used by tests and benchmarks to compare levels in one process.
SimdLevel ActiveSimdLevel();

absl::string_view SimdLevelName(SimdLevel level);

}  // namespace shapeid

#endif  // SHAPEID_CORE_SIMD_H_
