#include "core/descriptors/heap_meter.h"

#include <atomic>
#include <cerrno>
#include <cstddef>
#include <cstdint>

#if defined(__has_feature)
#if __has_feature(address_sanitizer) || __has_feature(thread_sanitizer) || \
    __has_feature(memory_sanitizer)
#define SHAPEID_HEAP_METER_OFF 1
#endif
#endif
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__) || !defined(__GLIBC__)
#define SHAPEID_HEAP_METER_OFF 1
#endif

namespace shapeid::heap_meter {
namespace {

std::atomic<bool> armed{false};
std::atomic<int64_t> live{0};
std::atomic<int64_t> peak{0};

#ifndef SHAPEID_HEAP_METER_OFF
void Add(int64_t bytes) {
  const int64_t now = live.fetch_add(bytes, std::memory_order_relaxed) + bytes;
  int64_t seen = peak.load(std::memory_order_relaxed);
  while (now > seen && !peak.compare_exchange_weak(seen, now, std::memory_order_relaxed)) {
  }
}
#endif

}  // namespace

bool Available() {
#ifdef SHAPEID_HEAP_METER_OFF
  return false;
#else
  return true;
#endif
}

void Start() {
  armed.store(false);
  live.store(0);
  peak.store(0);
  armed.store(true);
}

int64_t Stop() {
  armed.store(false);
  return peak.load();
}

int64_t Live() { return live.load(); }

}  // namespace shapeid::heap_meter

#ifndef SHAPEID_HEAP_METER_OFF
// glibc's allocator under its internal names (exported for exactly this use), and the
// replacements every library of the program binds to instead of glibc's malloc.
extern "C" {
void* __libc_malloc(size_t size);
void __libc_free(void* block);
void* __libc_calloc(size_t count, size_t size);
void* __libc_realloc(void* block, size_t size);
void* __libc_memalign(size_t alignment, size_t size);
void* __libc_valloc(size_t size);
void* __libc_pvalloc(size_t size);
size_t malloc_usable_size(void* block);
}

namespace {

using shapeid::heap_meter::Add;
using shapeid::heap_meter::armed;

inline void Count(void* block, int sign) {
  if (block != nullptr && armed.load(std::memory_order_relaxed)) {
    Add(sign * static_cast<int64_t>(malloc_usable_size(block)));
  }
}

inline void* Counted(void* block) {
  Count(block, 1);
  return block;
}

}  // namespace

extern "C" {

void* malloc(size_t size) { return Counted(__libc_malloc(size)); }

void free(void* block) {
  Count(block, -1);
  __libc_free(block);
}

void* calloc(size_t count, size_t size) { return Counted(__libc_calloc(count, size)); }

void* realloc(void* block, size_t size) {
  const int64_t before =
      block != nullptr ? static_cast<int64_t>(malloc_usable_size(block)) : int64_t{0};
  void* moved = __libc_realloc(block, size);
  if (armed.load(std::memory_order_relaxed)) {
    // realloc(p, 0) frees p and returns null; a failed realloc keeps p.
    if (moved != nullptr) {
      Add(static_cast<int64_t>(malloc_usable_size(moved)) - before);
    } else if (size == 0) {
      Add(-before);
    }
  }
  return moved;
}

void* memalign(size_t alignment, size_t size) { return Counted(__libc_memalign(alignment, size)); }

void* aligned_alloc(size_t alignment, size_t size) {
  return Counted(__libc_memalign(alignment, size));
}

int posix_memalign(void** out, size_t alignment, size_t size) {
  if (alignment % sizeof(void*) != 0 || (alignment & (alignment - 1)) != 0) return EINVAL;
  void* block = __libc_memalign(alignment, size);
  if (block == nullptr) return ENOMEM;
  *out = Counted(block);
  return 0;
}

void* valloc(size_t size) { return Counted(__libc_valloc(size)); }

void* pvalloc(size_t size) { return Counted(__libc_pvalloc(size)); }

}  // extern "C"
#endif  // SHAPEID_HEAP_METER_OFF
