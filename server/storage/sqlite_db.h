#ifndef SHAPEID_SERVER_STORAGE_SQLITE_DB_H_
#define SHAPEID_SERVER_STORAGE_SQLITE_DB_H_

#include <sqlite3.h>

#include <cstdint>
#include <memory>
#include <string>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "absl/types/span.h"

namespace shapeid {

// A thin RAII layer over the SQLite C API: one connection, prepared statements, and one
// mapping from SQLite result codes to absl::Status, so that the store reads like its logic.
// Not thread-safe: the caller serializes use of a connection and its statements.

// The status for SQLite result `code` on `db`, its message prefixed by `context`:
//  - SQLITE_FULL, and any I/O error whose errno is ENOSPC or EDQUOT (a -shm that cannot grow):
//    ResourceExhausted ("disk full");
//  - SQLITE_CORRUPT, SQLITE_NOTADB: DataLoss;
//  - SQLITE_READONLY*, SQLITE_CANTOPEN, SQLITE_IOERR*, SQLITE_PERM: Unavailable, with errno;
//  - anything else: Internal.
// So DataLoss means damage SQLite proved, never a disk that could not be read or written.
absl::Status SqliteStatus(sqlite3* db, int code, absl::string_view context);

class SqliteStatement {
 public:
  SqliteStatement() = default;
  SqliteStatement(SqliteStatement&& other) noexcept;
  SqliteStatement& operator=(SqliteStatement&& other) noexcept;
  ~SqliteStatement();

  // Binding (1-based like SQLite). Text and blobs are copied (SQLITE_TRANSIENT) so the caller
  // may free them before Step.
  void BindInt64(int index, int64_t value);
  void BindDouble(int index, double value);
  void BindText(int index, absl::string_view value);
  void BindBlob(int index, absl::Span<const uint8_t> value);
  void BindNull(int index);

  // True while a row is available, false when done; errors through SqliteStatus.
  absl::StatusOr<bool> Step();
  // Step, expecting no row (INSERT, UPDATE, DELETE, PRAGMA setters).
  absl::Status Run();
  // Ready for new bindings; keeps the compiled statement.
  void Reset();

  // Column accessors (0-based like SQLite) for the current row.
  int64_t ColumnInt64(int column) const;
  double ColumnDouble(int column) const;
  std::string ColumnText(int column) const;
  absl::Span<const uint8_t> ColumnBlob(int column) const;  // valid until the next Step
  bool ColumnIsNull(int column) const;

 private:
  friend class SqliteDb;
  SqliteStatement(sqlite3* db, sqlite3_stmt* stmt, std::string sql)
      : db_(db), stmt_(stmt), sql_(std::move(sql)) {}

  sqlite3* db_ = nullptr;
  sqlite3_stmt* stmt_ = nullptr;
  std::string sql_;  // for error messages
};

class SqliteDb {
 public:
  enum class Mode {
    kReadWrite,  // an existing database
    kCreate,     // read-write, created if missing
    // Read-only and "immutable": SQLite reads the main file only and takes no locks. The
    // caller must make sure no -wal file holds changes (they would be ignored).
    kReadOnlyImmutable,
    // Read-only, the -wal read into private memory (locking_mode=EXCLUSIVE before the first
    // access, over a VFS without file locks, "unix-none" by default): committed transactions
    // still in the -wal are seen, yet no -shm is created and nothing is written, not even a
    // checkpoint at close. How a WAL database is read on a full disk or a read-only volume,
    // where SQLite's shared-memory index cannot be created. The caller makes sure that no
    // other process writes the file meanwhile (no locks guard it) and that the -wal exists
    // (SQLite would create it).
    kReadOnlyPrivateWal,
  };
  // Opens `path` through the registered SQLite VFS `vfs` (tests inject disk faults through
  // one; for kReadOnlyPrivateWal it must take no locks); empty: SQLite's default ("unix-none"
  // for kReadOnlyPrivateWal). Extended result codes are on, so errors keep their detail
  // (SQLITE_IOERR_FSYNC, SQLITE_READONLY_DBMOVED...).
  static absl::StatusOr<std::unique_ptr<SqliteDb>> Open(const std::string& path, Mode mode,
                                                        const std::string& vfs = "");

  SqliteDb(const SqliteDb&) = delete;
  SqliteDb& operator=(const SqliteDb&) = delete;
  // Closes; a WAL-mode database checkpoints and removes its -wal file when the last
  // connection closes cleanly.
  ~SqliteDb();

  // Runs one or more statements that return no rows.
  absl::Status Exec(absl::string_view sql);
  absl::StatusOr<SqliteStatement> Prepare(absl::string_view sql);
  // The single integer a query such as "PRAGMA user_version" returns.
  absl::StatusOr<int64_t> QueryInt(absl::string_view sql);
  // The first column of every row of a query, as text ("PRAGMA quick_check").
  absl::StatusOr<std::string> QueryText(absl::string_view sql);

  // Rolls back when a transaction is open (after a failed statement or COMMIT); a no-op
  // otherwise.
  void RollbackIfOpen();

  // Closes now and reports the result (the destructor cannot): callers that move or remove the
  // file afterwards must know the WAL was checkpointed.
  absl::Status Close();

  // True when SQLite opened the file read-only although asked for read-write: the file or
  // its volume cannot be written (unix falls back to read-only then).
  bool read_only() const { return sqlite3_db_readonly(db_, "main") == 1; }

  sqlite3* raw() const { return db_; }
  const std::string& path() const { return path_; }

 private:
  SqliteDb(sqlite3* db, std::string path) : db_(db), path_(std::move(path)) {}

  sqlite3* db_;
  std::string path_;
};

}  // namespace shapeid

#endif  // SHAPEID_SERVER_STORAGE_SQLITE_DB_H_
