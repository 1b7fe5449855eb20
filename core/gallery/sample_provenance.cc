#include "core/gallery/sample_provenance.h"

#include <algorithm>

#include "absl/strings/str_cat.h"
#include "core/binary_codec.h"
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
  ByteWriter out;
  out.Bytes(std::string(1, static_cast<char>(kEncodingVersion)));
  out.String(provenance.source);
  out.U32(static_cast<uint32_t>(provenance.metadata.size()));
  for (const auto& [key, value] : provenance.metadata) {
    out.String(key);
    out.String(value);
  }
  return std::move(out).Finish();
}

absl::StatusOr<SampleProvenance> DecodeProvenance(absl::string_view bytes) {
  SampleProvenance provenance;
  if (bytes.empty()) return provenance;
  const auto damaged = [](absl::string_view what) {
    return absl::DataLossError(absl::StrCat("sample provenance: ", what));
  };
  if (bytes.size() < 1 + 4 + 4 + 4) return damaged(absl::StrCat(bytes.size(), " bytes"));
  ByteReader reader;
  if (!reader.Open(bytes)) return damaged("checksum mismatch");
  absl::string_view version;
  reader.Bytes(1, version);
  if (static_cast<uint8_t>(version[0]) != kEncodingVersion) {
    return damaged(absl::StrCat("encoding version ", static_cast<int>(version[0])));
  }
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
  if (reader.left() != 0) return damaged("bytes after the metadata");
  return provenance;
}

}  // namespace shapeid
