#ifndef SHAPEID_SERVER_STORAGE_SAMPLE_CHECKSUM_H_
#define SHAPEID_SERVER_STORAGE_SAMPLE_CHECKSUM_H_

#include <zlib.h>

#include <cstdint>
#include <cstring>
#include <vector>

#include "absl/strings/string_view.h"
#include "absl/types/span.h"

namespace shapeid {

// Stored features are IEEE-754 float32, little-endian, one after another: the layout of this
// machine's memory. A big-endian port would byte-swap here.
static_assert(sizeof(float) == 4, "float must be IEEE-754 binary32");
#if defined(__BYTE_ORDER__) && __BYTE_ORDER__ != __ORDER_LITTLE_ENDIAN__
#error "stored features are little-endian; add a byte swap for this platform"
#endif

inline absl::Span<const uint8_t> FeatureBytes(absl::Span<const float> features) {
  return absl::Span<const uint8_t>(reinterpret_cast<const uint8_t*>(features.data()),
                                   features.size() * sizeof(float));
}

// Appends `bytes` of features to `out` (bit for bit; no float conversion).
inline void FeaturesFromBytes(absl::Span<const uint8_t> bytes, std::vector<float>* out) {
  out->resize(bytes.size() / sizeof(float));
  if (!bytes.empty()) std::memcpy(out->data(), bytes.data(), out->size() * sizeof(float));
}

// CRC-32 (zlib's) of one sample, continuing `crc` (0 to start): its id as 8 bytes
// little-endian, its label's bytes, its features as float32 little-endian. The definition of
// GalleryExportTrailer.crc32 in the proto, so a store row and an export agree.
inline uint32_t SampleCrc32(uint32_t crc, uint64_t id, absl::string_view label,
                            absl::Span<const float> features) {
  // zlib restarts at 0 when handed a null buffer, whatever the length (an empty label or
  // span may have a null data()): empty parts are skipped.
  const auto extend = [](uLong c, const void* data, size_t size) {
    return size == 0 ? c : crc32_z(c, static_cast<const Bytef*>(data), size);
  };
  uint8_t id_bytes[8];
  for (int i = 0; i < 8; ++i) id_bytes[i] = static_cast<uint8_t>(id >> (8 * i));
  uLong c = extend(crc, id_bytes, sizeof(id_bytes));
  c = extend(c, label.data(), label.size());
  const absl::Span<const uint8_t> bytes = FeatureBytes(features);
  c = extend(c, bytes.data(), bytes.size());
  return static_cast<uint32_t>(c);
}

}  // namespace shapeid

#endif  // SHAPEID_SERVER_STORAGE_SAMPLE_CHECKSUM_H_
