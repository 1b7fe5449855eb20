#include "server/storage/postgres_gallery_store.h"

#include <poll.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <map>
#include <utility>

#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_split.h"
#include "core/knn/knn_options.h"
#include "core/status_macros.h"
#include "core/views/augment.h"
#include "server/storage/sample_checksum.h"

namespace shapeid {
namespace {

constexpr char kChannel[] = "shapeid_changes";
// Reads of the log and of galleries run in one snapshot, so that a gallery read whole (a
// reload) and the log position agree even while other replicas write.
constexpr char kSnapshot[] = "BEGIN ISOLATION LEVEL REPEATABLE READ READ ONLY";
// pg_advisory_xact_lock key held while a change is logged, so that log sequence numbers are
// handed out in commit order ("shapeid" in ASCII).
constexpr int64_t kLogLockKey = 0x73686170656964;
// Held while the tables are created: replicas starting together would otherwise race in
// CREATE TABLE IF NOT EXISTS (which is not safe against concurrent creators).
constexpr int64_t kSchemaLockKey = kLogLockKey + 1;
// Samples per INSERT statement (5 parameters each; PostgreSQL allows 65,535).
constexpr size_t kSamplesPerInsert = 1000;
// Change-log rows older than this are deleted (by any replica, once a minute), and
// shapeid_log_floor records the last sequence number deleted. A replica whose position is
// below the floor has missed what those rows said and reloads every gallery instead.
constexpr char kLogRetention[] = "15 minutes";

constexpr char kSchema[] = R"sql(
CREATE TABLE IF NOT EXISTS shapeid_galleries (
  name TEXT PRIMARY KEY,
  incarnation BIGINT NOT NULL UNIQUE,
  descriptor_spec TEXT NOT NULL,
  dimension INTEGER NOT NULL,
  k INTEGER NOT NULL,
  weighting TEXT NOT NULL,
  scaling TEXT NOT NULL,
  reject_distance_bits BIGINT NOT NULL,
  augment TEXT NOT NULL,
  descriptor_version BIGINT NOT NULL,
  software_version TEXT NOT NULL,
  created_unix_ns BIGINT NOT NULL,
  updated_unix_ns BIGINT NOT NULL,
  version BIGINT NOT NULL);
CREATE TABLE IF NOT EXISTS shapeid_samples (
  incarnation BIGINT NOT NULL,
  id BIGINT NOT NULL,
  position BIGSERIAL,
  label BYTEA NOT NULL,
  features BYTEA NOT NULL,
  crc BIGINT NOT NULL,
  PRIMARY KEY (incarnation, id));
CREATE INDEX IF NOT EXISTS shapeid_samples_order ON shapeid_samples (incarnation, position);
-- EncodeProvenance's bytes (their own CRC), empty or NULL for none; added after release 1, so
-- a database an older server made gains it here, and an older server's inserts leave it NULL.
ALTER TABLE shapeid_samples ADD COLUMN IF NOT EXISTS provenance BYTEA;
CREATE TABLE IF NOT EXISTS shapeid_changes (
  seq BIGSERIAL PRIMARY KEY,
  gallery TEXT NOT NULL,
  incarnation BIGINT NOT NULL,
  version BIGINT NOT NULL,
  kind TEXT NOT NULL,
  ids BIGINT[] NOT NULL,
  updated_unix_ns BIGINT NOT NULL,
  logged TIMESTAMPTZ NOT NULL DEFAULT clock_timestamp());
CREATE TABLE IF NOT EXISTS shapeid_log_floor (
  one BOOLEAN PRIMARY KEY DEFAULT TRUE CHECK (one),
  seq BIGINT NOT NULL);
INSERT INTO shapeid_log_floor (seq) VALUES (0) ON CONFLICT DO NOTHING;
-- A gallery's trained head (GalleryHead::Serialize's bytes, their own CRC): derived state,
-- checked against the samples by the loader, so it needs no place in the change log.
CREATE TABLE IF NOT EXISTS shapeid_heads (
  incarnation BIGINT PRIMARY KEY,
  head BYTEA NOT NULL);
)sql";

