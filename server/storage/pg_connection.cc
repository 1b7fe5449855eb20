#include "server/storage/pg_connection.h"

#include <libpq-fe.h>

#include <cstdlib>
#include <cstring>
#include <utility>

#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "absl/strings/strip.h"

namespace shapeid {
namespace {

// libpq's messages end with a newline, sometimes several lines; one line reads better in a
// gRPC status.
std::string OneLine(const char* message) {
  std::string line = message != nullptr ? message : "";
  for (char& c : line) {
    if (c == '\n') c = ' ';
  }
  return std::string(absl::StripTrailingAsciiWhitespace(line));
}

}  // namespace

PgParams& PgParams::Text(std::string value) {
  lengths_.push_back(static_cast<int>(value.size()));
  values_.push_back(std::move(value));
  formats_.push_back(0);
  return *this;
}

PgParams& PgParams::Int(int64_t value) { return Text(absl::StrCat(value)); }

PgParams& PgParams::Bytes(absl::Span<const uint8_t> value) {
  values_.emplace_back(reinterpret_cast<const char*>(value.data()), value.size());
  lengths_.push_back(static_cast<int>(value.size()));
  formats_.push_back(1);
  return *this;
}

PgParams& PgParams::IntArray(absl::Span<const int64_t> values) {
  return Text(absl::StrCat("{", absl::StrJoin(values, ","), "}"));
}

PgResult::PgResult(pg_result* result) : result_(result) {}
PgResult::PgResult(PgResult&& other) noexcept : result_(std::exchange(other.result_, nullptr)) {}
PgResult& PgResult::operator=(PgResult&& other) noexcept {
  if (this != &other) {
    if (result_ != nullptr) PQclear(result_);
    result_ = std::exchange(other.result_, nullptr);
  }
  return *this;
}
PgResult::~PgResult() {
  if (result_ != nullptr) PQclear(result_);
}

int PgResult::rows() const { return result_ == nullptr ? 0 : PQntuples(result_); }

bool PgResult::IsNull(int row, int column) const { return PQgetisnull(result_, row, column) != 0; }

absl::string_view PgResult::Value(int row, int column) const {
  return absl::string_view(PQgetvalue(result_, row, column),
                           static_cast<size_t>(PQgetlength(result_, row, column)));
}

int64_t PgResult::Int(int row, int column) const {
  if (IsNull(row, column)) return 0;
  return std::strtoll(PQgetvalue(result_, row, column), nullptr, 10);
}

int64_t PgResult::BinaryInt(int row, int column) const {
  const absl::string_view bytes = Value(row, column);
  uint64_t value = 0;
  for (size_t i = 0; i < bytes.size() && i < 8; ++i) {
    value = (value << 8) | static_cast<uint8_t>(bytes[i]);
  }
  return static_cast<int64_t>(value);
}

absl::StatusOr<std::unique_ptr<PgConnection>> PgConnection::Connect(
    const std::string& conninfo, const std::vector<std::pair<std::string, std::string>>& defaults) {
  // Keywords are processed in order and the last value wins; "dbname" first seen with
  // expand_dbname is expanded as a whole connection string, so conninfo goes last.
  std::vector<const char*> keywords;
  std::vector<const char*> values;
  for (const auto& [key, value] : defaults) {
    keywords.push_back(key.c_str());
    values.push_back(value.c_str());
  }
  keywords.push_back("dbname");
  values.push_back(conninfo.c_str());
  keywords.push_back(nullptr);
  values.push_back(nullptr);
  pg_conn* conn = PQconnectdbParams(keywords.data(), values.data(), /*expand_dbname=*/1);
  if (conn == nullptr) return absl::ResourceExhaustedError("libpq: out of memory");
  if (PQstatus(conn) != CONNECTION_OK) {
    // libpq's message names host and port and why, never the password.
    std::string why = OneLine(PQerrorMessage(conn));
    PQfinish(conn);
    return absl::UnavailableError(absl::StrCat("cannot connect to PostgreSQL: ", why));
  }
  // Quiet: NOTICEs ("relation already exists, skipping") would go to stderr.
  PQsetNoticeProcessor(
      conn, [](void*, const char*) {}, nullptr);
  return std::unique_ptr<PgConnection>(new PgConnection(conn));
}

PgConnection::~PgConnection() { PQfinish(conn_); }

bool PgConnection::ok() const { return PQstatus(conn_) == CONNECTION_OK; }

bool PgConnection::InFailedTransaction() const {
  return PQtransactionStatus(conn_) == PQTRANS_INERROR;
}

int PgConnection::socket() const { return PQsocket(conn_); }

absl::StatusOr<PgResult> PgConnection::Query(absl::string_view what, const std::string& sql,
                                             const PgParams& params, bool binary) {
  std::vector<const char*> values;
  values.reserve(params.values_.size());
  for (const std::string& v : params.values_) values.push_back(v.data());
  pg_result* raw = PQexecParams(conn_, sql.c_str(), params.size(), nullptr, values.data(),
                                params.lengths_.data(), params.formats_.data(), binary ? 1 : 0);
  const ExecStatusType status = raw == nullptr ? PGRES_FATAL_ERROR : PQresultStatus(raw);
  if (status == PGRES_COMMAND_OK || status == PGRES_TUPLES_OK) return PgResult(raw);

  const std::string message =
      OneLine(raw != nullptr ? PQresultErrorMessage(raw) : PQerrorMessage(conn_));
  const char* state = raw != nullptr ? PQresultErrorField(raw, PG_DIAG_SQLSTATE) : nullptr;
  const std::string sqlstate = state != nullptr ? state : "";
  if (raw != nullptr) PQclear(raw);
  const std::string text = absl::StrCat(what, ": ", message.empty() ? "no answer" : message);
  // Class 08: connection exceptions; 57P: the server is shutting down (admin or crash).
  if (!ok() || absl::StartsWith(sqlstate, "08") || absl::StartsWith(sqlstate, "57P")) {
    return absl::UnavailableError(absl::StrCat(text, " (PostgreSQL unreachable)"));
  }
  if (sqlstate == "23505") return absl::AlreadyExistsError(text);
  if (sqlstate == "40001" || sqlstate == "40P01") return absl::AbortedError(text);
  return absl::InternalError(text);
}

absl::Status PgConnection::Exec(absl::string_view what, const std::string& sql,
                                const PgParams& params) {
  return Query(what, sql, params).status();
}

absl::Status PgConnection::ExecScript(absl::string_view what, const std::string& sql) {
  pg_result* raw = PQexec(conn_, sql.c_str());
  const bool good = raw != nullptr && PQresultStatus(raw) == PGRES_COMMAND_OK;
  const std::string message =
      OneLine(raw != nullptr ? PQresultErrorMessage(raw) : PQerrorMessage(conn_));
  if (raw != nullptr) PQclear(raw);
  if (good) return absl::OkStatus();
  const std::string text = absl::StrCat(what, ": ", message);
  return ok() ? absl::InternalError(text) : absl::UnavailableError(text);
}

std::string DescribeConninfo(const std::string& conninfo) {
  char* error = nullptr;
  PQconninfoOption* options = PQconninfoParse(conninfo.c_str(), &error);
  if (options == nullptr) {
    if (error != nullptr) PQfreemem(error);
    return "(unparseable)";
  }
  std::string host, port, dbname;
  for (PQconninfoOption* o = options; o->keyword != nullptr; ++o) {
    if (o->val == nullptr) continue;
    if (std::strcmp(o->keyword, "host") == 0) host = o->val;
    if (std::strcmp(o->keyword, "port") == 0) port = o->val;
    if (std::strcmp(o->keyword, "dbname") == 0) dbname = o->val;
  }
  PQconninfoFree(options);
  if (host.empty()) host = "(PGHOST or local socket)";
  return absl::StrCat(host, port.empty() ? "" : ":", port, dbname.empty() ? "" : "/", dbname);
}

absl::StatusOr<std::vector<std::string>> PgConnection::TakeNotifications() {
  if (PQconsumeInput(conn_) == 0 || !ok()) {
    return absl::UnavailableError(
        absl::StrCat("PostgreSQL connection lost: ", OneLine(PQerrorMessage(conn_))));
  }
  std::vector<std::string> channels;
  while (PGnotify* notify = PQnotifies(conn_)) {
    channels.emplace_back(notify->relname);
    PQfreemem(notify);
  }
  return channels;
}

absl::StatusOr<std::unique_ptr<PgConnection>> ConnectBounded(const std::string& conninfo) {
  std::vector<std::pair<std::string, std::string>> defaults = {
      {"connect_timeout", "3"},     {"keepalives", "1"},       {"keepalives_idle", "5"},
      {"keepalives_interval", "2"}, {"keepalives_count", "2"}, {"tcp_user_timeout", "5000"}};
  // A keyword here would hide PGAPPNAME (libpq reads the environment only for what is unset).
  if (std::getenv("PGAPPNAME") == nullptr)
    defaults.push_back({"application_name", "shapeid-server"});
  return PgConnection::Connect(conninfo, defaults);
}

absl::StatusOr<std::unique_ptr<PgConnection>> PgConnectionPool::Lease() {
  std::unique_lock<std::mutex> lock(mu_);
  cv_.wait(lock,
           [&]() ABSL_NO_THREAD_SAFETY_ANALYSIS { return !idle_.empty() || leased_ < size_; });
  ++leased_;
  if (!idle_.empty()) {
    std::unique_ptr<PgConnection> connection = std::move(idle_.back());
    idle_.pop_back();
    if (connection->ok()) return connection;
  }
  lock.unlock();
  absl::StatusOr<std::unique_ptr<PgConnection>> fresh = ConnectBounded(conninfo_);
  if (!fresh.ok()) Return(nullptr);
  return fresh;
}

void PgConnectionPool::Return(std::unique_ptr<PgConnection> connection) {
  std::lock_guard<std::mutex> lock(mu_);
  --leased_;
  if (connection != nullptr && connection->ok()) idle_.push_back(std::move(connection));
  cv_.notify_one();
}

void PgConnectionPool::DropIdle() {
  std::lock_guard<std::mutex> lock(mu_);
  idle_.clear();
}

}  // namespace shapeid
