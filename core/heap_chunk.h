#ifndef SHAPEID_CORE_HEAP_CHUNK_H_
#define SHAPEID_CORE_HEAP_CHUNK_H_

#include <algorithm>
#include <cstddef>
#include <string>

namespace shapeid {

// What a malloc of `bytes` (> 0) takes from glibc's heap: the request plus its 8-byte header,
// rounded up to 16 bytes, at least 32. The unit of the memory estimates (GallerySnapshot::
// memory_bytes); glibc serves requests of 128 KiB and more with whole pages, which this
// undercounts by less than a page.
inline std::size_t HeapChunkBytes(std::size_t bytes) {
  return std::max<std::size_t>(32, (bytes + 8 + 15) / 16 * 16);
}

// The heap a std::string holds beyond its object: none while it fits the object (SSO).
inline std::size_t StringHeapBytes(const std::string& text) {
  return text.capacity() > std::string().capacity() ? HeapChunkBytes(text.capacity() + 1) : 0;
}

// What std::make_shared<T> allocates: T with a control block (a vtable and two counts).
template <typename T>
std::size_t SharedHeapBytes() {
  return HeapChunkBytes(sizeof(void*) + 2 * sizeof(int) + sizeof(T));
}

}  // namespace shapeid

#endif  // SHAPEID_CORE_HEAP_CHUNK_H_
