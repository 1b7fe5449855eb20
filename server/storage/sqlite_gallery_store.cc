#include "server/storage/sqlite_gallery_store.h"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <utility>

#include "absl/strings/ascii.h"
#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/strip.h"
#include "absl/time/clock.h"
#include "core/gallery/gallery_options.h"
#include "core/io/file_writer.h"
#include "core/io/point_cloud_reader.h"
#include "core/status_macros.h"
#include "server/storage/file_util.h"
#include "server/storage/sample_checksum.h"
#include "server/storage/sqlite_gallery_file.h"

namespace shapeid {

using sqlite_gallery_file::AsStoredId;
using sqlite_gallery_file::BindGalleryRow;
using sqlite_gallery_file::Damaged;
using sqlite_gallery_file::GalleryRowCrc;
using sqlite_gallery_file::InsertSample;
using sqlite_gallery_file::InsertSampleSql;
using sqlite_gallery_file::kApplicationId;
using sqlite_gallery_file::kConnectionPragmas;
using sqlite_gallery_file::kGalleryColumns;
using sqlite_gallery_file::kSchema;
using sqlite_gallery_file::ReadGallery;

namespace {

constexpr absl::string_view kGallerySuffix = ".gallery";
// A gallery's trained head (GalleryStore::SaveHead), beside its file; NAME.head.tmp while
// being written.
constexpr absl::string_view kHeadSuffix = ".head";

std::string UtcStamp() {
  return absl::FormatTime("%Y%m%dT%H%M%SZ", absl::Now(), absl::UTCTimeZone());
}

}  // namespace

// One gallery's open database and its prepared writes. `header` mirrors the gallery row
// (without samples) so an update can recompute the row's CRC.
struct SqliteGalleryStore::OpenGallery {
  std::mutex mu;
  std::unique_ptr<SqliteDb> db ABSL_GUARDED_BY(mu);
  SqliteStatement insert ABSL_GUARDED_BY(mu);
  SqliteStatement remove ABSL_GUARDED_BY(mu);
  SqliteStatement touch ABSL_GUARDED_BY(mu);
  // The file's PRAGMA user_version, which decides the insert's columns.
  int64_t format ABSL_GUARDED_BY(mu) = 0;
  GalleryMetadata header ABSL_GUARDED_BY(mu);
  // Set after a failed fsync; every later write fails with it.
  absl::Status broken ABSL_GUARDED_BY(mu);

  // Finalizes the statements, then closes (a connection with live statements cannot close,
  // so it would not checkpoint). Null db: the gallery is served read-only.
  void CloseWrites() ABSL_EXCLUSIVE_LOCKS_REQUIRED(mu) {
    insert = SqliteStatement();
    remove = SqliteStatement();
    touch = SqliteStatement();
    if (db != nullptr) (void)db->Close();
    db.reset();
  }
};

// Passes everything on to the loader and keeps its first error, which must end the load as it
// is: a loader's error is never damage in the file, so never a reason to set the file aside.
class SqliteGalleryStore::CheckedLoader final : public GalleryLoader {
 public:
  explicit CheckedLoader(GalleryLoader& loader) : loader_(loader) {}
  absl::Status Begin(const GalleryMetadata& gallery) override {
    return Checked(loader_.Begin(gallery));
  }
  absl::Status Add(StoredSample& sample) override { return Checked(loader_.Add(sample)); }
  absl::Status End() override { return Checked(loader_.End()); }
  const absl::Status& error() const { return error_; }

 private:
  absl::Status Checked(absl::Status status) {
    if (error_.ok()) error_ = status;
    return status;
  }

