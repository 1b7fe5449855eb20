#ifndef SHAPEID_CORE_TARGET_REGION_H_
#define SHAPEID_CORE_TARGET_REGION_H_

// SHAPEID_TARGET_REGION_BEGIN("avx2") ... SHAPEID_TARGET_REGION_END: every function defined
// between them is compiled for that instruction set. GCC takes `#pragma GCC target`; clang
// (the fuzz build) ignores it and takes `#pragma clang attribute` instead.
#define SHAPEID_PRAGMA(x) _Pragma(#x)
#if defined(__clang__)
#define SHAPEID_TARGET_REGION_BEGIN(isa) \
  SHAPEID_PRAGMA(clang attribute push(__attribute__((target(isa))), apply_to = function))
#define SHAPEID_TARGET_REGION_END SHAPEID_PRAGMA(clang attribute pop)
// Warnings only GCC has (clang would warn that it does not know them).
#define SHAPEID_IGNORE_GCC_WARNING(w)
#else
#define SHAPEID_TARGET_REGION_BEGIN(isa) \
  SHAPEID_PRAGMA(GCC push_options) SHAPEID_PRAGMA(GCC target(isa))
#define SHAPEID_TARGET_REGION_END SHAPEID_PRAGMA(GCC pop_options)
#define SHAPEID_IGNORE_GCC_WARNING(w) SHAPEID_PRAGMA(GCC diagnostic ignored w)
#endif

#endif  // SHAPEID_CORE_TARGET_REGION_H_
