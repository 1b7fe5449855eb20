#include "server/wire/gallery_export.h"

#include <zlib.h>

#include <algorithm>
#include <cstring>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "absl/strings/str_cat.h"
#include "core/status_macros.h"
#include "server/storage/sample_checksum.h"
#include "server/wire/proto_convert.h"

// The trailer's CRC covers float32 and the id little-endian; the features are hashed as they
// lie in memory.
#if defined(__BYTE_ORDER__) && __BYTE_ORDER__ != __ORDER_LITTLE_ENDIAN__
#error "gallery_export.cc hashes floats in memory order: add a byte swap for big-endian hosts"
#endif

namespace shapeid {
namespace {

v1::GalleryExportHeader HeaderFor(const GalleryMetadata& meta, int64_t num_samples) {
  v1::GalleryExportHeader header;
  header.set_format_version(kGalleryExportFormatVersion);
  ToProto(meta, &header);
  header.set_sample_count(static_cast<uint64_t>(num_samples));
  return header;
}

void AppendTo(v1::ExportedSamples* out, uint64_t id, const std::string& label) {
  out->add_sample_ids(id);
  out->add_labels(label);
}

// Serialized bytes one sample adds to an ExportedSamples message, at most: a 10-byte
// varint id, the label with its tag and length, its view count, the packed features.
size_t SampleBytes(size_t label_bytes, size_t features) {
  return 10 + 1 + 5 + label_bytes + 5 + 4 * features;
}

}  // namespace

uint32_t ExportCrc(uint32_t crc, uint64_t id, absl::string_view label,
                   absl::Span<const float> features) {
  // One definition for store rows and exports, so a stored sample and its export agree.
  return SampleCrc32(crc, id, label, features);
}

uint32_t ExportProvenanceCrc(uint32_t crc, uint64_t id, const SampleProvenance& provenance) {
  if (provenance.empty()) return crc;
  // Without the encoding's own trailing CRC: a CRC over data followed by its CRC is the same
  // for any data, so it would hide every change.
  const std::string encoded = EncodeProvenance(provenance);
  return SampleCrc32(crc, id, absl::string_view(encoded).substr(0, encoded.size() - 4), {});
}

// ---------------------------------------------------------------------------------------------
// Export

GalleryExporter::GalleryExporter(std::shared_ptr<const GallerySnapshot> snapshot,
                                 size_t chunk_bytes)
    : header_(HeaderFor(snapshot->metadata(), snapshot->num_samples())),
      append_(
          [s = snapshot.get()](int64_t slot, v1::ExportedSamples* out) -> const SampleProvenance* {
            const KnnIndex& index = s->index();
            AppendTo(out, index.IdAt(slot), index.LabelAt(slot));
            const int features = index.ViewsAt(slot) * index.dimension();
            const int old_size = out->features_size();
            out->mutable_features()->Resize(old_size + features, 0.0f);
            index.CopyFeatures(slot, out->mutable_features()->mutable_data() + old_size);
            // The snapshot's table holds the provenance as long as keep_alive_ holds the snapshot.
            return s->Provenance(index.IdAt(slot)).get();
          }),
      multi_view_(snapshot->index().num_rows() > snapshot->num_samples()),
      chunk_bytes_(chunk_bytes),
      keep_alive_(std::move(snapshot)) {}

GalleryExporter::GalleryExporter(StoredGallery gallery, size_t chunk_bytes)
    : GalleryExporter(std::make_shared<const StoredGallery>(std::move(gallery)), chunk_bytes) {}

GalleryExporter::GalleryExporter(std::shared_ptr<const StoredGallery> gallery, size_t chunk_bytes)
    : header_(HeaderFor(*gallery, static_cast<int64_t>(gallery->samples.size()))),
      append_([samples = &gallery->samples](int64_t slot,
                                            v1::ExportedSamples* out) -> const SampleProvenance* {
        const StoredSample& sample = (*samples)[static_cast<size_t>(slot)];
        AppendTo(out, sample.id, sample.label);
        out->mutable_features()->Add(sample.features.begin(), sample.features.end());
        return sample.provenance.empty() ? nullptr : &sample.provenance;
      }),
      multi_view_(std::any_of(gallery->samples.begin(), gallery->samples.end(),
                              [d = static_cast<size_t>(gallery->dimension)](const StoredSample& s) {
                                return s.features.size() > d;
                              })),
      chunk_bytes_(chunk_bytes),
      keep_alive_(std::move(gallery)) {}

bool GalleryExporter::Next(v1::GalleryExportChunk* chunk) {
  chunk->Clear();
  const auto num_samples = static_cast<int64_t>(header_.sample_count());
  switch (stage_) {
    case Stage::kHeader:
      *chunk->mutable_header() = header_;
      stage_ = num_samples > 0 ? Stage::kSamples : Stage::kTrailer;
      return true;
    case Stage::kSamples:
      FillSamples(chunk->mutable_samples());
      if (next_slot_ == num_samples) stage_ = Stage::kTrailer;
      return true;
    case Stage::kTrailer:
      chunk->mutable_trailer()->set_sample_count(header_.sample_count());
      chunk->mutable_trailer()->set_crc32(crc_);
      chunk->mutable_trailer()->set_provenance_crc32(provenance_crc_);
      stage_ = Stage::kDone;
      return true;
    case Stage::kDone:
      break;
  }
  return false;
}

void GalleryExporter::FillSamples(v1::ExportedSamples* out) {
  const auto num_samples = static_cast<int64_t>(header_.sample_count());
  const int dimension = static_cast<int>(header_.dimension());
  size_t bytes = 0;
  // The run's provenance, one per sample, exported only if one of them has some: a gallery
  // without provenance exports what it always did.
  std::vector<const SampleProvenance*> provenance;
  bool any_provenance = false;
  while (next_slot_ < num_samples && bytes < chunk_bytes_) {
    const int first = out->features_size();
    const SampleProvenance* sample_provenance = append_(next_slot_, out);
    provenance.push_back(sample_provenance);
    const int i = out->sample_ids_size() - 1;
    const absl::Span<const float> features(out->features().data() + first,
                                           static_cast<size_t>(out->features_size() - first));
    // Only galleries with several views per sample say how many: a plain gallery's export
    // stays what it always was.
    if (multi_view_) out->add_view_counts(static_cast<uint32_t>(features.size() / dimension));
    crc_ = ExportCrc(crc_, out->sample_ids(i), out->labels(i), features);
    bytes += SampleBytes(out->labels(i).size(), features.size());
    if (sample_provenance != nullptr) {
      any_provenance = true;
      provenance_crc_ =
          ExportProvenanceCrc(provenance_crc_, out->sample_ids(i), *sample_provenance);
      bytes += sample_provenance->source.size() + 8;
      for (const auto& [key, value] : sample_provenance->metadata) {
        bytes += key.size() + value.size() + 8;
      }
    }
    ++next_slot_;
  }
  if (!any_provenance) return;
  for (const SampleProvenance* p : provenance) {
    v1::SampleMetadata* metadata = out->add_metadata();
    out->add_sources(p == nullptr ? "" : p->source);
    if (p == nullptr) continue;
    for (const auto& [key, value] : p->metadata) {
      v1::SampleMetadata::Entry* entry = metadata->add_entries();
      entry->set_key(key);
      entry->set_value(value);
    }
  }
}

// ---------------------------------------------------------------------------------------------
// Import

GalleryImportAssembler::GalleryImportAssembler(int64_t max_samples) : max_samples_(max_samples) {}

absl::Status GalleryImportAssembler::Fail(absl::Status status) {
  error_ = absl::Status(status.code(), absl::StrCat(status.message(), " (chunk ", chunks_, ")"));
  return error_;
}

absl::Status GalleryImportAssembler::Add(const v1::GalleryExportChunk& chunk) {
  if (!error_.ok()) return error_;
  absl::Status status;
  if (finished_) {
    status = absl::FailedPreconditionError("the import was already finished");
  } else if (have_trailer_) {
    status = absl::InvalidArgumentError("a chunk after the trailer, which ends an export");
  } else {
    switch (chunk.kind_case()) {
      case v1::GalleryExportChunk::kHeader:
        status = AddHeader(chunk.header());
        break;
      case v1::GalleryExportChunk::kSamples:
        status = AddSamples(chunk.samples());
        break;
      case v1::GalleryExportChunk::kTrailer:
        status = AddTrailer(chunk.trailer());
        break;
      case v1::GalleryExportChunk::KIND_NOT_SET:
        status = absl::InvalidArgumentError("a chunk with no header, samples or trailer");
        break;
    }
  }
  if (!status.ok()) return Fail(std::move(status));
  ++chunks_;
  return absl::OkStatus();
}

absl::Status GalleryImportAssembler::AddHeader(const v1::GalleryExportHeader& header) {
  if (have_header_) {
    return absl::InvalidArgumentError("a second header; an export has exactly one, first");
  }
  if (header.format_version() != kGalleryExportFormatVersion) {
    return absl::FailedPreconditionError(absl::StrCat(
        "export format version ", header.format_version(), "; this server reads version ",
        kGalleryExportFormatVersion, " (export the gallery again with a matching shapeid)"));
  }
  if (header.dimension() == 0 ||
      header.dimension() > static_cast<uint32_t>(std::numeric_limits<int>::max())) {
    return absl::InvalidArgumentError(
        absl::StrCat("the header gives dimension ", header.dimension(), "; it must be > 0"));
  }
  if (header.sample_count() > static_cast<uint64_t>(max_samples_)) {
    return absl::ResourceExhaustedError(
        absl::StrCat("the export holds ", header.sample_count(),
                     " samples, more than max_samples_per_gallery = ", max_samples_));
  }
  absl::StatusOr<GalleryMetadata> meta = MetadataFromProto(header);
  if (!meta.ok()) {
    return absl::InvalidArgumentError(absl::StrCat("header: ", meta.status().message()));
  }
  static_cast<GalleryMetadata&>(gallery_) = *std::move(meta);
  announced_ = header.sample_count();
  // Not all of it up front: a 100-byte header must not pin megabytes before any sample came.
  gallery_.samples.reserve(static_cast<size_t>(std::min<uint64_t>(announced_, 1 << 16)));
  have_header_ = true;
  return absl::OkStatus();
}

absl::Status GalleryImportAssembler::AddSamples(const v1::ExportedSamples& samples) {
  if (!have_header_) {
    return absl::InvalidArgumentError("samples before the header; an export starts with it");
  }
  const auto n = static_cast<uint64_t>(samples.sample_ids_size());
  const auto dimension = static_cast<uint64_t>(gallery_.dimension);
  if (static_cast<uint64_t>(samples.labels_size()) != n) {
    return absl::InvalidArgumentError(
        absl::StrCat(n, " sample ids but ", samples.labels_size(), " labels"));
  }
  const bool counted = samples.view_counts_size() > 0;
  if (counted && static_cast<uint64_t>(samples.view_counts_size()) != n) {
    return absl::InvalidArgumentError(
        absl::StrCat(n, " sample ids but ", samples.view_counts_size(), " view counts"));
  }
  uint64_t vectors = 0;
  for (uint64_t i = 0; i < n; ++i) {
    const uint32_t views = counted ? samples.view_counts(static_cast<int>(i)) : 1;
    if (views < 1 || views > 1 + AugmentOptions::kMaxViews) {
      return absl::InvalidArgumentError(
          absl::StrCat("sample id ", samples.sample_ids(static_cast<int>(i)), " has ", views,
                       " views; 1 to ", 1 + AugmentOptions::kMaxViews, " allowed"));
    }
    vectors += views;
  }
  if (static_cast<uint64_t>(samples.features_size()) != vectors * dimension) {
    return absl::InvalidArgumentError(
        absl::StrCat(n, " samples with ", vectors, " views of dimension ", dimension, " need ",
                     vectors * dimension, " features, got ", samples.features_size()));
  }
  const bool with_provenance = samples.sources_size() > 0 || samples.metadata_size() > 0;
  if (with_provenance && (static_cast<uint64_t>(samples.sources_size()) != n ||
                          static_cast<uint64_t>(samples.metadata_size()) != n)) {
    return absl::InvalidArgumentError(absl::StrCat(n, " sample ids but ", samples.sources_size(),
                                                   " sources and ", samples.metadata_size(),
                                                   " metadata"));
  }
  const auto received = static_cast<uint64_t>(gallery_.samples.size());
  if (received + n > announced_) {
    return absl::InvalidArgumentError(absl::StrCat("more samples than the header announced (",
                                                   announced_, "): ", received + n, " so far"));
  }
  const float* next = samples.features().data();
  for (uint64_t i = 0; i < n; ++i) {
    StoredSample& sample = gallery_.samples.emplace_back();
    sample.id = samples.sample_ids(static_cast<int>(i));
    sample.label = samples.labels(static_cast<int>(i));
    const uint64_t count = (counted ? samples.view_counts(static_cast<int>(i)) : 1) * dimension;
    sample.features.assign(next, next + count);
    next += count;
    crc_ = ExportCrc(crc_, sample.id, sample.label, sample.features);
    if (with_provenance) {
      sample.provenance.source = samples.sources(static_cast<int>(i));
      // As exported (sorted, keys unique); GalleryRegistry::Import checks it.
      for (const auto& entry : samples.metadata(static_cast<int>(i)).entries()) {
        sample.provenance.metadata.emplace_back(entry.key(), entry.value());
      }
      provenance_crc_ = ExportProvenanceCrc(provenance_crc_, sample.id, sample.provenance);
    }
  }
  return absl::OkStatus();
}

absl::Status GalleryImportAssembler::AddTrailer(const v1::GalleryExportTrailer& trailer) {
  if (!have_header_) {
    return absl::InvalidArgumentError("a trailer before the header; an export starts with it");
  }
  const auto received = static_cast<uint64_t>(gallery_.samples.size());
  if (received != announced_ || trailer.sample_count() != received) {
    return absl::DataLossError(absl::StrCat("export damaged: the header announced ", announced_,
                                            " samples, the trailer counts ", trailer.sample_count(),
                                            ", ", received, " arrived"));
  }
  if (trailer.crc32() != crc_) {
    return absl::DataLossError(absl::StrCat("export damaged: checksum mismatch over the ", received,
                                            " samples (the trailer says ", trailer.crc32(),
                                            ", the samples give ", crc_, ")"));
  }
  if (trailer.provenance_crc32() != provenance_crc_) {
    return absl::DataLossError(absl::StrCat(
        "export damaged: checksum mismatch over the samples' provenance (the trailer says ",
        trailer.provenance_crc32(), ", the samples give ", provenance_crc_, ")"));
  }
  have_trailer_ = true;
  return absl::OkStatus();
}

absl::StatusOr<StoredGallery> GalleryImportAssembler::Finish() {
  if (!error_.ok()) return error_;
  if (finished_) return absl::FailedPreconditionError("the import was already finished");
  if (!have_header_) {
    return absl::InvalidArgumentError("the export is empty: no header arrived");
  }
  if (!have_trailer_) {
    error_ = absl::DataLossError(absl::StrCat("export truncated: ", gallery_.samples.size(), " of ",
                                              announced_, " samples, no trailer"));
    return error_;
  }
  // The trailer's checksum covers the bytes, not their sense: an export written by hand or by
  // another tool may repeat an id, which would otherwise surface as ALREADY_EXISTS, the code
  // of a gallery name that is taken.
  std::vector<uint64_t> ids;
  ids.reserve(gallery_.samples.size());
  for (const StoredSample& sample : gallery_.samples) ids.push_back(sample.id);
  std::sort(ids.begin(), ids.end());
  if (auto twice = std::adjacent_find(ids.begin(), ids.end()); twice != ids.end()) {
    error_ = absl::InvalidArgumentError(
        absl::StrCat("export malformed: sample id ", *twice, " appears more than once"));
    return error_;
  }
  finished_ = true;
  return std::move(gallery_);
}

}  // namespace shapeid