  GalleryLoader& loader_;
  absl::Status error_;
};

absl::StatusOr<std::unique_ptr<SqliteGalleryStore>> SqliteGalleryStore::Open(
    SqliteGalleryStoreOptions options) {
  if (options.data_dir.empty()) return absl::InvalidArgumentError("data_dir is empty");
  while (options.data_dir.size() > 1 && options.data_dir.back() == '/') {
    options.data_dir.pop_back();
  }
  // access() reports EROFS even to root, whose permission checks it otherwise skips.
  std::string read_only;
  if (access(options.data_dir.c_str(), W_OK) != 0 && errno == EROFS) {
    read_only = absl::StrCat("the data directory ", options.data_dir,
                             " is on a read-only file system; galleries are served but cannot "
                             "change");
  } else {
    SHAPEID_RETURN_IF_ERROR(MakeDirectories(options.data_dir + "/galleries"));
  }
  const std::string lock_path = options.data_dir + "/LOCK";
  const int fd =
      open(lock_path.c_str(), (read_only.empty() ? O_RDWR | O_CREAT : O_RDONLY) | O_CLOEXEC, 0644);
  if (fd < 0 && !(errno == ENOENT && !read_only.empty())) {
    return absl::UnavailableError(
        absl::StrCat("cannot open ", lock_path, ": ", std::strerror(errno)));
  }
  // Exclusive for a writer; shared among read-only servers, which cannot disturb each other.
  if (fd >= 0 && flock(fd, (read_only.empty() ? LOCK_EX : LOCK_SH) | LOCK_NB) != 0) {
    char pid[32] = {};
    [[maybe_unused]] const ssize_t n = pread(fd, pid, sizeof(pid) - 1, 0);
    close(fd);
    return absl::FailedPreconditionError(
        absl::StrCat("data directory ", options.data_dir,
                     " is in use by another shapeid-server (pid ", absl::StripAsciiWhitespace(pid),
                     " per ", lock_path, "); two servers must never share one directory"));
  }
  if (read_only.empty()) {
    // The pid is only a hint for the message above; the lock is what matters.
    const std::string pid = absl::StrCat(getpid(), "\n");
    if (ftruncate(fd, 0) != 0 || pwrite(fd, pid.data(), pid.size(), 0) < 0) {
    }
  }
  return std::unique_ptr<SqliteGalleryStore>(
      new SqliteGalleryStore(std::move(options), fd, std::move(read_only)));
}

SqliteGalleryStore::SqliteGalleryStore(SqliteGalleryStoreOptions options, int lock_fd,
                                       std::string read_only)
    : options_(std::move(options)),
      galleries_dir_(options_.data_dir + "/galleries"),
      lock_fd_(lock_fd),
      read_only_(std::move(read_only)) {}

absl::Status SqliteGalleryStore::CheckWritable(absl::string_view what) const {
  if (read_only_.empty()) return absl::OkStatus();
  return absl::UnavailableError(absl::StrCat("cannot ", what, ": ", read_only_));
}

SqliteGalleryStore::~SqliteGalleryStore() {
  {
    std::lock_guard<std::mutex> lock(mu_);
    open_.clear();  // closes (and checkpoints) every database before the lock is released
  }
  if (lock_fd_ >= 0) close(lock_fd_);
}

std::string SqliteGalleryStore::GalleryPath(absl::string_view name) const {
  return absl::StrCat(galleries_dir_, "/", name, kGallerySuffix);
}

std::string SqliteGalleryStore::HeadPath(absl::string_view name) const {
  return absl::StrCat(galleries_dir_, "/", name, kHeadSuffix);
}

absl::Status SqliteGalleryStore::SaveHead(absl::string_view name, absl::string_view bytes) {
  SHAPEID_RETURN_IF_ERROR(CheckWritable(absl::StrCat("keep the head of gallery '", name, "'")));
  SHAPEID_ASSIGN_OR_RETURN(std::shared_ptr<OpenGallery> g, Find(name));
  std::lock_guard<std::mutex> lock(g->mu);  // not beside a delete of the gallery
  absl::Status status = WriteFileAtomically(HeadPath(name), bytes);
  if (status.ok()) status = SyncDirectory(galleries_dir_);
  if (!status.ok()) {
    return absl::Status(status.code(), absl::StrCat("cannot keep the head of gallery '", name,
                                                    "': ", status.message()));
  }
  return absl::OkStatus();
}

std::vector<SqliteGalleryStore::SetAside> SqliteGalleryStore::set_aside() const {
  std::lock_guard<std::mutex> lock(mu_);
  return set_aside_;
}

std::vector<SqliteGalleryStore::ReadOnlyGallery> SqliteGalleryStore::read_only_galleries() const {
  std::lock_guard<std::mutex> lock(mu_);
  std::vector<ReadOnlyGallery> galleries;
  for (const auto& [name, reason] : read_only_galleries_) galleries.push_back({name, reason});
  return galleries;
}

absl::StatusOr<std::shared_ptr<SqliteGalleryStore::OpenGallery>> SqliteGalleryStore::Find(
    absl::string_view name) const {
  std::lock_guard<std::mutex> lock(mu_);
  auto it = open_.find(name);
  if (it == open_.end()) {
    return absl::InternalError(absl::StrCat("the store holds no gallery '", name, "'"));
  }
  return it->second;
}

namespace {

// Opens a gallery's database for writing: pragmas, the file's format and the prepared
// statements.
absl::Status PrepareWrites(const std::string& path, const std::string& vfs,
                           std::unique_ptr<SqliteDb>* db, int64_t* format, SqliteStatement* insert,
                           SqliteStatement* remove, SqliteStatement* touch) {
  if (*db == nullptr) {
    SHAPEID_ASSIGN_OR_RETURN(*db, SqliteDb::Open(path, SqliteDb::Mode::kReadWrite, vfs));
  }
  SHAPEID_RETURN_IF_ERROR((*db)->Exec(kConnectionPragmas));
  SHAPEID_ASSIGN_OR_RETURN(*format, (*db)->QueryInt("PRAGMA user_version"));
  SHAPEID_ASSIGN_OR_RETURN(*insert, (*db)->Prepare(InsertSampleSql(*format)));
  SHAPEID_ASSIGN_OR_RETURN(*remove, (*db)->Prepare("DELETE FROM samples WHERE id = ?"));
  SHAPEID_ASSIGN_OR_RETURN(
      *touch,
      (*db)->Prepare("UPDATE gallery SET updated_unix_ns = ?, crc = ? WHERE singleton = 1"));
  return absl::OkStatus();
}

// Commits `body` as one transaction, or rolls it back.
template <typename Body>
absl::Status Transaction(SqliteDb& db, Body body) {
  SHAPEID_RETURN_IF_ERROR(db.Exec("BEGIN IMMEDIATE"));
  absl::Status status = body();
  if (status.ok()) status = db.Exec("COMMIT");
  if (!status.ok()) db.RollbackIfOpen();
  return status;
}

// After a failed fsync the page cache may no longer match the disk (the kernel can drop
// dirty pages it failed to write), so nothing but a fresh load can be trusted.
bool IsFsyncFailure(SqliteDb& db) {
  const int code = sqlite3_extended_errcode(db.raw());
  return code == SQLITE_IOERR_FSYNC || code == SQLITE_IOERR_DIR_FSYNC;
}

// A disk that could not be written or read (full, read-only, I/O errors), as opposed to the
// file's content: never grounds for setting a gallery aside.
bool IsDiskCondition(const absl::Status& status) {
  return status.code() == absl::StatusCode::kResourceExhausted ||
         status.code() == absl::StatusCode::kUnavailable;
}

// What start-up may set aside: damage proven by SQLite or our checks, or a newer format.
bool IsProvenDamage(const absl::Status& status) {
  return status.code() == absl::StatusCode::kDataLoss ||
         status.code() == absl::StatusCode::kFailedPrecondition;
}

}  // namespace

absl::Status SqliteGalleryStore::SaveGallery(const StoredGallery& gallery) {
  SHAPEID_RETURN_IF_ERROR(CheckWritable(absl::StrCat("store gallery '", gallery.name, "'")));
  if (absl::Status s = ValidateGalleryName(gallery.name); !s.ok()) return s;
  const std::string final_path = GalleryPath(gallery.name);
  const std::string tmp_path = absl::StrCat(galleries_dir_, "/.", gallery.name, ".tmp");
  const auto remove_tmp = [&] {
    for (const char* suffix : {"", "-wal", "-shm", "-journal"}) {
      (void)RemoveFileIfExists(tmp_path + suffix);
    }
  };
  const std::string where = absl::StrCat("cannot store gallery '", gallery.name, "'");
  remove_tmp();
  if (FileExists(final_path)) {
    return absl::InternalError(absl::StrCat(where, ": ", final_path, " already exists"));
  }

  // The whole gallery goes into a temporary file first: a crash leaves either no gallery or
  // all of it, never an empty shell with half its samples.
  absl::Status status = [&]() -> absl::Status {
    SHAPEID_ASSIGN_OR_RETURN(
        std::unique_ptr<SqliteDb> db,
        SqliteDb::Open(tmp_path, SqliteDb::Mode::kCreate, options_.testing_vfs));
    SHAPEID_RETURN_IF_ERROR(db->Exec(absl::StrCat(
        "PRAGMA application_id=", kApplicationId, "; PRAGMA user_version=", kFormatVersion,
        "; PRAGMA journal_mode=WAL;", kConnectionPragmas)));
    const absl::Status written = Transaction(*db, [&]() -> absl::Status {
      SHAPEID_RETURN_IF_ERROR(db->Exec(kSchema));
      SHAPEID_ASSIGN_OR_RETURN(
          SqliteStatement row,
          db->Prepare(absl::StrCat("INSERT INTO gallery(singleton, ", kGalleryColumns,
                                   ") VALUES(1,?,?,?,?,?,?,?,?,?,?,?,?,?)")));
      BindGalleryRow(row, gallery);
      SHAPEID_RETURN_IF_ERROR(row.Run());
      SHAPEID_ASSIGN_OR_RETURN(SqliteStatement insert,
                               db->Prepare(InsertSampleSql(kFormatVersion)));
      for (const StoredSample& sample : gallery.samples) {
        SHAPEID_RETURN_IF_ERROR(InsertSample(insert, kFormatVersion, sample));
      }
      return absl::OkStatus();
    });
    SHAPEID_RETURN_IF_ERROR(written);
    // Closing the last connection checkpoints the WAL into the file and removes the -wal.
    SHAPEID_RETURN_IF_ERROR(db->Close());
    SHAPEID_RETURN_IF_ERROR(SyncFile(tmp_path));
    // A -wal or -shm left by an earlier gallery of this name must not be replayed into it.
    SHAPEID_RETURN_IF_ERROR(RemoveFileIfExists(final_path + "-wal"));
    SHAPEID_RETURN_IF_ERROR(RemoveFileIfExists(final_path + "-shm"));
    SHAPEID_RETURN_IF_ERROR(RenameFile(tmp_path, final_path));
    return SyncDirectory(galleries_dir_);  // the durable point
  }();
  if (!status.ok()) {
    remove_tmp();
    return absl::Status(status.code(), absl::StrCat(where, ": ", status.message()));
  }

  auto open = std::make_shared<OpenGallery>();
  std::lock_guard<std::mutex> gallery_lock(open->mu);
  status = PrepareWrites(final_path, options_.testing_vfs, &open->db, &open->format, &open->insert,
                         &open->remove, &open->touch);
  if (!status.ok()) {
    // Stored but not writable: undo, so that the failed call leaves no gallery behind.
    open->db.reset();
    (void)RemoveFileIfExists(final_path);
    (void)SyncDirectory(galleries_dir_);
    return absl::Status(status.code(), absl::StrCat(where, ": ", status.message()));
  }
  open->header = gallery;
  std::lock_guard<std::mutex> lock(mu_);
  open_[gallery.name] = std::move(open);
  return absl::OkStatus();
}

absl::Status SqliteGalleryStore::ChangeSamples(
    absl::string_view name, absl::string_view what, absl::Time updated,
    const std::function<absl::Status(OpenGallery&)>& change) {
  SHAPEID_RETURN_IF_ERROR(CheckWritable(absl::StrCat(what, " gallery '", name, "'")));
  SHAPEID_ASSIGN_OR_RETURN(std::shared_ptr<OpenGallery> g, Find(name));
  std::lock_guard<std::mutex> lock(g->mu);
  SHAPEID_RETURN_IF_ERROR(g->broken);
  if (g->db == nullptr) SHAPEID_RETURN_IF_ERROR(Reopen(name, what, *g));
  GalleryMetadata header = g->header;
  header.updated = updated;
  absl::Status status = Transaction(*g->db, [&]() -> absl::Status {
    SHAPEID_RETURN_IF_ERROR(change(*g));
    g->touch.BindInt64(1, absl::ToUnixNanos(updated));
    g->touch.BindInt64(2, GalleryRowCrc(header));
    return g->touch.Run();
  });
  if (!status.ok()) {
    status = absl::Status(
        status.code(), absl::StrCat("cannot ", what, " gallery '", name, "': ", status.message()));
    if (IsFsyncFailure(*g->db)) g->broken = status;
    return status;
  }
  g->header = std::move(header);
  return absl::OkStatus();
}

absl::Status SqliteGalleryStore::AppendSamples(absl::string_view name,
                                               absl::Span<const StoredSample> batch,
                                               absl::Time updated, uint64_t /*version*/) {
  const bool has_provenance = std::any_of(
      batch.begin(), batch.end(), [](const StoredSample& s) { return !s.provenance.empty(); });
  const std::string what = absl::StrCat("store ", batch.size(), " samples in");
  if (has_provenance) SHAPEID_RETURN_IF_ERROR(AddProvenanceColumn(name, what));
  return ChangeSamples(name, what, updated, [&](OpenGallery& g) -> absl::Status {
    for (const StoredSample& sample : batch) {
      SHAPEID_RETURN_IF_ERROR(InsertSample(g.insert, g.format, sample));
    }
    return absl::OkStatus();
  });
}

absl::Status SqliteGalleryStore::AddProvenanceColumn(absl::string_view name,
                                                     absl::string_view what) {
  SHAPEID_RETURN_IF_ERROR(CheckWritable(absl::StrCat(what, " gallery '", name, "'")));
  SHAPEID_ASSIGN_OR_RETURN(std::shared_ptr<OpenGallery> g, Find(name));
  std::lock_guard<std::mutex> lock(g->mu);
  SHAPEID_RETURN_IF_ERROR(g->broken);
  if (g->db == nullptr) SHAPEID_RETURN_IF_ERROR(Reopen(name, what, *g));
  if (g->format >= sqlite_gallery_file::kFirstFormatWithProvenance) return absl::OkStatus();
  // Its own transaction: if the samples' then fails, the file merely has an empty column.
  absl::Status status =
      Transaction(*g->db, [&] { return g->db->Exec(sqlite_gallery_file::kAddProvenanceColumn); });
  if (status.ok()) {
    absl::StatusOr<SqliteStatement> insert =
        g->db->Prepare(InsertSampleSql(sqlite_gallery_file::kFirstFormatWithProvenance));
    status = insert.status();
    if (insert.ok()) {
      g->insert = *std::move(insert);
      g->format = sqlite_gallery_file::kFirstFormatWithProvenance;
    }
  }
  if (!status.ok()) {
    return absl::Status(status.code(),
                        absl::StrCat("cannot ", what, " gallery '", name,
                                     "': adding the provenance column: ", status.message()));
  }
  return absl::OkStatus();
}

absl::Status SqliteGalleryStore::RemoveSamples(absl::string_view name,
                                               absl::Span<const uint64_t> ids, absl::Time updated,
                                               uint64_t /*version*/) {
  return ChangeSamples(
      name, absl::StrCat("remove ", ids.size(), " samples from"), updated,
      [&](OpenGallery& g) -> absl::Status {
        for (uint64_t id : ids) {
          g.remove.BindInt64(1, AsStoredId(id));
          SHAPEID_RETURN_IF_ERROR(g.remove.Run());
          if (sqlite3_changes(g.db->raw()) != 1) {
            return absl::InternalError(absl::StrCat("sample id ", id, " is not stored"));
          }
        }
        return absl::OkStatus();
      });
}

absl::Status SqliteGalleryStore::DeleteGallery(absl::string_view name) {
  SHAPEID_RETURN_IF_ERROR(CheckWritable(absl::StrCat("delete gallery '", name, "'")));
  SHAPEID_ASSIGN_OR_RETURN(std::shared_ptr<OpenGallery> g, Find(name));
  std::lock_guard<std::mutex> lock(g->mu);
  const std::string path = GalleryPath(name);
  const std::string doomed = absl::StrCat(galleries_dir_, "/.", name, ".deleted");
  // Checkpoint and close first, so the -wal holds nothing the rename would orphan. If the
  // close fails, the rename below still removes the gallery; its -wal goes with it. A
  // gallery served read-only has no connection.
  const bool writable = g->db != nullptr;
  if (writable) g->CloseWrites();
  absl::Status status = RenameFile(path, doomed);
  if (status.ok()) status = SyncDirectory(galleries_dir_);  // the durable point
  if (!status.ok()) {
    // Still stored: reopen so the gallery stays writable, as the registry keeps it.
    if (writable) {
      g->broken = PrepareWrites(path, options_.testing_vfs, &g->db, &g->format, &g->insert,
                                &g->remove, &g->touch);
    }
    return absl::Status(status.code(),
                        absl::StrCat("cannot delete gallery '", name, "': ", status.message()));
  }
  {
    std::lock_guard<std::mutex> store_lock(mu_);
    open_.erase(std::string(name));
    read_only_galleries_.erase(std::string(name));
  }
  // Best effort: start-up removes whatever a crash leaves here.
  for (const std::string& leftover :
       {doomed, path + "-wal", path + "-shm", HeadPath(name), HeadPath(name) + ".tmp"}) {
    (void)RemoveFileIfExists(leftover);
  }
  return absl::OkStatus();
}

absl::StatusOr<GalleryMetadata> SqliteGalleryStore::LoadFile(const std::string& name,
                                                             CheckedLoader& loader,
                                                             std::shared_ptr<OpenGallery>* out,
                                                             absl::Status* unwritable) {
  const std::string path = GalleryPath(name);
  if (absl::Status s = ValidateGalleryName(name); !s.ok()) {
    return absl::DataLossError(
        absl::StrCat(path, " is not named after a valid gallery: ", s.message()));
  }
  auto open = std::make_shared<OpenGallery>();
  std::lock_guard<std::mutex> lock(open->mu);
  absl::StatusOr<GalleryMetadata> loaded;
  if (read_only()) {
    *unwritable = absl::UnavailableError(read_only_);
  } else {
    absl::StatusOr<std::unique_ptr<SqliteDb>> db =
        SqliteDb::Open(path, SqliteDb::Mode::kReadWrite, options_.testing_vfs);
    loaded = db.ok() ? ReadGallery(**db, path, name, loader) : db.status();
    if (!loader.error().ok()) return loader.error();
    if (loaded.ok() && (*db)->read_only()) {
      // unix opened it read-only by itself: read completely, but every write would fail.
      *unwritable = absl::UnavailableError(
          absl::StrCat(path, " can only be read (a read-only file or volume)"));
    } else if (loaded.ok()) {
      open->db = *std::move(db);
      *unwritable = PrepareWrites(path, options_.testing_vfs, &open->db, &open->format,
                                  &open->insert, &open->remove, &open->touch);
      if (!unwritable->ok()) open->CloseWrites();
    } else if (!IsDiskCondition(loaded.status())) {
      return Damaged(path, loaded.status());
    } else {
      // Read-write needs SQLite's -shm (and -wal) created and written; reading need not.
      *unwritable = loaded.status();
    }
  }
  if (!loaded.ok()) {
    // Read again from the start: the loader drops what the first read began.
    loaded = ReadReadOnly(name, loader);
    if (!loader.error().ok()) return loader.error();
    if (!loaded.ok() && IsDiskCondition(loaded.status())) {
      return absl::Status(
          loaded.status().code(),
          absl::StrCat(path,
                       " cannot be read because of the disk, which is not damage, so "
                       "nothing was moved: ",
                       loaded.status().message(),
                       read_only() ? "" : absl::StrCat("; for writing: ", unwritable->message()),
                       ". Free space or repair the disk, then restart"));
    }
    if (!loaded.ok()) return Damaged(path, loaded.status());
  }
  open->header = *loaded;
  *out = std::move(open);
  return loaded;
}

absl::StatusOr<GalleryMetadata> SqliteGalleryStore::ReadReadOnly(const std::string& name,
                                                                 GalleryLoader& loader) {
  const std::string path = GalleryPath(name);
  // Committed transactions still in the -wal must be seen: an immutable open would ignore
  // them, so then the -wal is read into private memory instead (no -shm needed). The
  // directory's LOCK keeps every other shapeid process from writing meanwhile.
  SqliteDb::Mode mode = SqliteDb::Mode::kReadOnlyImmutable;
  struct stat wal;
  if (stat((path + "-wal").c_str(), &wal) == 0) {
    if (wal.st_size > 0) mode = SqliteDb::Mode::kReadOnlyPrivateWal;
  } else if (const int err = errno; err != ENOENT) {
    return absl::UnavailableError(absl::StrCat("cannot stat ", path, "-wal: ", std::strerror(err)));
  }
  std::string vfs = options_.testing_vfs;
  if (!vfs.empty() && mode == SqliteDb::Mode::kReadOnlyPrivateWal) vfs += "-none";
  SHAPEID_ASSIGN_OR_RETURN(std::unique_ptr<SqliteDb> db, SqliteDb::Open(path, mode, vfs));
  return ReadGallery(*db, path, name, loader);
}

absl::Status SqliteGalleryStore::Reopen(absl::string_view name, absl::string_view what,
                                        OpenGallery& g) {
  const std::string path = GalleryPath(name);
  absl::Status status =
      PrepareWrites(path, options_.testing_vfs, &g.db, &g.format, &g.insert, &g.remove, &g.touch);
  if (status.ok() && g.db->read_only()) {
    status = absl::UnavailableError(
        absl::StrCat(path, " can only be read (a read-only file or volume)"));
  }
  if (!status.ok()) {
    g.CloseWrites();
    return absl::Status(status.code(),
                        absl::StrCat("cannot ", what, " gallery '", name,
                                     "': it is served read-only, as its file cannot be opened "
                                     "for writing: ",
                                     status.message()));
  }
  std::lock_guard<std::mutex> lock(mu_);
  read_only_galleries_.erase(std::string(name));
  return absl::OkStatus();
}

absl::Status SqliteGalleryStore::SetAsideFile(const std::string& name, const absl::Status& reason) {
  const std::string damaged_dir = options_.data_dir + "/damaged";
  SHAPEID_RETURN_IF_ERROR(MakeDirectories(damaged_dir));
  const std::string from = GalleryPath(name);
  const std::string to = absl::StrCat(damaged_dir, "/", name, ".", UtcStamp(), kGallerySuffix);
  // The -wal first: once the main file has moved, a -wal left behind would be replayed into
  // a new gallery of the same name.
  if (FileExists(from + "-wal")) SHAPEID_RETURN_IF_ERROR(RenameFile(from + "-wal", to + "-wal"));
  SHAPEID_RETURN_IF_ERROR(RemoveFileIfExists(from + "-shm"));
  SHAPEID_RETURN_IF_ERROR(RenameFile(from, to));
  SHAPEID_RETURN_IF_ERROR(SyncDirectory(damaged_dir));
  SHAPEID_RETURN_IF_ERROR(SyncDirectory(galleries_dir_));
  std::lock_guard<std::mutex> lock(mu_);
  set_aside_.push_back(SetAside{name, to, std::string(reason.message())});
  return absl::OkStatus();
}

absl::Status SqliteGalleryStore::Load(GalleryLoader& destination) {
  if (read_only() && !FileExists(galleries_dir_)) return absl::OkStatus();
  SHAPEID_ASSIGN_OR_RETURN(const std::vector<std::string> entries, ListDirectory(galleries_dir_));
  // Finish what a crash interrupted: a deletion past its durable point, or a gallery that
  // was still being written (never acknowledged). Read-only, they are only skipped. Best
  // effort: such a file is never loaded, so a disk that refuses to remove it (full,
  // read-only, failing) must not stop the galleries from being served; the next start tries
  // again.
  bool cleaned = false;
  for (const std::string& entry : entries) {
    if (!read_only() && ((absl::StartsWith(entry, ".") && (absl::StrContains(entry, ".deleted") ||
                                                           absl::StrContains(entry, ".tmp"))) ||
                         absl::EndsWith(entry, absl::StrCat(kHeadSuffix, ".tmp")))) {
      cleaned |= RemoveFileIfExists(absl::StrCat(galleries_dir_, "/", entry)).ok();
    }
  }
  if (cleaned) (void)SyncDirectory(galleries_dir_);

  CheckedLoader loader(destination);
  for (const std::string& entry : entries) {
    if (absl::StartsWith(entry, ".") || !absl::EndsWith(entry, kGallerySuffix)) continue;
    const std::string name = entry.substr(0, entry.size() - kGallerySuffix.size());
    std::shared_ptr<OpenGallery> open;
    absl::Status unwritable;
    absl::StatusOr<GalleryMetadata> loaded = LoadFile(name, loader, &open, &unwritable);
    if (!loader.error().ok()) return loader.error();
    if (!loaded.ok()) {
      if (!IsProvenDamage(loaded.status()) || !options_.set_aside_damaged || read_only()) {
        return absl::Status(loaded.status().code(), absl::StrCat("cannot load gallery '", name,
                                                                 "': ", loaded.status().message()));
      }
      open.reset();  // close before moving the file
      if (absl::Status moved = SetAsideFile(name, loaded.status()); !moved.ok()) {
        return absl::Status(moved.code(),
                            absl::StrCat("cannot set gallery '", name, "' aside (",
                                         loaded.status().message(), "): ", moved.message()));
      }
      continue;
    }
    {
      std::lock_guard<std::mutex> lock(mu_);
      open_[name] = std::move(open);
      if (!unwritable.ok() && !read_only()) read_only_galleries_[name] = unwritable;
    }
    // Derived state: a head that cannot be read is left out, and the gallery fits it again.
    if (FileExists(HeadPath(name))) {
      if (absl::StatusOr<std::string> head = ReadFileContents(HeadPath(name)); head.ok()) {
        SHAPEID_RETURN_IF_ERROR(destination.Head(*head));
      }
    }
  }
  return absl::OkStatus();
}

}  // namespace shapeid