constexpr char kGalleryColumns[] =
    "name, incarnation, descriptor_spec, dimension, k, weighting, scaling, reject_distance_bits, "
    "augment, descriptor_version, software_version, created_unix_ns, updated_unix_ns, version";

int64_t DoubleBits(double value) {
  int64_t bits;
  std::memcpy(&bits, &value, sizeof(bits));
  return bits;
}

double BitsDouble(int64_t bits) {
  double value;
  std::memcpy(&value, &bits, sizeof(value));
  return value;
}

// The shapeid_galleries row of a gallery, in kGalleryColumns' order.
PgParams GalleryRow(const GalleryMetadata& g) {
  PgParams row;
  row.Text(g.name)
      .Int(static_cast<int64_t>(g.incarnation))
      .Text(g.options.descriptor_spec)
      .Int(g.dimension)
      .Int(g.options.knn.k)
      .Text(std::string(VoteWeightingName(g.options.knn.weighting)))
      .Text(std::string(FeatureScalingName(g.options.knn.scaling)))
      .Int(DoubleBits(g.options.reject_distance))
      .Text(AugmentOptionsToString(g.options.augment))
      .Int(g.descriptor_version)
      .Text(g.software_version)
      .Int(absl::ToUnixNanos(g.created))
      .Int(absl::ToUnixNanos(g.updated))
      .Int(static_cast<int64_t>(g.version));
  return row;
}

// The inverse of GalleryRow for row `r` of a SELECT of kGalleryColumns; `damaged` makes the
// error for a value that cannot be read.
absl::StatusOr<GalleryMetadata> FromGalleryRow(
    const PgResult& row, int r, const std::function<absl::Status(absl::string_view)>& damaged) {
  GalleryMetadata g;
  g.name = std::string(row.Value(r, 0));
  g.incarnation = static_cast<uint64_t>(row.Int(r, 1));
  g.options.descriptor_spec = std::string(row.Value(r, 2));
  g.dimension = static_cast<int>(row.Int(r, 3));
  g.options.knn.k = static_cast<int>(row.Int(r, 4));
  absl::StatusOr<VoteWeighting> weighting = ParseVoteWeighting(row.Value(r, 5));
  absl::StatusOr<FeatureScaling> scaling = ParseFeatureScaling(row.Value(r, 6));
  if (!weighting.ok() || !scaling.ok()) return damaged("unreadable kNN options");
  g.options.knn.weighting = *weighting;
  g.options.knn.scaling = *scaling;
  g.options.reject_distance = BitsDouble(row.Int(r, 7));
  absl::StatusOr<AugmentOptions> augment = ParseAugmentOptions(row.Value(r, 8));
  if (!augment.ok()) return damaged(augment.status().message());
  g.options.augment = *augment;
  g.descriptor_version = static_cast<uint32_t>(row.Int(r, 9));
  g.software_version = std::string(row.Value(r, 10));
  g.created = absl::FromUnixNanos(row.Int(r, 11));
  g.updated = absl::FromUnixNanos(row.Int(r, 12));
  g.version = static_cast<uint64_t>(row.Int(r, 13));
  if (g.dimension < 1) return damaged(absl::StrCat("dimension ", g.dimension));
  return g;
}

absl::Span<const uint8_t> Bytes(absl::string_view s) {
  return absl::Span<const uint8_t>(reinterpret_cast<const uint8_t*>(s.data()), s.size());
}

// The columns every read of samples selects, in this order.
constexpr char kSampleColumns[] = "id, label, features, crc, provenance";

