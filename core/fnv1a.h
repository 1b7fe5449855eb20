#ifndef SHAPEID_CORE_FNV1A_H_
#define SHAPEID_CORE_FNV1A_H_

#include <cstddef>
#include <cstdint>

namespace shapeid {

// FNV-1a, 64-bit, over bytes given in pieces: the same value as over their concatenation.
// For seeds, fingerprints and golden tests, never for security.
class Fnv1a {
 public:
  void Add(const void* data, size_t size) {
    const auto* bytes = static_cast<const unsigned char*>(data);
    for (size_t i = 0; i < size; ++i) value_ = (value_ ^ bytes[i]) * 0x100000001b3ull;
  }
  uint64_t value() const { return value_; }

 private:
  uint64_t value_ = 0xcbf29ce484222325ull;
};

}  // namespace shapeid

#endif  // SHAPEID_CORE_FNV1A_H_
