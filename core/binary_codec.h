#ifndef SHAPEID_CORE_BINARY_CODEC_H_
#define SHAPEID_CORE_BINARY_CODEC_H_

// The project's little-endian binary encoding (sample provenance, learned models, gallery
// heads): fixed-width integers, float32 runs and length-prefixed strings, closed by a CRC-32
// (zlib's) of everything before it. The
// reader checks every length against the bytes left before it allocates, so a hostile file
// can neither crash it nor make it allocate more than the file could fill.

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <string>
#include <utility>

#include "absl/status/status.h"
#include "absl/strings/string_view.h"

namespace shapeid {

uint32_t Crc32Of(absl::string_view bytes);

class ByteWriter {
 public:
  void U32(uint32_t v) {
    for (int i = 0; i < 4; ++i) out_.push_back(static_cast<char>((v >> (8 * i)) & 0xff));
  }
  void U64(uint64_t v) {
    U32(static_cast<uint32_t>(v));
    U32(static_cast<uint32_t>(v >> 32));
  }
  void Floats(const float* values, int64_t n) {
    for (int64_t i = 0; i < n; ++i) {
      uint32_t bits;
      std::memcpy(&bits, &values[i], 4);
      U32(bits);
    }
  }
  void Bytes(absl::string_view bytes) { out_.append(bytes.data(), bytes.size()); }
  // Begins a versioned file: its magic bytes, then its format version (OpenVersionedFile).
  void Header(absl::string_view magic, uint32_t version) {
    Bytes(magic);
    U32(version);
  }
  void String(absl::string_view s) {
    U32(static_cast<uint32_t>(s.size()));
    Bytes(s);
  }
  // The bytes written, closed by their CRC-32.
  std::string Finish() && {
    U32(Crc32Of(out_));
    return std::move(out_);
  }

 private:
  std::string out_;
};

class ByteReader {
 public:
  // False unless `bytes` ends with the CRC-32 of what precedes it; the reader then reads
  // only what precedes it.
  bool Open(absl::string_view bytes) {
    if (bytes.size() < 4) return false;
    ByteReader tail;
    tail.bytes_ = bytes.substr(bytes.size() - 4);
    uint32_t stored = 0;
    tail.U32(stored);
    bytes_ = bytes.substr(0, bytes.size() - 4);
    return stored == Crc32Of(bytes_);
  }
  bool U32(uint32_t& v) {
    if (bytes_.size() < 4) return false;
    v = 0;
    for (int i = 0; i < 4; ++i) v |= uint32_t{static_cast<unsigned char>(bytes_[i])} << (8 * i);
    bytes_.remove_prefix(4);
    return true;
  }
  bool U64(uint64_t& v) {
    uint32_t low = 0, high = 0;
    if (!U32(low) || !U32(high)) return false;
    v = (uint64_t{high} << 32) | low;
    return true;
  }
  // False when fewer than 4 * n bytes are left or a value is not finite.
  bool Floats(float* out, int64_t n) {
    if (n < 0 || static_cast<int64_t>(bytes_.size() / 4) < n) return false;
    for (int64_t i = 0; i < n; ++i) {
      uint32_t bits = 0;
      U32(bits);
      std::memcpy(&out[i], &bits, 4);
      if (!std::isfinite(out[i])) return false;
    }
    return true;
  }
  bool Bytes(size_t n, absl::string_view& out) {
    if (bytes_.size() < n) return false;
    out = bytes_.substr(0, n);
    bytes_.remove_prefix(n);
    return true;
  }
  // A length-prefixed string of at most `max_size` bytes. Constructed, not assigned: assign()
  // would leave a growth capacity (30 bytes for 16), which held provenance would pay for.
  bool String(std::string& out, size_t max_size = SIZE_MAX) {
    uint32_t size = 0;
    absl::string_view view;
    if (!U32(size) || size > max_size || !Bytes(size, view)) return false;
    out = std::string(view.data(), view.size());
    return true;
  }
  size_t left() const { return bytes_.size(); }

 private:
  absl::string_view bytes_;
};

// Opens a file that a ByteWriter began with Header(magic, version) and closed with Finish:
// checks the magic, the CRC-32 and the version, in that order, and leaves `reader` just after
// them. Otherwise DataLoss "not a shapeid <what>: <why>", the wording every reader of these
// files uses for its later checks too.
absl::Status OpenVersionedFile(absl::string_view bytes, absl::string_view magic, uint32_t version,
                               absl::string_view what, ByteReader& reader);

}  // namespace shapeid

#endif  // SHAPEID_CORE_BINARY_CODEC_H_
