#ifndef SHAPEID_SERVER_STORAGE_TESTING_FAULT_VFS_H_
#define SHAPEID_SERVER_STORAGE_TESTING_FAULT_VFS_H_

// A SQLite VFS for tests that fails file operations the way a full disk, a read-only volume
// or a failing disk does, where CI (root, which ignores file modes, and no mounts) cannot
// produce the real thing. It wraps SQLite's "unix" VFS as NAME and its lock-free
// "unix-none" as NAME-none, the pair SqliteGalleryStoreOptions::testing_vfs expects. Faults
// apply to files opened through either, from the moment Set is called.
//
// Registered (never as the default) for the object's lifetime, which must outlast every
// connection using it. Thread-safe.

#include <sqlite3.h>

#include <atomic>
#include <memory>
#include <mutex>
#include <string>

namespace shapeid {

class FaultVfs {
 public:
  struct Faults {
    // A database, -wal or -shm file that does not exist yet cannot be created
    // (SQLITE_CANTOPEN).
    bool fail_create = false;
    // A write, truncate or -shm mapping that needs space its file does not have yet fails as
    // on a full disk (SQLITE_FULL; SQLITE_IOERR_SHMSIZE for the -shm, as SQLite reports it).
    bool fail_growth = false;
    // Existing files open read-only, as on a read-only volume; an existing -shm cannot be
    // initialized (SQLITE_READONLY_CANTINIT) and deleting fails (SQLITE_IOERR_DELETE).
    bool read_only = false;
    // Every read of a main database file fails with this, e.g. SQLITE_IOERR_READ.
    int read_error = SQLITE_OK;
    // Opening or mapping the -shm fails with this, e.g. SQLITE_IOERR_SHMOPEN.
    int shm_error = SQLITE_OK;
    // The errno of the failures above, as sqlite3_system_errno reports it.
    int error = 0;
    // Only files whose path contains this fail (empty: every file).
    std::string path_contains;
  };
  // fail_create and fail_growth with ENOSPC.
  static Faults DiskFull();
  // read_only and fail_create with EROFS.
  static Faults ReadOnlyVolume();

  // Registers NAME and NAME-none.
  explicit FaultVfs(std::string name);
  ~FaultVfs();
  FaultVfs(const FaultVfs&) = delete;
  FaultVfs& operator=(const FaultVfs&) = delete;

  const std::string& name() const;
  // Replaces the faults in force; Set({}) ends them.
  void Set(Faults faults);
  // Failures injected so far: a test asserts it is positive, so that it knows the fault it
  // meant to exercise really happened.
  int injected() const;

  struct State;  // what the C callbacks reach through sqlite3_vfs::pAppData

 private:
  std::unique_ptr<State> state_;
};

}  // namespace shapeid

#endif  // SHAPEID_SERVER_STORAGE_TESTING_FAULT_VFS_H_
