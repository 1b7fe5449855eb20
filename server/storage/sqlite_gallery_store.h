#ifndef SHAPEID_SERVER_STORAGE_SQLITE_GALLERY_STORE_H_
#define SHAPEID_SERVER_STORAGE_SQLITE_GALLERY_STORE_H_

#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "absl/base/thread_annotations.h"
#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "core/gallery/gallery_store.h"
#include "server/storage/sqlite_db.h"

namespace shapeid {

struct SqliteGalleryStoreOptions {
  // Where galleries live; created (with parents) if missing. Layout:
  //   LOCK                       held (flock) by the one server using the directory
  //   galleries/NAME.gallery     one SQLite database per gallery (+ -wal, -shm while open)
  //   damaged/NAME.TIME.gallery  galleries set aside by set_aside_damaged
  std::string data_dir;
  // What start-up does with a gallery file whose damage is proven: SQLite finds it corrupt or
  // not a database, its integrity check or one of our CRC-32s fails, it is not a shapeid
  // gallery, or its format is newer than this release reads. false, the default: LoadAll
  // fails with DataLoss (or FailedPrecondition for a newer format) naming the file and what
  // is wrong, and the server refuses to start; nothing is touched. true: the file is moved
  // into damaged/ with its -wal, the reason is reported by set_aside(), and the other
  // galleries load. A file that could not be opened or read because of the disk (full,
  // read-only, I/O errors) is not proven damaged and is never moved: see LoadAll.
  bool set_aside_damaged = false;
  // Tests only: the registered SQLite VFS to open gallery files with, so that a test can
  // inject disk faults (testing/fault_vfs.h); galleries read without locks (see LoadAll) go
  // through NAME-none. Empty: SQLite's own, "unix" and "unix-none".
  std::string testing_vfs = {};
};

// The embedded gallery store: one SQLite database per gallery, in WAL mode with
// synchronous=FULL, so every write below is committed and fsynced before it returns OK. One
// file per gallery keeps damage to one gallery from taking the others down and makes
// deleting a gallery a rename.
//
// Durability of each call (GalleryStore's contract):
//  - SaveGallery writes the whole new gallery into a temporary file, syncs it, renames it into
//    place and syncs the directory: the gallery exists completely or not at all.
//  - AppendSamples / RemoveSamples are one SQLite transaction each.
//  - DeleteGallery renames the file out of the way and syncs the directory (the durable
//    point), then unlinks it; start-up finishes any interrupted deletion.
// Every stored row carries a CRC-32 (as in the export format), checked at load together with
// SQLite's quick_check, so bit rot is reported rather than served.
//
// Errors: ResourceExhausted when the disk is full; Unavailable for I/O errors and read-only
// or vanished files; DataLoss only for damage (never for a disk that failed); each message
// names the gallery and the file. After a failed fsync the gallery's writes fail until
// restart: the kernel may have dropped the unsynced pages, so only a reload can tell what is
// on disk.
//
// A data directory on a read-only file system (a volume mounted read-only, say for a
// classify-only replica) opens read-only: galleries load and serve (changes still in a -wal
// included), and every write fails Unavailable saying why. Several read-only servers may
// share such a directory; a writable server excludes all others. A single gallery that cannot
// be opened for writing is served read-only the same way: see LoadAll.
//
// Thread-safe. Calls for different galleries run concurrently.
class SqliteGalleryStore final : public GalleryStore {
 public:
  // Galleries' on-disk format; stored as PRAGMA user_version. Bump on any schema change and
  // teach LoadAll to read the old one. 2: the gallery row's `augment` column, and
  // samples with several views. 3: the samples' `provenance` column. Older files load (format
  // 1 as galleries without augmentation) and keep their format as they are appended to, until
  // a sample with provenance arrives: then the column is added and the file is format 3.
  static constexpr int kFormatVersion = 3;

  // Creates the directories and takes the directory's lock. Unavailable naming the path if a
  // directory cannot be created or written; FailedPrecondition if another process holds the
  // lock (two servers on one directory would corrupt each other's view).
  static absl::StatusOr<std::unique_ptr<SqliteGalleryStore>> Open(
      SqliteGalleryStoreOptions options);

  ~SqliteGalleryStore() override;

