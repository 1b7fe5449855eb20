#ifndef SHAPEID_SERVER_STORAGE_PG_CONNECTION_H_
#define SHAPEID_SERVER_STORAGE_PG_CONNECTION_H_

// A thin RAII layer over libpq (Debian's libpq-dev): one connection, statements with
// parameters, results, and libpq's errors as absl::Status. Only what the PostgreSQL gallery
// store needs; not thread-safe (one connection per thread at a time, as libpq requires).

#include <condition_variable>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <utility>
#include <vector>

#include "absl/base/thread_annotations.h"
#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "absl/types/span.h"

struct pg_conn;
struct pg_result;

namespace shapeid {

// Parameters of one statement ($1, $2...). Text values are sent as text (PostgreSQL parses
// them into the column's type); Bytes as binary, for BYTEA without escaping.
class PgParams {
 public:
  PgParams& Text(std::string value);
  PgParams& Int(int64_t value);
  PgParams& Bytes(absl::Span<const uint8_t> value);
  // A BIGINT[] in text form ("{1,2,3}").
  PgParams& IntArray(absl::Span<const int64_t> values);

  int size() const { return static_cast<int>(values_.size()); }

 private:
  friend class PgConnection;
  std::vector<std::string> values_;
  std::vector<int> lengths_;
  std::vector<int> formats_;  // 0 text, 1 binary
};

// Rows of a statement's answer, every column in text form except BYTEA columns asked for
// with PgConnection::Query(..., binary=true), where every column is binary.
class PgResult {
 public:
  PgResult() = default;
  explicit PgResult(pg_result* result);
  PgResult(PgResult&&) noexcept;
  PgResult& operator=(PgResult&&) noexcept;
  ~PgResult();

  int rows() const;
  bool IsNull(int row, int column) const;
  // The raw bytes of a value (text or binary).
  absl::string_view Value(int row, int column) const;
  // A text-format integer column; 0 for NULL.
  int64_t Int(int row, int column) const;
  // A binary-format BIGINT (network byte order).
  int64_t BinaryInt(int row, int column) const;

 private:
  pg_result* result_ = nullptr;
};

class PgConnection {
 public:
  // Connects with `conninfo` (a libpq URI "postgres://..." or "key=value" string; libpq's
  // PG* environment variables fill what it leaves out), over `defaults` (keyword, value),
  // which conninfo's own settings override. Unavailable with libpq's reason (never the
  // password) when the server cannot be reached or refuses.
  static absl::StatusOr<std::unique_ptr<PgConnection>> Connect(
      const std::string& conninfo,
      const std::vector<std::pair<std::string, std::string>>& defaults = {});
  ~PgConnection();

  PgConnection(const PgConnection&) = delete;
  PgConnection& operator=(const PgConnection&) = delete;

  // Runs one statement. Errors: Unavailable when the connection is gone (ok() turns false),
  // AlreadyExists for a unique violation, Aborted for a serialization failure or deadlock,
  // Internal otherwise; the message is PostgreSQL's, prefixed with `what`.
  absl::StatusOr<PgResult> Query(absl::string_view what, const std::string& sql,
                                 const PgParams& params = PgParams(), bool binary = false);
  // Query for statements without an answer.
  absl::Status Exec(absl::string_view what, const std::string& sql,
                    const PgParams& params = PgParams());
  // Several statements without parameters (a schema), as one implicit transaction.
  absl::Status ExecScript(absl::string_view what, const std::string& sql);

  // False once the connection is broken; the owner drops it and connects afresh.
  bool ok() const;
  // A statement failed inside the open transaction: until ROLLBACK, every statement fails.
  bool InFailedTransaction() const;
  // The socket, for waiting on notifications.
  int socket() const;
  // Reads what arrived on the socket and returns the notifications' channel names (empty if
  // none). Unavailable if the connection broke.
  absl::StatusOr<std::vector<std::string>> TakeNotifications();

 private:
  explicit PgConnection(pg_conn* conn) : conn_(conn) {}
  pg_conn* conn_;
};

// PgConnection::Connect with shapeid's bounds on how long a dead or silent server can hold a
// call (connect_timeout, keepalives, tcp_user_timeout) and application_name shapeid-server
// unless PGAPPNAME is set; `conninfo`'s own settings win.
absl::StatusOr<std::unique_ptr<PgConnection>> ConnectBounded(const std::string& conninfo);

// At most `size` connections (ConnectBounded) leased to calls on any threads; Lease waits
// while all are out. A broken connection is dropped and replaced on the next lease.
// Thread-safe.
class PgConnectionPool {
 public:
  PgConnectionPool(std::string conninfo, int size) : conninfo_(std::move(conninfo)), size_(size) {}

  // A connection, idle or new; Unavailable if a new one cannot connect. Give it back with
  // Return (null if it was lost).
  absl::StatusOr<std::unique_ptr<PgConnection>> Lease();
  void Return(std::unique_ptr<PgConnection> connection);
  // Forgets idle connections: after PostgreSQL restarted they are all dead, though libpq
  // cannot tell until each is used.
  void DropIdle();

 private:
  const std::string conninfo_;
  const int size_;
  std::mutex mu_;
  std::condition_variable cv_;
  std::vector<std::unique_ptr<PgConnection>> idle_ ABSL_GUARDED_BY(mu_);
  int leased_ ABSL_GUARDED_BY(mu_) = 0;
};

// "HOST:PORT/DATABASE" of a connection string, for logs: never the user or the password.
// Empty parts are left out; "(unparseable)" if libpq cannot read it.
std::string DescribeConninfo(const std::string& conninfo);

// Stored ids are BIGINT: ids at or above 2^63 (the assigned ones) are kept as their two's
// complement, which round-trips exactly.
inline int64_t AsPgId(uint64_t id) { return static_cast<int64_t>(id); }
inline uint64_t FromPgId(int64_t id) { return static_cast<uint64_t>(id); }

}  // namespace shapeid

#endif  // SHAPEID_SERVER_STORAGE_PG_CONNECTION_H_
