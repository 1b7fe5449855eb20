#include "core/simd.h"

#include <algorithm>
#include <cstdlib>
#include <cstring>

namespace shapeid {

SimdLevel DetectedSimdLevel() {
#if defined(__x86_64__) || defined(__i386__)
  __builtin_cpu_init();
  if (__builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512bw")) {
    return SimdLevel::kAvx512;
  }
  if (__builtin_cpu_supports("avx2")) return SimdLevel::kAvx2;
#endif
  return SimdLevel::kScalar;
}

SimdLevel ActiveSimdLevel() {
  static const SimdLevel level = [] {
    const SimdLevel detected = DetectedSimdLevel();
    const char* env = std::getenv("SHAPEID_SIMD");
    if (env == nullptr) return detected;
    SimdLevel wanted = detected;
    if (std::strcmp(env, "scalar") == 0) wanted = SimdLevel::kScalar;
    if (std::strcmp(env, "avx2") == 0) wanted = SimdLevel::kAvx2;
    if (std::strcmp(env, "avx512") == 0) wanted = SimdLevel::kAvx512;
    return std::min(wanted, detected);
  }();
  return level;
}

absl::string_view SimdLevelName(SimdLevel level) {
  switch (level) {
    case SimdLevel::kScalar:
      return "scalar";
    case SimdLevel::kAvx2:
      return "avx2";
    case SimdLevel::kAvx512:
      return "avx512";
  }
  return "unknown";
}

}  // namespace shapeid