  absl::Status SaveGallery(const StoredGallery& gallery) override;
  absl::Status DeleteGallery(absl::string_view name) override;
  // `version` is not kept: versions restart at 0 when a server loads its own galleries.
  // On a gallery served read-only (read_only_galleries()) they first reopen its file for
  // writing, so that space freed on a full disk heals it without a restart; while that fails
  // they fail with its code (ResourceExhausted for a full disk, Unavailable otherwise), "cannot
  // ... gallery 'NAME': it is served read-only ...: <why>". DeleteGallery works on such a
  // gallery: it writes nothing into the file, and it is how to free space.
  absl::Status AppendSamples(absl::string_view name, absl::Span<const StoredSample> batch,
                             absl::Time updated, uint64_t version) override;
  absl::Status RemoveSamples(absl::string_view name, absl::Span<const uint64_t> ids,
                             absl::Time updated, uint64_t version) override;
  // Verifies and reads every gallery file, sorted by name; keeps each open for later writes.
  // Call once, before any write.
  //
  // A disk condition is not damage. A gallery that cannot be opened for writing (a full disk,
  // a read-only file, an I/O error) but can still be read completely, committed changes in
  // its -wal included, loads read-only: it is listed by read_only_galleries() and its writes
  // fail saying why (see AppendSamples). One that cannot even be read fails LoadAll with the
  // disk's code (ResourceExhausted, Unavailable), a message saying that it is not damage and
  // what to do, and is never set aside. Proven damage fails LoadAll with DataLoss, or is set
  // aside (SqliteGalleryStoreOptions::set_aside_damaged).
  //
  // Load reads each file a sample at a time into the loader (a gallery set aside partway is
  // begun and never ended); LoadAll collects the same whole.
  absl::Status Load(GalleryLoader& loader) override;
  // The head goes to NAME.head beside the gallery's file, written atomically (a temporary
  // file, fsync, rename, fsync of the directory); Load hands it over after the gallery.
  absl::Status SaveHead(absl::string_view name, absl::string_view bytes) override;
  absl::StatusOr<std::vector<StoredGallery>> LoadAll() override { return CollectGalleries(*this); }

  struct SetAside {
    std::string name;      // gallery
    std::string moved_to;  // path under damaged/
    std::string reason;    // the error that made it unloadable
  };
  // What the last LoadAll moved aside (set_aside_damaged only).
  std::vector<SetAside> set_aside() const;

  struct ReadOnlyGallery {
    std::string name;     // gallery
    absl::Status reason;  // why it cannot be written: ResourceExhausted (disk full), Unavailable
  };
  // The galleries served read-only because LoadAll could read but not write them, sorted by
  // name; one leaves the list when a later write reopens it (the disk has room again). Empty
  // when the whole data directory is read-only: read_only() covers every gallery then.
  std::vector<ReadOnlyGallery> read_only_galleries() const;

  const std::string& data_dir() const { return options_.data_dir; }
  // True when the data directory's file system is read-only (see the class comment).
  bool read_only() const { return !read_only_.empty(); }
  // The database file of gallery `name` (which may not exist).
  std::string GalleryPath(absl::string_view name) const;
  // The file of its trained head (which may not exist).
  std::string HeadPath(absl::string_view name) const;

 private:
  struct OpenGallery;
  class CheckedLoader;

  SqliteGalleryStore(SqliteGalleryStoreOptions options, int lock_fd, std::string read_only);

  // Unavailable when read-only: "cannot <what>: <why>".
  absl::Status CheckWritable(absl::string_view what) const;

  absl::StatusOr<std::shared_ptr<OpenGallery>> Find(absl::string_view name) const;
  // The one write path of AppendSamples and RemoveSamples: `change` and the gallery row's
  // update time in one transaction; errors say "cannot <what> gallery 'NAME'".
  absl::Status ChangeSamples(absl::string_view name, absl::string_view what, absl::Time updated,
                             const std::function<absl::Status(OpenGallery&)>& change);
  // Makes a file of a format before 3 able to hold provenance (see kFormatVersion).
  // Errors say "cannot <what> gallery 'NAME'", as ChangeSamples'.
  absl::Status AddProvenanceColumn(absl::string_view name, absl::string_view what);
  // Verifies and reads one gallery file into `loader`, for writing if it can (see LoadAll);
  // `*unwritable` says why not. The loader's own error is returned as it is.
  absl::StatusOr<GalleryMetadata> LoadFile(const std::string& name, CheckedLoader& loader,
                                           std::shared_ptr<OpenGallery>* out,
                                           absl::Status* unwritable);
  // Reads a gallery into `loader` without writing anything, not even a -shm.
  absl::StatusOr<GalleryMetadata> ReadReadOnly(const std::string& name, GalleryLoader& loader);
  // Opens a gallery served read-only for writing, with g.mu held; "cannot <what> gallery
  // 'NAME': ..." if it still cannot be.
  absl::Status Reopen(absl::string_view name, absl::string_view what, OpenGallery& g);
  absl::Status SetAsideFile(const std::string& name, const absl::Status& reason);

  const SqliteGalleryStoreOptions options_;
  const std::string galleries_dir_;
  const int lock_fd_;            // -1 when a read-only directory has no LOCK file
  const std::string read_only_;  // empty, or why the directory cannot be written

  mutable std::mutex mu_;
  std::map<std::string, std::shared_ptr<OpenGallery>, std::less<>> open_ ABSL_GUARDED_BY(mu_);
  std::vector<SetAside> set_aside_ ABSL_GUARDED_BY(mu_);
  std::map<std::string, absl::Status, std::less<>> read_only_galleries_ ABSL_GUARDED_BY(mu_);
};

}  // namespace shapeid

#endif  // SHAPEID_SERVER_STORAGE_SQLITE_GALLERY_STORE_H_
