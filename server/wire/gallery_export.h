#ifndef SHAPEID_SERVER_WIRE_GALLERY_EXPORT_H_
#define SHAPEID_SERVER_WIRE_GALLERY_EXPORT_H_

// A gallery as the stream of GalleryExportChunk messages that ExportGallery sends and
// ImportGallery receives (proto/shapeid/v1/shapeid.proto): the header, runs of samples, the
// trailer with the count and a CRC-32. Pure conversion: no gRPC calls, so the service stays
// a thin edge and these are tested directly.

#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "absl/types/span.h"
#include "core/gallery/gallery_snapshot.h"
#include "core/gallery/gallery_store.h"
#include "shapeid/v1/shapeid.pb.h"

namespace shapeid {

// The export format this server writes, and the only one it reads.
inline constexpr uint32_t kGalleryExportFormatVersion = 1;

// Target serialized size of one ExportedSamples chunk. 1 MiB keeps every chunk far below
// gRPC's 4 MiB default message limit (clients keep their default) while making per-message
// cost negligible: a 1,000,000 x 81 gallery is about 330 chunks.
inline constexpr size_t kExportChunkBytes = size_t{1} << 20;

// Extends `crc` (zlib's CRC-32; start from 0) over one sample as GalleryExportTrailer.crc32
// defines it: the id as 8 bytes little-endian, the label's bytes, the features as IEEE-754
// float32 little-endian.
uint32_t ExportCrc(uint32_t crc, uint64_t id, absl::string_view label,
                   absl::Span<const float> features);
// The same for GalleryExportTrailer.provenance_crc32 (EncodeProvenance's bytes without their
// own trailing CRC): a sample without provenance leaves `crc` as it is.
uint32_t ExportProvenanceCrc(uint32_t crc, uint64_t id, const SampleProvenance& provenance);

// Cuts one gallery into chunks: the header, then samples in training order, at most about
// `chunk_bytes` per chunk (a chunk always holds at least one sample, so a single sample
// larger than that makes a larger chunk), then the trailer. An empty gallery is a header and
// a trailer. Holds only the chunk being filled: the samples are read in place. Not
// thread-safe; one exporter per stream.
class GalleryExporter {
 public:
  // Exports `snapshot`, which the exporter keeps alive: a gallery trained meanwhile
  // publishes new snapshots, and this one, hence the export, stays self-consistent.
  explicit GalleryExporter(std::shared_ptr<const GallerySnapshot> snapshot,
                           size_t chunk_bytes = kExportChunkBytes);
  // Exports `gallery`, whose every sample must hold `dimension` features (as
  // GallerySnapshot::ToStored makes it). For tests and tools; the service exports snapshots.
  explicit GalleryExporter(StoredGallery gallery, size_t chunk_bytes = kExportChunkBytes);

  GalleryExporter(const GalleryExporter&) = delete;
  GalleryExporter& operator=(const GalleryExporter&) = delete;

  // Replaces `*chunk` with the next chunk and returns true, or returns false (chunk cleared)
  // once the trailer has been produced.
  bool Next(v1::GalleryExportChunk* chunk);
  // True once Next has produced the trailer.
  bool done() const { return stage_ == Stage::kDone; }

 private:
  // Appends the sample at `slot` (training order) to `out` but its provenance, which it
  // returns (null: none; valid while keep_alive_ is).
  using AppendSample =
      std::function<const SampleProvenance*(int64_t slot, v1::ExportedSamples* out)>;

  GalleryExporter(std::shared_ptr<const StoredGallery> gallery, size_t chunk_bytes);
  void FillSamples(v1::ExportedSamples* out);

  enum class Stage { kHeader, kSamples, kTrailer, kDone };

  const v1::GalleryExportHeader header_;
  const AppendSample append_;
  // Some sample has several views: every sample's view count is exported.
  const bool multi_view_;
  const size_t chunk_bytes_;
  const std::shared_ptr<const void> keep_alive_;  // what append_ reads
  Stage stage_ = Stage::kHeader;
  int64_t next_slot_ = 0;
  uint32_t crc_ = 0;
  uint32_t provenance_crc_ = 0;
};

// Rebuilds a StoredGallery from the chunks of an export, as they arrive, checking it on the
// way so that a bad export fails at the first bad chunk, before the rest is transferred.
// Holds the samples received so far (one copy of the gallery) and nothing else.
//
// Errors, each naming the chunk (0-based) and what is wrong:
//  - InvalidArgument: chunks out of order (samples or trailer before the header, a second
//    header, anything after the trailer, a chunk with no content); a zero dimension; a
//    samples chunk whose label or feature count does not match its ids; more samples than
//    the header announced; unknown knn enums;
//  - FailedPrecondition: a format_version other than kGalleryExportFormatVersion;
//  - ResourceExhausted: a header announcing more than `max_samples` samples (checked before
//    anything is allocated for them);
//  - DataLoss: the trailer's count or checksums disagree with what arrived ("export damaged:
//    ..."), or Finish without a trailer ("export truncated: ...").
// Provenance (ExportedSamples.sources and .metadata, absent in exports of galleries without
// any) is checked by GalleryRegistry::Import like the labels; here only its counts.
// The first error poisons the assembler: every later call returns it. Names, labels, ids
// and feature values (finite, within +-KnnIndex::kMaxFeatureMagnitude) are checked by
// GalleryRegistry::Import, not here: that one check also guards stores' loads and replicas.
// Not thread-safe; one assembler per stream.
class GalleryImportAssembler {
 public:
  explicit GalleryImportAssembler(int64_t max_samples);

  absl::Status Add(const v1::GalleryExportChunk& chunk);

  // The gallery, exactly as exported: name, options, times, versions, and every sample's
  // id, label and feature bits in order. Moves it out: call once (FailedPrecondition after).
  absl::StatusOr<StoredGallery> Finish();

  // Samples received so far.
  int64_t num_samples() const { return static_cast<int64_t>(gallery_.samples.size()); }

 private:
  absl::Status AddHeader(const v1::GalleryExportHeader& header);
  absl::Status AddSamples(const v1::ExportedSamples& samples);
  absl::Status AddTrailer(const v1::GalleryExportTrailer& trailer);
  absl::Status Fail(absl::Status status);

  const int64_t max_samples_;
  StoredGallery gallery_;
  bool have_header_ = false;
  bool have_trailer_ = false;
  bool finished_ = false;
  uint64_t announced_ = 0;  // header.sample_count
  int64_t chunks_ = 0;      // chunks added so far
  uint32_t crc_ = 0;
  uint32_t provenance_crc_ = 0;
  absl::Status error_;
};

}  // namespace shapeid

#endif  // SHAPEID_SERVER_WIRE_GALLERY_EXPORT_H_
