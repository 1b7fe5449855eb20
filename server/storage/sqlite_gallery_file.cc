#include "server/storage/sqlite_gallery_file.h"

#include <cstring>

#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/strip.h"
#include "absl/time/time.h"
#include "core/gallery/gallery_options.h"
#include "core/status_macros.h"
#include "server/storage/sample_checksum.h"
#include "server/storage/sqlite_gallery_store.h"

namespace shapeid {
namespace sqlite_gallery_file {

uint32_t GalleryRowCrc(const GalleryMetadata& g) {
  uint64_t reject_bits;
  std::memcpy(&reject_bits, &g.options.reject_distance, sizeof(reject_bits));
  const std::string text = absl::StrCat(
      g.name, "\n", g.options.descriptor_spec, "\n", g.dimension, "\n", g.options.knn.k, "\n",
      VoteWeightingName(g.options.knn.weighting), "\n", FeatureScalingName(g.options.knn.scaling),
      "\n", reject_bits, "\n", g.descriptor_version, "\n", g.software_version, "\n",
      absl::ToUnixNanos(g.created), "\n", absl::ToUnixNanos(g.updated),
      // Only when on, so a format-1 row (no augmentation) keeps its checksum.
      g.options.augment.enabled() ? absl::StrCat("\n", AugmentOptionsToString(g.options.augment))
                                  : "");
  return static_cast<uint32_t>(
      crc32_z(0, reinterpret_cast<const Bytef*>(text.data()), text.size()));
}

int64_t AsStoredId(uint64_t id) { return static_cast<int64_t>(id); }
uint64_t FromStoredId(int64_t id) { return static_cast<uint64_t>(id); }

void BindGalleryRow(SqliteStatement& s, const GalleryMetadata& g) {
  s.BindText(1, g.name);
  s.BindText(2, g.options.descriptor_spec);
  s.BindInt64(3, g.dimension);
  s.BindInt64(4, g.options.knn.k);
  s.BindText(5, VoteWeightingName(g.options.knn.weighting));
  s.BindText(6, FeatureScalingName(g.options.knn.scaling));
  s.BindDouble(7, g.options.reject_distance);
  s.BindInt64(8, g.descriptor_version);
  s.BindText(9, g.software_version);
  s.BindInt64(10, absl::ToUnixNanos(g.created));
  s.BindInt64(11, absl::ToUnixNanos(g.updated));
  s.BindInt64(12, GalleryRowCrc(g));
  s.BindText(13, AugmentOptionsToString(g.options.augment));
}

absl::string_view InsertSampleSql(int64_t format) {
  return format >= kFirstFormatWithProvenance
             ? "INSERT INTO samples(id, label, features, crc, provenance) VALUES(?,?,?,?,?)"
             : "INSERT INTO samples(id, label, features, crc) VALUES(?,?,?,?)";
}

absl::Status InsertSample(SqliteStatement& insert, int64_t format, const StoredSample& sample) {
  insert.BindInt64(1, AsStoredId(sample.id));
  insert.BindText(2, sample.label);
  insert.BindBlob(3, FeatureBytes(sample.features));
  insert.BindInt64(4, SampleCrc32(0, sample.id, sample.label, sample.features));
  if (format >= kFirstFormatWithProvenance) {
    const std::string provenance = EncodeProvenance(sample.provenance);
    if (provenance.empty()) {
      insert.BindNull(5);  // NULL: no provenance (the common case costs no bytes)
    } else {
      insert.BindBlob(5,
                      absl::Span<const uint8_t>(reinterpret_cast<const uint8_t*>(provenance.data()),
                                                provenance.size()));
    }
  } else if (!sample.provenance.empty()) {
    return absl::InternalError(absl::StrCat(
        "sample id ", sample.id, " has provenance, which a format-", format, " file cannot hold"));
  }
  return insert.Run();
}

absl::Status Damaged(const std::string& path, const absl::Status& status) {
  if (status.code() != absl::StatusCode::kDataLoss ||
      absl::StrContains(status.message(), "damaged") ||
      absl::StrContains(status.message(), "not a shapeid gallery")) {
    return status;
  }
  absl::string_view detail = status.message();
  absl::ConsumePrefix(&detail, absl::StrCat(path, ": "));
  return absl::DataLossError(absl::StrCat("gallery file ", path, " is damaged: ", detail));
}

absl::StatusOr<GalleryMetadata> ReadGallery(SqliteDb& db, const std::string& path,
                                            const std::string& name, GalleryLoader& loader) {
  const auto damaged = [&](absl::string_view what) {
    return absl::DataLossError(absl::StrCat("gallery file ", path, " is damaged: ", what));
  };
  // A query on our tables that SQLite cannot even compile ("no such table") means the file
  // is not a shapeid gallery's schema: damage, as a CRC mismatch is.
  const auto schema = [&](auto result) -> decltype(result) {
    if (!result.ok() && result.status().code() == absl::StatusCode::kInternal &&
        (sqlite3_extended_errcode(db.raw()) & 0xff) == SQLITE_ERROR) {
      return damaged(absl::StrCat("not a shapeid gallery's schema: ", result.status().message()));
    }
    return result;
  };

  // What the file is, before trusting anything in it.
  SHAPEID_ASSIGN_OR_RETURN(const int64_t application_id, db.QueryInt("PRAGMA application_id"));
  if (application_id != kApplicationId) {
    return absl::DataLossError(absl::StrCat(path,
                                            " is not a shapeid gallery (SQLite application_id ",
                                            application_id, ", expected ", kApplicationId, ")"));
  }
  SHAPEID_ASSIGN_OR_RETURN(const int64_t format, db.QueryInt("PRAGMA user_version"));
  if (format > SqliteGalleryStore::kFormatVersion) {
    return absl::FailedPreconditionError(
        absl::StrCat(path, " has format version ", format,
                     ", written by a newer shapeid; this server reads "
                     "up to version ",
                     SqliteGalleryStore::kFormatVersion,
                     ". Run the newer release, or export the gallery with it"));
  }
  if (format < 1) return damaged(absl::StrCat("format version ", format));
  // quick_check: every page and b-tree structure (a truncated or overwritten file), in
  // O(file size); CRCs below catch damage inside the rows.
  SHAPEID_ASSIGN_OR_RETURN(const std::string check, db.QueryText("PRAGMA quick_check"));
  if (check != "ok") return damaged(absl::StrCat("SQLite integrity check: ", check));

  GalleryMetadata g;
  {
    SHAPEID_ASSIGN_OR_RETURN(
        SqliteStatement row,
        schema(db.Prepare(absl::StrCat("SELECT ", format == 1 ? kGalleryColumnsV1 : kGalleryColumns,
                                       " FROM gallery"))));
    SHAPEID_ASSIGN_OR_RETURN(const bool found, row.Step());
    if (!found) return damaged("the gallery row is missing");
    g.name = row.ColumnText(0);
    g.options.descriptor_spec = row.ColumnText(1);
    g.dimension = static_cast<int>(row.ColumnInt64(2));
    g.options.knn.k = static_cast<int>(row.ColumnInt64(3));
    absl::StatusOr<VoteWeighting> weighting = ParseVoteWeighting(row.ColumnText(4));
    absl::StatusOr<FeatureScaling> scaling = ParseFeatureScaling(row.ColumnText(5));
    g.options.reject_distance = row.ColumnDouble(6);
    g.descriptor_version = static_cast<uint32_t>(row.ColumnInt64(7));
    g.software_version = row.ColumnText(8);
    g.created = absl::FromUnixNanos(row.ColumnInt64(9));
    g.updated = absl::FromUnixNanos(row.ColumnInt64(10));
    const uint32_t crc = static_cast<uint32_t>(row.ColumnInt64(11));
    if (!weighting.ok() || !scaling.ok()) return damaged("unreadable kNN options");
    if (format >= 2) {
      absl::StatusOr<AugmentOptions> augment = ParseAugmentOptions(row.ColumnText(12));
      if (!augment.ok()) return damaged(augment.status().message());
      g.options.augment = *augment;
    }
    g.options.knn.weighting = *weighting;
    g.options.knn.scaling = *scaling;
    if (GalleryRowCrc(g) != crc) return damaged("checksum mismatch in the gallery row");
    if (g.name != name) {
      return damaged(absl::StrCat("it holds gallery '", g.name, "', not '", name, "'"));
    }
    if (g.dimension < 1) return damaged(absl::StrCat("dimension ", g.dimension));
  }
  SHAPEID_RETURN_IF_ERROR(loader.Begin(g));
  {
    SHAPEID_ASSIGN_OR_RETURN(
        SqliteStatement rows,
        schema(db.Prepare(format >= kFirstFormatWithProvenance
                              ? "SELECT seq, id, label, features, crc, provenance FROM samples "
                                "ORDER BY seq"
                              : "SELECT seq, id, label, features, crc FROM samples ORDER BY seq")));
    const size_t bytes = static_cast<size_t>(g.dimension) * sizeof(float);
    StoredSample sample;  // every field set again for each row; features keep their capacity
    while (true) {
      SHAPEID_ASSIGN_OR_RETURN(const bool more, rows.Step());
      if (!more) break;
      sample.id = FromStoredId(rows.ColumnInt64(1));
      sample.label = rows.ColumnText(2);
      const absl::Span<const uint8_t> blob = rows.ColumnBlob(3);
      const std::string at =
          absl::StrCat("sample id ", sample.id, " (row ", rows.ColumnInt64(0), ")");
      // One descriptor per view: a positive multiple of the dimension.
      if (blob.empty() || blob.size() % bytes != 0) {
        return damaged(absl::StrCat(at, " has ", blob.size(),
                                    " bytes of features, expected a positive multiple of ", bytes));
      }
      FeaturesFromBytes(blob, &sample.features);
      if (SampleCrc32(0, sample.id, sample.label, sample.features) !=
          static_cast<uint32_t>(rows.ColumnInt64(4))) {
        return damaged(absl::StrCat(at, ": checksum mismatch"));
      }
      sample.provenance = SampleProvenance();
      if (format >= kFirstFormatWithProvenance) {
        const absl::Span<const uint8_t> encoded = rows.ColumnBlob(5);
        absl::StatusOr<SampleProvenance> provenance = DecodeProvenance(
            absl::string_view(reinterpret_cast<const char*>(encoded.data()), encoded.size()));
        if (!provenance.ok()) return damaged(absl::StrCat(at, ": ", provenance.status().message()));
        sample.provenance = *std::move(provenance);
      }
      SHAPEID_RETURN_IF_ERROR(loader.Add(sample));
    }
  }
  SHAPEID_RETURN_IF_ERROR(loader.End());
  return g;
}

}  // namespace sqlite_gallery_file
}  // namespace shapeid
