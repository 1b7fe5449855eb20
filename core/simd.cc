#include "core/simd.h"

#include <algorithm>
#include <cstdlib>

#include "core/enum_names.h"

namespace shapeid {
namespace {

constexpr EnumNames<SimdLevel, 3> kSimdLevelNames = {{
    {SimdLevel::kScalar, "scalar"},
    {SimdLevel::kAvx2, "avx2"},
    {SimdLevel::kAvx512, "avx512"},
}};

}  // namespace

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
    return std::min(ValueNamed(kSimdLevelNames, env).value_or(detected), detected);
  }();
  return level;
}

absl::string_view SimdLevelName(SimdLevel level) { return NameOf(kSimdLevelNames, level); }

}  // namespace shapeid
