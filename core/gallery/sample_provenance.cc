#include "core/gallery/sample_provenance.h"

#include <zlib.h>

#include <algorithm>

#include "absl/strings/str_cat.h"
#include "core/gallery/gallery_options.h"
#include "core/heap_chunk.h"

namespace shapeid {

namespace {

constexpr uint8_t kEncodingVersion = 1;

absl::Status CheckUtf8(absl::string_view what, absl::string_view text) {
  const size_t bad = InvalidUtf8Offset(text);
  if (bad == absl::string_view::npos) return absl::OkStatus();
  return absl::InvalidArgumentError(
      absl::StrCat(what, " ", QuoteForMessage(text), " is not valid UTF-8 (at byte ", bad, ")"));
}

void PutU32(uint32_t value, std::string& out) {
  for (int i = 0; i < 4; ++i) out.push_back(static_cast<char>((value >> (8 * i)) & 0xff));
}

void PutString(absl::string_view text, std::string& out) {
  PutU32(static_cast<uint32_t>(text.size()), out);
  out.append(text.data(), text.size());
}

uint32_t Crc(absl::string_view bytes) {
  if (bytes.empty()) return 0;
  return static_cast<uint32_t>(
      crc32_z(0, reinterpret_cast<const Bytef*>(bytes.data()), bytes.size()));
}

// Reads the encoding front to back; every read checks the bytes left.
class Reader {
 public:
  explicit Reader(absl::string_view bytes) : rest_(bytes) {}
  bool U32(uint32_t& value) {
    if (rest_.size() < 4) return false;
    value = 0;
    for (int i = 0; i < 4; ++i) value |= uint32_t{static_cast<uint8_t>(rest_[i])} << (8 * i);
    rest_.remove_prefix(4);
    return true;
  }
  bool String(std::string& text) {
    uint32_t size;
    if (!U32(size) || rest_.size() < size) return false;
    // Constructed, not assigned: assign() would leave a growth capacity (30 bytes for 16).
    text = std::string(rest_.data(), size);
    rest_.remove_prefix(size);
    return true;
  }
  bool done() const { return rest_.empty(); }
  size_t left() const { return rest_.size(); }

 private:
  absl::string_view rest_;
};

}  // namespace

absl::Status NormalizeMetadata(std::vector<std::pair<std::string, std::string>>& metadata) {
  std::sort(metadata.begin(), metadata.end());
  for (size_t i = 1; i < metadata.size(); ++i) {
    if (metadata[i].first == metadata[i - 1].first) {
      return absl::InvalidArgumentError(
          absl::StrCat("metadata key ", QuoteForMessage(metadata[i].first), " is given twice"));
    }
  }
  return absl::OkStatus();
}

absl::Status ValidateProvenance(const SampleProvenance& provenance) {
  if (provenance.source.size() > kMaxSourceBytes) {
    return absl::InvalidArgumentError(
        absl::StrCat("source ", QuoteForMessage(provenance.source), " has ",
                     provenance.source.size(), " bytes, more than the limit of ", kMaxSourceBytes));
  }
  if (absl::Status s = CheckUtf8("source", provenance.source); !s.ok()) return s;
  if (provenance.metadata.size() > kMaxMetadataEntries) {
    return absl::InvalidArgumentError(absl::StrCat("metadata has ", provenance.metadata.size(),
                                                   " entries, more than the limit of ",
                                                   kMaxMetadataEntries));
  }
  size_t bytes = 0;
  for (size_t i = 0; i < provenance.metadata.size(); ++i) {
    const auto& [key, value] = provenance.metadata[i];
    if (key.empty()) return absl::InvalidArgumentError("a metadata key is empty");
    if (i > 0 && !(provenance.metadata[i - 1].first < key)) {
      return absl::InvalidArgumentError(
          absl::StrCat("metadata key ", QuoteForMessage(key), " is out of order or given twice"));
    }
    if (absl::Status s = CheckUtf8("metadata key", key); !s.ok()) return s;
    if (absl::Status s = CheckUtf8(absl::StrCat("metadata value of ", QuoteForMessage(key)), value);
        !s.ok()) {
      return s;
    }
    bytes += key.size() + value.size();
  }
  if (bytes > kMaxMetadataBytes) {
    return absl::InvalidArgumentError(absl::StrCat("metadata has ", bytes,
                                                   " bytes of keys and values, more than the "
                                                   "limit of ",
                                                   kMaxMetadataBytes));
  }
  return absl::OkStatus();
}

size_t ProvenanceBytes(const SampleProvenance& provenance) {
  size_t bytes = provenance.source.size();
  for (const auto& [key, value] : provenance.metadata) bytes += key.size() + value.size();
  return bytes;
}

size_t ProvenanceMemoryBytes(const SampleProvenance& provenance) {
  size_t bytes = SharedHeapBytes<SampleProvenance>() + StringHeapBytes(provenance.source);
  if (provenance.metadata.capacity() > 0) {
    bytes += HeapChunkBytes(provenance.metadata.capacity() *
                            sizeof(decltype(provenance.metadata)::value_type));
  }
  for (const auto& [key, value] : provenance.metadata) {
    bytes += StringHeapBytes(key) + StringHeapBytes(value);
  }
  return bytes;
}

std::string EncodeProvenance(const SampleProvenance& provenance) {
  if (provenance.empty()) return "";
  std::string out(1, static_cast<char>(kEncodingVersion));
  PutString(provenance.source, out);
  PutU32(static_cast<uint32_t>(provenance.metadata.size()), out);
  for (const auto& [key, value] : provenance.metadata) {
    PutString(key, out);
    PutString(value, out);
  }
  PutU32(Crc(out), out);
  return out;
}

absl::StatusOr<SampleProvenance> DecodeProvenance(absl::string_view bytes) {
  SampleProvenance provenance;
  if (bytes.empty()) return provenance;
  const auto damaged = [](absl::string_view what) {
    return absl::DataLossError(absl::StrCat("sample provenance: ", what));
  };
  if (bytes.size() < 1 + 4 + 4 + 4) return damaged(absl::StrCat(bytes.size(), " bytes"));
  const absl::string_view body = bytes.substr(0, bytes.size() - 4);
  uint32_t stored_crc;
  Reader(bytes.substr(bytes.size() - 4)).U32(stored_crc);
  if (Crc(body) != stored_crc) return damaged("checksum mismatch");
  if (static_cast<uint8_t>(body[0]) != kEncodingVersion) {
    return damaged(absl::StrCat("encoding version ", static_cast<int>(body[0])));
  }
  Reader reader(body.substr(1));
  uint32_t entries;
  if (!reader.String(provenance.source) || !reader.U32(entries)) return damaged("truncated");
  // Each entry takes at least 8 bytes, so a damaged count can neither make this loop long
  // nor the reservation large.
  provenance.metadata.reserve(std::min<size_t>(entries, reader.left() / 8));
  for (uint32_t i = 0; i < entries; ++i) {
    std::string key, value;
    if (!reader.String(key) || !reader.String(value)) return damaged("truncated metadata");
    provenance.metadata.emplace_back(std::move(key), std::move(value));
  }
  if (!reader.done()) return damaged("bytes after the metadata");
  return provenance;
}

}  // namespace shapeid