// Sample row `r` of a binary SELECT of kSampleColumns, checked; `damaged` makes the error.
absl::StatusOr<StoredSample> FromSampleRow(
    const PgResult& rows, int r, int dimension,
    const std::function<absl::Status(absl::string_view)>& damaged) {
  StoredSample s;
  s.id = FromPgId(rows.BinaryInt(r, 0));
  s.label = std::string(rows.Value(r, 1));
  const absl::string_view features = rows.Value(r, 2);
  if (features.size() % (sizeof(float) * static_cast<size_t>(dimension)) != 0) {
    return damaged(absl::StrCat("sample id ", s.id, " has ", features.size(), " feature bytes"));
  }
  FeaturesFromBytes(Bytes(features), &s.features);
  if (SampleCrc32(0, s.id, s.label, s.features) != static_cast<uint32_t>(rows.BinaryInt(r, 3))) {
    return damaged(absl::StrCat("checksum mismatch in sample id ", s.id));
  }
  absl::StatusOr<SampleProvenance> provenance =
      DecodeProvenance(rows.IsNull(r, 4) ? absl::string_view() : rows.Value(r, 4));
  if (!provenance.ok()) {
    return damaged(absl::StrCat("sample id ", s.id, ": ", provenance.status().message()));
  }
  s.provenance = *std::move(provenance);
  return s;
}

// Inserts samples of one incarnation, kSamplesPerInsert per statement.
absl::Status InsertSamples(PgConnection& connection, absl::string_view what, int64_t incarnation,
                           absl::Span<const StoredSample> samples) {
  for (size_t begin = 0; begin < samples.size(); begin += kSamplesPerInsert) {
    const size_t end = std::min(samples.size(), begin + kSamplesPerInsert);
    std::string sql =
        "INSERT INTO shapeid_samples (incarnation, id, label, features, crc, provenance) VALUES ";
    PgParams params;
    params.Int(incarnation);
    for (size_t i = begin; i < end; ++i) {
      const StoredSample& s = samples[i];
      const int p = params.size();
      absl::StrAppend(&sql, i == begin ? "" : ",", "($1,$", p + 1, ",$", p + 2, ",$", p + 3, ",$",
                      p + 4, ",$", p + 5, ")");
      params.Int(AsPgId(s.id))
          .Bytes(Bytes(s.label))
          .Bytes(FeatureBytes(s.features))
          .Int(SampleCrc32(0, s.id, s.label, s.features))
          .Bytes(Bytes(EncodeProvenance(s.provenance)));
    }
    SHAPEID_RETURN_IF_ERROR(connection.Exec(what, sql, params));
  }
  return absl::OkStatus();
}

// Appends the change to the log (in commit order, see kLogLockKey) and notifies the other
// replicas; both take effect at COMMIT.
absl::Status LogChange(PgConnection& connection, absl::string_view what, absl::string_view name,
                       int64_t incarnation, uint64_t version, absl::string_view kind,
                       absl::Span<const int64_t> ids, absl::Time updated) {
  SHAPEID_RETURN_IF_ERROR(
      connection.Exec(what, "SELECT pg_advisory_xact_lock($1)", PgParams().Int(kLogLockKey)));
  SHAPEID_RETURN_IF_ERROR(connection.Exec(
      what,
      "INSERT INTO shapeid_changes (gallery, incarnation, version, kind, ids, updated_unix_ns) "
      "VALUES ($1, $2, $3, $4, $5::bigint[], $6)",
      PgParams()
          .Text(std::string(name))
          .Int(incarnation)
          .Int(static_cast<int64_t>(version))
          .Text(std::string(kind))
          .IntArray(ids)
          .Int(absl::ToUnixNanos(updated))));
  return connection.Exec(what, absl::StrCat("NOTIFY ", kChannel));
}

}  // namespace

absl::StatusOr<std::unique_ptr<PostgresGalleryStore>> PostgresGalleryStore::Open(
    PostgresGalleryStoreOptions options) {
  // Two at least: a catch-up holds one while it waits for a gallery whose writer needs another.
  if (options.pool_size < 2) return absl::InvalidArgumentError("pool_size must be at least 2");
  auto pool = std::make_unique<PgConnectionPool>(options.conninfo, options.pool_size);
  std::unique_ptr<PostgresGalleryStore> store(
      new PostgresGalleryStore(std::move(options), std::move(pool)));
  const absl::Status created =
      store->WithConnection("cannot create shapeid's tables", [](PgConnection& c) {
        SHAPEID_RETURN_IF_ERROR(c.Exec("cannot create shapeid's tables",
                                       "SELECT pg_advisory_xact_lock($1)",
                                       PgParams().Int(kSchemaLockKey)));
        return c.ExecScript("cannot create shapeid's tables", kSchema);
      });
  if (!created.ok()) return created;
  return store;
}

