#ifndef SHAPEID_CORE_GALLERY_SAMPLE_PROVENANCE_H_
#define SHAPEID_CORE_GALLERY_SAMPLE_PROVENANCE_H_

#include <cstddef>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"

namespace shapeid {

// Where a trained sample came from, kept beside its descriptors so that an answer can be
// traced to the scan it matched (a vector database's payload): the file or URI it was read
// from, and a few key/value pairs of the caller's (camera, session, operator...). Stored,
// exported, replicated and returned with every neighbor; never used by the search.
struct SampleProvenance {
  std::string source;
  // Sorted by key, keys unique (ValidateProvenance's form; NormalizeMetadata makes it).
  std::vector<std::pair<std::string, std::string>> metadata;

  bool empty() const { return source.empty() && metadata.empty(); }
  friend bool operator==(const SampleProvenance& a, const SampleProvenance& b) {
    return a.source == b.source && a.metadata == b.metadata;
  }
  friend bool operator!=(const SampleProvenance& a, const SampleProvenance& b) { return !(a == b); }
};

// Limits: small enough that provenance never outweighs a descriptor (a DFSD is ~1 KB).
inline constexpr size_t kMaxSourceBytes = 4096;
inline constexpr size_t kMaxMetadataEntries = 64;
inline constexpr size_t kMaxMetadataBytes = 4096;  // keys and values together

// Sorts `metadata` by key. InvalidArgument naming the key when a key appears twice.
absl::Status NormalizeMetadata(std::vector<std::pair<std::string, std::string>>& metadata);

// InvalidArgument unless the source and every key and value are valid UTF-8, keys are
// non-empty, sorted and unique, and the limits above hold; the message names what is wrong.
absl::Status ValidateProvenance(const SampleProvenance& provenance);

// The bytes of text `provenance` holds: its source and every key and value (what the limits
// above bound: at most 8,192). What an answer that returns it carries, less framing.
size_t ProvenanceBytes(const SampleProvenance& provenance);
// An estimate of the heap `provenance` holds once shared in a gallery: its strings' and its
// metadata vector's capacities and the shared object with its control block, each allocation
// as glibc's malloc sizes it (core/heap_chunk.h). About 16 KiB at the limits.
size_t ProvenanceMemoryBytes(const SampleProvenance& provenance);

// The stores' byte form of a non-empty provenance: version byte 1, then the source, the
// number of pairs and each key and value, every length and count a little-endian uint32,
// then a CRC-32 (zlib's) of everything before it, little-endian. Empty provenance: "".
std::string EncodeProvenance(const SampleProvenance& provenance);
// The inverse; "" gives an empty provenance. DataLoss, saying what is wrong, for bytes that
// are not such an encoding (damage caught by the CRC included). Strings and the metadata
// vector are allocated at their exact sizes, as a copy of the provenance would be, so a
// gallery loaded from a store holds what the one trained did.
absl::StatusOr<SampleProvenance> DecodeProvenance(absl::string_view bytes);

}  // namespace shapeid

#endif  // SHAPEID_CORE_GALLERY_SAMPLE_PROVENANCE_H_
