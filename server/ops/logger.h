#ifndef SHAPEID_SERVER_OPS_LOGGER_H_
#define SHAPEID_SERVER_OPS_LOGGER_H_

// The server's log: one line per event on stderr, as text for people or as JSON for a log
// pipeline (--log_format), filtered by a level that may change while the server runs
// (--log_level, and the SetLogLevel RPC). gRPC-free, so the store and main use it too.

#include <atomic>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <variant>

#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "absl/types/span.h"

namespace shapeid {

enum class LogLevel { kDebug = 0, kInfo = 1, kWarning = 2, kError = 3 };
enum class LogFormat { kText, kJson };

// "debug", "info", "warning", "error"; and back (InvalidArgument naming the choices).
absl::string_view LogLevelName(LogLevel level);
absl::StatusOr<LogLevel> ParseLogLevel(absl::string_view name);
absl::StatusOr<LogFormat> ParseLogFormat(absl::string_view name);

struct LoggerOptions {
  LogFormat format = LogFormat::kText;
  // Lines below it are dropped. info: a line per RPC; warning: failed RPCs and warnings.
  LogLevel level = LogLevel::kInfo;
};

// One field of a line: a key and a string, integer or real value. It keeps views: build it
// from strings that outlive the Log call (a temporary std::string in an array of fields dies
// before the line is written).
struct LogField {
  LogField(absl::string_view k, absl::string_view v) : key(k), value(v) {}
  LogField(absl::string_view k, const char* v) : key(k), value(absl::string_view(v)) {}
  LogField(absl::string_view k, const std::string& v) : key(k), value(absl::string_view(v)) {}
  LogField(absl::string_view k, int64_t v) : key(k), value(v) {}
  LogField(absl::string_view k, int v) : key(k), value(int64_t{v}) {}
  LogField(absl::string_view k, double v) : key(k), value(v) {}
  absl::string_view key;
  std::variant<absl::string_view, int64_t, double> value;
};

// Thread-safe. Each line is formatted whole and handed to the sink in one piece (the default
// sink is one write(2) to stderr), so lines from many threads never interleave.
//
// Text: "shapeid-server: [LEVEL: ]message key=value key="quoted value"..." (the level only
// when not info: the start-up lines read as before). JSON: {"time":"2026-11-23T05:40:00.123456Z",
// "level":"info","msg":"message","key":value,...}, strings escaped (core/json.h), so every line
// parses whatever a client put in a gallery name.
class Logger {
 public:
  using Sink = std::function<void(absl::string_view line)>;  // the line ends with '\n'

  explicit Logger(LoggerOptions options = {}, Sink sink = nullptr);

  bool Enabled(LogLevel level) const { return level >= level_.load(std::memory_order_relaxed); }
  void Log(LogLevel level, absl::string_view message, absl::Span<const LogField> fields = {}) const;
  void Info(absl::string_view message, absl::Span<const LogField> fields = {}) const {
    Log(LogLevel::kInfo, message, fields);
  }
  void Warning(absl::string_view message, absl::Span<const LogField> fields = {}) const {
    Log(LogLevel::kWarning, message, fields);
  }
  void Error(absl::string_view message, absl::Span<const LogField> fields = {}) const {
    Log(LogLevel::kError, message, fields);
  }

  // The line Log would write (for tests and for callers that batch).
  std::string Format(LogLevel level, absl::string_view message,
                     absl::Span<const LogField> fields) const;

  LogLevel level() const { return level_.load(std::memory_order_relaxed); }
  // Live: takes effect for the next line. Returns the previous level.
  LogLevel SetLevel(LogLevel level) { return level_.exchange(level); }
  LogFormat format() const { return format_; }

 private:
  const LogFormat format_;
  std::atomic<LogLevel> level_;
  const Sink sink_;
};

}  // namespace shapeid

#endif  // SHAPEID_SERVER_OPS_LOGGER_H_