PostgresGalleryStore::PostgresGalleryStore(PostgresGalleryStoreOptions options,
                                           std::unique_ptr<PgConnectionPool> pool)
    : options_(std::move(options)), pool_(std::move(pool)) {}

// Runs `work` in one transaction on a pooled connection: BEGIN, work, COMMIT (work's
// statements), ROLLBACK on error. A connection found broken at BEGIN (PostgreSQL restarted
// since it was last used) is replaced once, so a restart costs no call that could not have
// reached it anyway.
template <typename F>
absl::Status PostgresGalleryStore::WithConnection(absl::string_view what, const F& work,
                                                  const char* begin) {
  for (int attempt = 1;; ++attempt) {
    SHAPEID_ASSIGN_OR_RETURN(std::unique_ptr<PgConnection> connection, pool_->Lease());
    absl::Status begun = connection->Exec(what, begin);
    if (!begun.ok()) {
      pool_->Return(nullptr);
      if (absl::IsUnavailable(begun) && attempt == 1) {
        pool_->DropIdle();  // the others died with it
        continue;
      }
      return begun;
    }
    absl::Status status = work(*connection);
    if (status.ok()) status = connection->Exec(what, "COMMIT");
    if (!status.ok() && connection->ok()) (void)connection->Exec(what, "ROLLBACK");
    pool_->Return(std::move(connection));
    return status;
  }
}

absl::Status PostgresGalleryStore::SaveGallery(const StoredGallery& g) {
  const std::string what = absl::StrCat("cannot store gallery '", g.name, "'");
  const int64_t incarnation = static_cast<int64_t>(g.incarnation);
  if (incarnation == 0) {
    return absl::InternalError(absl::StrCat(what, ": it has no incarnation"));
  }
  const absl::Status status = WithConnection(what, [&](PgConnection& c) -> absl::Status {
    const absl::Status inserted =
        c.Exec(what,
               absl::StrCat("INSERT INTO shapeid_galleries (", kGalleryColumns,
                            ") VALUES ($1,$2,$3,$4,$5,$6,$7,$8,$9,$10,$11,$12,$13,$14)"),
               GalleryRow(g));
    if (absl::IsAlreadyExists(inserted)) {
      return absl::AlreadyExistsError(
          absl::StrCat("gallery '", g.name, "' already exists (created through another replica)"));
    }
    SHAPEID_RETURN_IF_ERROR(inserted);
    SHAPEID_RETURN_IF_ERROR(InsertSamples(c, what, incarnation, g.samples));
    SHAPEID_RETURN_IF_ERROR(
        LogChange(c, what, g.name, incarnation, g.version, "create", {}, g.updated));
    // Before COMMIT: the follower may read the change the moment it commits, and must then
    // know it as this replica's own.
    std::lock_guard<std::mutex> lock(incarnations_mu_);
    incarnations_[g.name] = incarnation;
    return absl::OkStatus();
  });
  if (!status.ok()) {
    std::lock_guard<std::mutex> lock(incarnations_mu_);
    auto it = incarnations_.find(g.name);
    if (it != incarnations_.end() && it->second == incarnation) incarnations_.erase(it);
  }
  return status;
}

