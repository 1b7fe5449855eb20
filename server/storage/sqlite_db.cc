#include "server/storage/sqlite_db.h"

#include <cerrno>
#include <cstring>
#include <utility>

#include "absl/strings/str_cat.h"
#include "core/status_macros.h"

namespace shapeid {

absl::Status SqliteStatus(sqlite3* db, int code, absl::string_view context) {
  const int primary = code & 0xff;
  std::string detail = db != nullptr ? sqlite3_errmsg(db) : sqlite3_errstr(code);
  const int os_errno = db != nullptr ? sqlite3_system_errno(db) : 0;
  if (os_errno != 0 &&
      (primary == SQLITE_IOERR || primary == SQLITE_CANTOPEN || primary == SQLITE_READONLY ||
       primary == SQLITE_FULL || primary == SQLITE_PERM)) {
    absl::StrAppend(&detail, " (", std::strerror(os_errno), ")");
  }
  const std::string message = absl::StrCat(context, ": ", detail);
  // A -wal or -shm that cannot be created or grown on a full disk reports an I/O error.
  const bool no_space = os_errno == ENOSPC || os_errno == EDQUOT;
  if (primary == SQLITE_FULL ||
      (no_space && (primary == SQLITE_IOERR || primary == SQLITE_CANTOPEN))) {
    return absl::ResourceExhaustedError(
        absl::StrCat(message, "; the disk is full, nothing was written: free space and retry"));
  }
  switch (primary) {
    case SQLITE_CORRUPT:
    case SQLITE_NOTADB:
      return absl::DataLossError(message);
    case SQLITE_READONLY:
    case SQLITE_CANTOPEN:
    case SQLITE_IOERR:
    case SQLITE_PERM:
      return absl::UnavailableError(message);
    default:
      return absl::InternalError(message);
  }
}

// ---------------------------------------------------------------------------------------
// SqliteStatement

SqliteStatement::SqliteStatement(SqliteStatement&& other) noexcept
    : db_(std::exchange(other.db_, nullptr)),
      stmt_(std::exchange(other.stmt_, nullptr)),
      sql_(std::move(other.sql_)) {}

SqliteStatement& SqliteStatement::operator=(SqliteStatement&& other) noexcept {
  if (this != &other) {
    sqlite3_finalize(stmt_);
    db_ = std::exchange(other.db_, nullptr);
    stmt_ = std::exchange(other.stmt_, nullptr);
    sql_ = std::move(other.sql_);
  }
  return *this;
}

SqliteStatement::~SqliteStatement() { sqlite3_finalize(stmt_); }

// Bind errors (index out of range, out of memory) are programming errors or surface again at
// Step as SQLITE_MISUSE/NOMEM, so they are not reported twice.
void SqliteStatement::BindInt64(int index, int64_t value) {
  sqlite3_bind_int64(stmt_, index, value);
}
void SqliteStatement::BindDouble(int index, double value) {
  sqlite3_bind_double(stmt_, index, value);
}
void SqliteStatement::BindText(int index, absl::string_view value) {
  sqlite3_bind_text64(stmt_, index, value.data(), value.size(), SQLITE_TRANSIENT, SQLITE_UTF8);
}
void SqliteStatement::BindBlob(int index, absl::Span<const uint8_t> value) {
  // A zero-length blob must stay a blob, not NULL: SQLite binds NULL for a null pointer.
  static const uint8_t kEmpty = 0;
  sqlite3_bind_blob64(stmt_, index, value.empty() ? &kEmpty : value.data(), value.size(),
                      SQLITE_TRANSIENT);
}

void SqliteStatement::BindNull(int index) { sqlite3_bind_null(stmt_, index); }

absl::StatusOr<bool> SqliteStatement::Step() {
  const int rc = sqlite3_step(stmt_);
  if (rc == SQLITE_ROW) return true;
  if (rc == SQLITE_DONE) return false;
  return SqliteStatus(db_, rc, sql_);
}

absl::Status SqliteStatement::Run() {
  absl::StatusOr<bool> row = Step();
  Reset();
  if (!row.ok()) return row.status();
  return absl::OkStatus();
}

void SqliteStatement::Reset() {
  sqlite3_reset(stmt_);
  sqlite3_clear_bindings(stmt_);
}

int64_t SqliteStatement::ColumnInt64(int column) const {
  return sqlite3_column_int64(stmt_, column);
}
double SqliteStatement::ColumnDouble(int column) const {
  return sqlite3_column_double(stmt_, column);
}
std::string SqliteStatement::ColumnText(int column) const {
  const unsigned char* text = sqlite3_column_text(stmt_, column);
  const int bytes = sqlite3_column_bytes(stmt_, column);
  return text == nullptr
             ? std::string()
             : std::string(reinterpret_cast<const char*>(text), static_cast<size_t>(bytes));
}
absl::Span<const uint8_t> SqliteStatement::ColumnBlob(int column) const {
  const void* blob = sqlite3_column_blob(stmt_, column);
  const int bytes = sqlite3_column_bytes(stmt_, column);
  return absl::Span<const uint8_t>(static_cast<const uint8_t*>(blob), static_cast<size_t>(bytes));
}
bool SqliteStatement::ColumnIsNull(int column) const {
  return sqlite3_column_type(stmt_, column) == SQLITE_NULL;
}

// ---------------------------------------------------------------------------------------
// SqliteDb

absl::StatusOr<std::unique_ptr<SqliteDb>> SqliteDb::Open(const std::string& path, Mode mode,
                                                         const std::string& vfs) {
  sqlite3* db = nullptr;
  int flags = SQLITE_OPEN_NOMUTEX;  // the caller serializes use of a connection
  std::string name = path;
  switch (mode) {
    case Mode::kReadWrite:
      flags |= SQLITE_OPEN_READWRITE;
      break;
    case Mode::kCreate:
      flags |= SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE;
      break;
    case Mode::kReadOnlyImmutable: {
      flags |= SQLITE_OPEN_READONLY | SQLITE_OPEN_URI;
      // URI syntax: '%', '?' and '#' would be special; gallery names cannot contain them,
      // but a data directory might.
      std::string escaped;
      for (char c : path) {
        if (c == '%' || c == '?' || c == '#') {
          absl::StrAppend(&escaped, "%", absl::Hex(static_cast<unsigned char>(c), absl::kZeroPad2));
        } else {
          escaped += c;
        }
      }
      name = absl::StrCat("file:", escaped, "?immutable=1");
      break;
    }
    case Mode::kReadOnlyPrivateWal:
      flags |= SQLITE_OPEN_READONLY;
      break;
  }
  const std::string vfs_name = !vfs.empty()                        ? vfs
                               : mode == Mode::kReadOnlyPrivateWal ? "unix-none"
                                                                   : "";
  const int rc =
      sqlite3_open_v2(name.c_str(), &db, flags, vfs_name.empty() ? nullptr : vfs_name.c_str());
  if (rc != SQLITE_OK) {
    absl::Status status = SqliteStatus(db, rc, absl::StrCat("cannot open ", path));
    sqlite3_close(db);  // sqlite3_open_v2 allocates a handle even on failure
    return status;
  }
  sqlite3_extended_result_codes(db, 1);
  auto opened = std::unique_ptr<SqliteDb>(new SqliteDb(db, path));
  if (mode == Mode::kReadOnlyPrivateWal) {
    // Both before the first access: exclusive locking mode keeps the WAL index in the heap
    // (no -shm), and a read-only connection must not try to checkpoint when it closes.
    sqlite3_db_config(db, SQLITE_DBCONFIG_NO_CKPT_ON_CLOSE, 1, nullptr);
    SHAPEID_RETURN_IF_ERROR(opened->Exec("PRAGMA locking_mode=EXCLUSIVE"));
  }
  return opened;
}

SqliteDb::~SqliteDb() { sqlite3_close_v2(db_); }

absl::Status SqliteDb::Close() {
  if (db_ == nullptr) return absl::OkStatus();
  const int rc = sqlite3_close(db_);
  if (rc != SQLITE_OK) return SqliteStatus(db_, rc, absl::StrCat("closing ", path_));
  db_ = nullptr;
  return absl::OkStatus();
}

absl::Status SqliteDb::Exec(absl::string_view sql) {
  const std::string text(sql);
  const int rc = sqlite3_exec(db_, text.c_str(), nullptr, nullptr, nullptr);
  if (rc != SQLITE_OK) return SqliteStatus(db_, rc, absl::StrCat(path_, ": ", text));
  return absl::OkStatus();
}

absl::StatusOr<SqliteStatement> SqliteDb::Prepare(absl::string_view sql) {
  sqlite3_stmt* stmt = nullptr;
  const int rc = sqlite3_prepare_v3(db_, sql.data(), static_cast<int>(sql.size()),
                                    SQLITE_PREPARE_PERSISTENT, &stmt, nullptr);
  if (rc != SQLITE_OK) return SqliteStatus(db_, rc, absl::StrCat(path_, ": ", sql));
  return SqliteStatement(db_, stmt, absl::StrCat(path_, ": ", sql));
}

absl::StatusOr<int64_t> SqliteDb::QueryInt(absl::string_view sql) {
  absl::StatusOr<SqliteStatement> stmt = Prepare(sql);
  if (!stmt.ok()) return stmt.status();
  absl::StatusOr<bool> row = stmt->Step();
  if (!row.ok()) return row.status();
  if (!*row) return absl::InternalError(absl::StrCat(path_, ": ", sql, " returned no row"));
  return stmt->ColumnInt64(0);
}

absl::StatusOr<std::string> SqliteDb::QueryText(absl::string_view sql) {
  absl::StatusOr<SqliteStatement> stmt = Prepare(sql);
  if (!stmt.ok()) return stmt.status();
  std::string text;
  while (true) {
    absl::StatusOr<bool> row = stmt->Step();
    if (!row.ok()) return row.status();
    if (!*row) break;
    if (!text.empty()) text += "; ";
    text += stmt->ColumnText(0);
  }
  return text;
}

void SqliteDb::RollbackIfOpen() {
  if (db_ != nullptr && sqlite3_get_autocommit(db_) == 0) {
    sqlite3_exec(db_, "ROLLBACK", nullptr, nullptr, nullptr);
  }
}

}  // namespace shapeid
