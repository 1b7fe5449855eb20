#ifndef SHAPEID_SERVER_STORAGE_SQLITE_GALLERY_FILE_H_
#define SHAPEID_SERVER_STORAGE_SQLITE_GALLERY_FILE_H_

// The format of one gallery's SQLite file: its schema, rows and checksums, and how a file is
// verified and read. SqliteGalleryStore (the directory, locks, writes, set-aside) uses it.

#include <cstdint>
#include <string>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "core/gallery/gallery_store.h"
#include "server/storage/sqlite_db.h"

namespace shapeid {
namespace sqlite_gallery_file {

// PRAGMA application_id: "SHID". Lets `file` and our loader tell a gallery from any other
// SQLite database.
inline constexpr int32_t kApplicationId = 0x53484944;

// Per connection: synchronous=FULL makes every COMMIT fsync the WAL before it returns, which
// is the durability contract; cell_size_check catches more damage when pages are read.
inline constexpr absl::string_view kConnectionPragmas =
    "PRAGMA synchronous=FULL; PRAGMA cell_size_check=ON; PRAGMA trusted_schema=OFF;";

// One row describes the gallery; samples are rows in training order (seq). Ids are uint64
// stored as the int64 with the same bits. Every row carries a CRC-32 of its content.
inline constexpr absl::string_view kSchema = R"sql(
CREATE TABLE gallery(
  singleton INTEGER PRIMARY KEY CHECK (singleton = 1),
  name TEXT NOT NULL,
  descriptor_spec TEXT NOT NULL,
  dimension INTEGER NOT NULL,
  knn_k INTEGER NOT NULL,
  knn_weighting TEXT NOT NULL,
  knn_scaling TEXT NOT NULL,
  reject_distance REAL NOT NULL,
  descriptor_version INTEGER NOT NULL,
  software_version TEXT NOT NULL,
  created_unix_ns INTEGER NOT NULL,
  updated_unix_ns INTEGER NOT NULL,
  crc INTEGER NOT NULL,
  augment TEXT NOT NULL);
CREATE TABLE samples(
  seq INTEGER PRIMARY KEY,
  id INTEGER NOT NULL UNIQUE,
  label TEXT NOT NULL,
  features BLOB NOT NULL,
  crc INTEGER NOT NULL,
  provenance BLOB);
)sql";

// Format 3 adds the samples' `provenance` column: EncodeProvenance's bytes (which carry their
// own CRC), NULL for a sample without. An older file gains it (ALTER TABLE, user_version 3)
// at its first sample with provenance, so files that never see one stay as they were.
inline constexpr absl::string_view kAddProvenanceColumn =
    "ALTER TABLE samples ADD COLUMN provenance BLOB; PRAGMA user_version=3;";
inline constexpr int kFirstFormatWithProvenance = 3;
// The insert statement of a file of format `format`: 5 parameters from format 3 on, else 4.
absl::string_view InsertSampleSql(int64_t format);

// Format 1's columns; format 2 adds `augment` (AugmentOptionsToString), and samples of an
// augmented gallery hold several descriptors (views) in their features blob.
inline constexpr absl::string_view kGalleryColumnsV1 =
    "name, descriptor_spec, dimension, knn_k, knn_weighting, knn_scaling, reject_distance, "
    "descriptor_version, software_version, created_unix_ns, updated_unix_ns, crc";
inline constexpr absl::string_view kGalleryColumns =
    "name, descriptor_spec, dimension, knn_k, knn_weighting, knn_scaling, reject_distance, "
    "descriptor_version, software_version, created_unix_ns, updated_unix_ns, crc, augment";

// The gallery row's CRC-32 (of its content but the CRC).
uint32_t GalleryRowCrc(const GalleryMetadata& g);

// Sample ids are uint64 stored as the int64 with the same bits.
int64_t AsStoredId(uint64_t id);
uint64_t FromStoredId(int64_t id);

// Binds the gallery row's kGalleryColumns, in order, to parameters 1..13 of `s`.
void BindGalleryRow(SqliteStatement& s, const GalleryMetadata& g);
// Runs `insert` (InsertSampleSql(format)) for `sample`. Internal for a sample with
// provenance in a file of an older format (the caller adds the column first).
absl::Status InsertSample(SqliteStatement& insert, int64_t format, const StoredSample& sample);

// SQLite's own words ("database disk image is malformed") with ours in front.
absl::Status Damaged(const std::string& path, const absl::Status& status);

// Verifies and reads the gallery `name` from `db`, the file at `path`, into `loader`: Begin
// with its metadata once the file and its gallery row check out, each sample as it is read
// and checked (one StoredSample reused, so the read holds one sample at a time), End after
// the last; returns the metadata. DataLoss for damage (or a file that is not a shapeid
// gallery), FailedPrecondition for a newer format, the disk's code (ResourceExhausted,
// Unavailable) when it cannot be read, the loader's error as it is. After an error the
// loader may hold a gallery begun and not ended.
absl::StatusOr<GalleryMetadata> ReadGallery(SqliteDb& db, const std::string& path,
                                            const std::string& name, GalleryLoader& loader);

}  // namespace sqlite_gallery_file
}  // namespace shapeid

#endif  // SHAPEID_SERVER_STORAGE_SQLITE_GALLERY_FILE_H_