absl::Status PostgresGalleryStore::DeleteGallery(absl::string_view name) {
  const std::string what = absl::StrCat("cannot delete gallery '", name, "'");
  const absl::Status status = WithConnection(what, [&](PgConnection& c) -> absl::Status {
    SHAPEID_ASSIGN_OR_RETURN(PgResult row,
                             c.Query(what,
                                     "DELETE FROM shapeid_galleries WHERE name = $1 RETURNING "
                                     "incarnation, version",
                                     PgParams().Text(std::string(name))));
    // Deleted through another replica meanwhile: the gallery is gone, as asked.
    if (row.rows() == 0) return absl::OkStatus();
    const int64_t incarnation = row.Int(0, 0);
    SHAPEID_RETURN_IF_ERROR(c.Exec(what, "DELETE FROM shapeid_samples WHERE incarnation = $1",
                                   PgParams().Int(incarnation)));
    SHAPEID_RETURN_IF_ERROR(c.Exec(what, "DELETE FROM shapeid_heads WHERE incarnation = $1",
                                   PgParams().Int(incarnation)));
    return LogChange(c, what, name, incarnation, static_cast<uint64_t>(row.Int(0, 1)), "delete", {},
                     absl::Now());
  });
  // After COMMIT only: a delete that did not commit leaves the gallery, and its writes.
  if (status.ok()) {
    std::lock_guard<std::mutex> lock(incarnations_mu_);
    incarnations_.erase(std::string(name));
  }
  return status;
}

absl::Status PostgresGalleryStore::ChangeSamples(
    absl::string_view name, absl::string_view what_verb, absl::Time updated, uint64_t version,
    absl::string_view kind, absl::Span<const int64_t> ids,
    const std::function<absl::Status(PgConnection&, int64_t)>& change) {
  const std::string what = absl::StrCat("cannot ", what_verb, " gallery '", name, "'");
  int64_t expected;
  {
    std::lock_guard<std::mutex> lock(incarnations_mu_);
    auto it = incarnations_.find(name);
    expected = it != incarnations_.end() ? it->second : 0;
  }
  return WithConnection(what, [&](PgConnection& c) -> absl::Status {
    SHAPEID_ASSIGN_OR_RETURN(
        PgResult row,
        c.Query(what,
                "SELECT incarnation, version FROM shapeid_galleries WHERE name = $1 FOR UPDATE",
                PgParams().Text(std::string(name))));
    // Aborted: this replica's copy is behind the store (deleted, made again, or written
    // through another replica); the gallery catches up and tries again.
    if (row.rows() == 0) {
      return absl::AbortedError(absl::StrCat(what, ": it was deleted through another replica"));
    }
    const int64_t incarnation = row.Int(0, 0);
    const uint64_t stored_version = static_cast<uint64_t>(row.Int(0, 1));
    if (incarnation != expected || stored_version + 1 != version) {
      return absl::AbortedError(absl::StrCat(what,
                                             ": changed through another replica (stored "
                                             "version ",
                                             stored_version, ", this replica's ", version - 1,
                                             ")"));
    }
    SHAPEID_RETURN_IF_ERROR(change(c, incarnation));
    SHAPEID_RETURN_IF_ERROR(c.Exec(
        what, "UPDATE shapeid_galleries SET version = $2, updated_unix_ns = $3 WHERE name = $1",
        PgParams()
            .Text(std::string(name))
            .Int(static_cast<int64_t>(version))
            .Int(absl::ToUnixNanos(updated))));
    return LogChange(c, what, name, incarnation, version, kind, ids, updated);
  });
}

absl::Status PostgresGalleryStore::AppendSamples(absl::string_view name,
                                                 absl::Span<const StoredSample> batch,
                                                 absl::Time updated, uint64_t version) {
  std::vector<int64_t> ids;
  ids.reserve(batch.size());
  for (const StoredSample& s : batch) ids.push_back(AsPgId(s.id));
  return ChangeSamples(name, absl::StrCat("store ", batch.size(), " samples in"), updated, version,
                       "append", ids, [&](PgConnection& c, int64_t incarnation) {
                         return InsertSamples(c, "cannot store samples", incarnation, batch);
                       });
}

absl::Status PostgresGalleryStore::RemoveSamples(absl::string_view name,
                                                 absl::Span<const uint64_t> ids, absl::Time updated,
                                                 uint64_t version) {
  std::vector<int64_t> stored_ids;
  stored_ids.reserve(ids.size());
  for (uint64_t id : ids) stored_ids.push_back(AsPgId(id));
  return ChangeSamples(
      name, absl::StrCat("remove ", ids.size(), " samples from"), updated, version, "remove",
      stored_ids, [&](PgConnection& c, int64_t incarnation) {
        return c.Exec(
            "cannot remove samples",
            "DELETE FROM shapeid_samples WHERE incarnation = $1 AND id = ANY($2::bigint[])",
            PgParams().Int(incarnation).IntArray(stored_ids));
      });
}

// Callers read in one snapshot (kSnapshot): the row and its samples are two statements.
absl::StatusOr<StoredGallery> PostgresSnapshot::ReadGallery(absl::string_view name, bool* found) {
  PgConnection& c = c_;
  const std::string what = absl::StrCat("cannot read gallery '", name, "'");
  SHAPEID_ASSIGN_OR_RETURN(
      PgResult row,
      c.Query(what,
              absl::StrCat("SELECT ", kGalleryColumns, " FROM shapeid_galleries WHERE name = $1"),
              PgParams().Text(std::string(name))));
  *found = row.rows() == 1;
  if (!*found) return StoredGallery();
  const auto damaged = [&](absl::string_view why) {
    return absl::DataLossError(
        absl::StrCat("gallery '", name, "' in PostgreSQL is damaged: ", why));
  };
  StoredGallery g;
  SHAPEID_ASSIGN_OR_RETURN(static_cast<GalleryMetadata&>(g), FromGalleryRow(row, 0, damaged));

  SHAPEID_ASSIGN_OR_RETURN(
      PgResult samples,
      c.Query(what,
              absl::StrCat("SELECT ", kSampleColumns,
                           " FROM shapeid_samples WHERE incarnation = $1 ORDER BY position"),
              PgParams().Int(static_cast<int64_t>(g.incarnation)), /*binary=*/true));
  g.samples.reserve(static_cast<size_t>(samples.rows()));
  for (int r = 0; r < samples.rows(); ++r) {
    SHAPEID_ASSIGN_OR_RETURN(StoredSample s, FromSampleRow(samples, r, g.dimension, damaged));
    g.samples.push_back(std::move(s));
  }
  return g;
}

absl::StatusOr<std::vector<StoredGallery>> PostgresGalleryStore::LoadAll() {
  std::vector<StoredGallery> all;
  int64_t seq = 0;
  // One snapshot of the database: the galleries as of the log position read with them.
  const absl::Status status = WithConnection(
      "cannot load galleries",
      [&](PgConnection& c) {
        SHAPEID_ASSIGN_OR_RETURN(
            PgResult last,
            c.Query("cannot load galleries",
                    "SELECT greatest((SELECT coalesce(max(seq), 0) FROM shapeid_changes), "
                    "(SELECT seq FROM shapeid_log_floor))"));
        seq = last.Int(0, 0);
        SHAPEID_ASSIGN_OR_RETURN(
            PgResult names,
            c.Query("cannot load galleries", "SELECT name FROM shapeid_galleries ORDER BY name"));
        for (int r = 0; r < names.rows(); ++r) {
          bool found = false;
          SHAPEID_ASSIGN_OR_RETURN(StoredGallery g,
                                   PostgresSnapshot(c).ReadGallery(names.Value(r, 0), &found));
          if (found) all.push_back(std::move(g));
        }
        return absl::OkStatus();
      },
      kSnapshot);
  SHAPEID_RETURN_IF_ERROR(status);
  {
    std::lock_guard<std::mutex> lock(incarnations_mu_);
    incarnations_.clear();
    for (const StoredGallery& g : all) incarnations_[g.name] = static_cast<int64_t>(g.incarnation);
  }
  loaded_position_.store(seq);
  return all;
}

absl::Status PostgresGalleryStore::SaveHead(absl::string_view name, absl::string_view bytes) {
  const std::string what = absl::StrCat("cannot keep the trained head of gallery '", name, "'");
  // One statement, so atomic; a gallery deleted meanwhile matches no row and keeps nothing.
  return WithConnection(what, [&](PgConnection& c) {
    return c.Exec(what,
                  "INSERT INTO shapeid_heads (incarnation, head) SELECT incarnation, $2 FROM "
                  "shapeid_galleries WHERE name = $1 ON CONFLICT (incarnation) DO UPDATE SET "
                  "head = EXCLUDED.head",
                  PgParams()
                      .Text(std::string(name))
                      .Bytes(absl::MakeConstSpan(reinterpret_cast<const uint8_t*>(bytes.data()),
                                                 bytes.size())));
  });
}

absl::Status PostgresGalleryStore::Load(GalleryLoader& loader) {
  SHAPEID_ASSIGN_OR_RETURN(std::vector<StoredGallery> all, LoadAll());
  // Read after the galleries, outside their snapshot: a head fitted on other samples than
  // those loaded is refused by the loader's fingerprint check and fitted again.
  std::map<int64_t, std::string> name_of;  // by incarnation
  for (const StoredGallery& gallery : all) {
    name_of[static_cast<int64_t>(gallery.incarnation)] = gallery.name;
  }
  std::map<std::string, std::string, std::less<>> heads;
  const absl::Status read = WithConnection("cannot read trained heads", [&](PgConnection& c) {
    SHAPEID_ASSIGN_OR_RETURN(PgResult rows,
                             c.Query("cannot read trained heads",
                                     "SELECT incarnation, head FROM shapeid_heads", PgParams(),
                                     /*binary=*/true));
    for (int r = 0; r < rows.rows(); ++r) {
      if (auto name = name_of.find(rows.BinaryInt(r, 0)); name != name_of.end()) {
        heads[name->second] = std::string(rows.Value(r, 1));
      }
    }
    return absl::OkStatus();
  });
  // Heads are derived: without them every gallery still loads, and fits its head again.
  if (!read.ok()) heads.clear();
  return HandOverGalleries(std::move(all), heads, loader);
}

absl::Status PostgresGalleryStore::ReadSnapshot(
    const std::function<absl::Status(PostgresSnapshot&)>& read) {
  return WithConnection(
      "cannot read the change log",
      [&](PgConnection& c) {
        PostgresSnapshot snapshot(c);
        return read(snapshot);
      },
      kSnapshot);
}

absl::StatusOr<std::unique_ptr<PostgresListener>> PostgresGalleryStore::Listen() {
  SHAPEID_ASSIGN_OR_RETURN(std::unique_ptr<PgConnection> connection,
                           ConnectBounded(options_.conninfo));
  SHAPEID_RETURN_IF_ERROR(connection->Exec("cannot listen", absl::StrCat("LISTEN ", kChannel)));
  return std::make_unique<PostgresListener>(std::move(connection));
}

void PostgresGalleryStore::HeldIncarnation(absl::string_view name, int64_t incarnation) {
  std::lock_guard<std::mutex> lock(incarnations_mu_);
  incarnations_[std::string(name)] = incarnation;
}

void PostgresGalleryStore::DroppedIncarnation(absl::string_view name, int64_t incarnation) {
  std::lock_guard<std::mutex> lock(incarnations_mu_);
  auto it = incarnations_.find(name);
  if (it != incarnations_.end() && it->second == incarnation) incarnations_.erase(it);
}

absl::StatusOr<int64_t> PostgresSnapshot::LogFloor() {
  SHAPEID_ASSIGN_OR_RETURN(
      PgResult floor, c_.Query("cannot read the change log", "SELECT seq FROM shapeid_log_floor"));
  return floor.rows() == 1 ? floor.Int(0, 0) : 0;
}

absl::StatusOr<std::vector<std::string>> PostgresSnapshot::GalleryNames() {
  SHAPEID_ASSIGN_OR_RETURN(
      PgResult names, c_.Query("cannot read the change log", "SELECT name FROM shapeid_galleries"));
  std::vector<std::string> all;
  for (int r = 0; r < names.rows(); ++r) all.emplace_back(names.Value(r, 0));
  return all;
}

absl::StatusOr<std::vector<LoggedChange>> PostgresSnapshot::ReadChangesAfter(int64_t position,
                                                                             int limit) {
  SHAPEID_ASSIGN_OR_RETURN(
      PgResult rows,
      c_.Query("cannot read the change log",
               "SELECT seq, gallery, incarnation, version, kind, ids, updated_unix_ns "
               "FROM shapeid_changes WHERE seq > $1 ORDER BY seq LIMIT $2",
               PgParams().Int(position).Int(limit)));
  std::vector<LoggedChange> changes(static_cast<size_t>(rows.rows()));
  for (int r = 0; r < rows.rows(); ++r) {
    LoggedChange& change = changes[static_cast<size_t>(r)];
    change.seq = rows.Int(r, 0);
    change.gallery = std::string(rows.Value(r, 1));
    change.incarnation = rows.Int(r, 2);
    change.version = static_cast<uint64_t>(rows.Int(r, 3));
    change.kind = std::string(rows.Value(r, 4));
    // BIGINT[] in text form: "{1,2,3}".
    absl::string_view ids = rows.Value(r, 5);
    ids.remove_prefix(1);
    ids.remove_suffix(1);
    for (absl::string_view id : absl::StrSplit(ids, ',', absl::SkipEmpty())) {
      int64_t value = 0;
      if (!absl::SimpleAtoi(id, &value)) {
        return absl::DataLossError(absl::StrCat("change ", change.seq, " has a bad id list"));
      }
      change.ids.push_back(value);
    }
    change.updated = absl::FromUnixNanos(rows.Int(r, 6));
  }
  return changes;
}

absl::StatusOr<std::vector<StoredSample>> PostgresSnapshot::ReadAppended(
    const LoggedChange& change) {
  SHAPEID_ASSIGN_OR_RETURN(
      PgResult rows,
      c_.Query("cannot read samples",
               absl::StrCat("SELECT ", kSampleColumns,
                            " FROM shapeid_samples WHERE incarnation = $1 AND "
                            "id = ANY($2::bigint[]) ORDER BY position"),
               PgParams().Int(change.incarnation).IntArray(change.ids), /*binary=*/true));
  const auto damaged = [&](absl::string_view why) {
    return absl::DataLossError(
        absl::StrCat("gallery '", change.gallery, "' in PostgreSQL is damaged: ", why));
  };
  std::vector<StoredSample> samples;
  samples.reserve(static_cast<size_t>(rows.rows()));
  for (int r = 0; r < rows.rows(); ++r) {
    // The features' length is checked where they are applied (KnnIndex::Add).
    SHAPEID_ASSIGN_OR_RETURN(StoredSample s, FromSampleRow(rows, r, /*dimension=*/1, damaged));
    samples.push_back(std::move(s));
  }
  return samples;
}

absl::StatusOr<bool> PostgresListener::WaitForNotification(absl::Duration timeout) {
  pollfd fd{connection_->socket(), POLLIN, 0};
  const int timeout_ms = static_cast<int>(std::max<int64_t>(1, absl::ToInt64Milliseconds(timeout)));
  if (::poll(&fd, 1, timeout_ms) == 0) return false;
  SHAPEID_ASSIGN_OR_RETURN(std::vector<std::string> notified, connection_->TakeNotifications());
  return !notified.empty();
}

bool PostgresListener::TakeQueuedNotification() {
  if (!connection_->ok()) return false;
  absl::StatusOr<std::vector<std::string>> queued = connection_->TakeNotifications();
  return queued.ok() && !queued->empty();
}

absl::Status PostgresListener::ReadSnapshot(
    const std::function<absl::Status(PostgresSnapshot&)>& read) {
  absl::Status status = connection_->Exec("cannot read the change log", kSnapshot);
  if (status.ok()) {
    PostgresSnapshot snapshot(*connection_);
    status = read(snapshot);
  }
  const absl::Status ended =
      connection_->Exec("cannot read the change log", status.ok() ? "COMMIT" : "ROLLBACK");
  return status.ok() ? ended : status;
}

void PostgresListener::PruneLog() {
  (void)connection_->Exec(
      "prune the change log",
      absl::StrCat("WITH gone AS (DELETE FROM shapeid_changes WHERE logged < "
                   "clock_timestamp() - interval '",
                   kLogRetention,
                   "' RETURNING seq) UPDATE shapeid_log_floor SET seq = greatest(seq, "
                   "(SELECT coalesce(max(seq), 0) FROM gone))"));
}

}  // namespace shapeid
