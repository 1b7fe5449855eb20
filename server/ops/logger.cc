#include "server/ops/logger.h"

#include <unistd.h>

#include <cerrno>
#include <string>
#include <utility>

#include "absl/strings/ascii.h"
#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "absl/time/clock.h"
#include "absl/time/time.h"
#include "core/enum_names.h"
#include "core/json.h"

namespace shapeid {
namespace {

constexpr EnumNames<LogLevel, 4> kLogLevelNames = {{
    {LogLevel::kDebug, "debug"},
    {LogLevel::kInfo, "info"},
    {LogLevel::kWarning, "warning"},
    {LogLevel::kError, "error"},
}};

constexpr EnumNames<LogFormat, 2> kLogFormatNames = {{
    {LogFormat::kText, "text"},
    {LogFormat::kJson, "json"},
}};

// Writes the whole line to stderr, retrying short writes: one write(2) for any line below
// PIPE_BUF, so concurrent lines stay whole even when several processes share the stream.
void WriteToStderr(absl::string_view line) {
  while (!line.empty()) {
    const ssize_t n = write(STDERR_FILENO, line.data(), line.size());
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return;  // nowhere to report a broken stderr
    line.remove_prefix(static_cast<size_t>(n));
  }
}

// A text value as it is, or quoted when a reader could not tell where it ends (empty, blank,
// '"', '=' or a control character): logfmt's rule, so "key=value" tools parse the lines.
void AppendTextValue(absl::string_view value, std::string* out) {
  bool plain = !value.empty();
  for (const char c : value) {
    const unsigned char u = static_cast<unsigned char>(c);
    if (u <= ' ' || c == '"' || c == '=' || u == 0x7f) {
      plain = false;
      break;
    }
  }
  if (plain) {
    out->append(value.data(), value.size());
  } else {
    out->append(JsonString(value));
  }
}

void AppendValue(LogFormat format, const LogField& field, std::string* out) {
  if (const auto* text = std::get_if<absl::string_view>(&field.value)) {
    if (format == LogFormat::kJson) {
      out->append(JsonString(*text));
    } else {
      AppendTextValue(*text, out);
    }
  } else if (const auto* integer = std::get_if<int64_t>(&field.value)) {
    absl::StrAppend(out, *integer);
  } else {
    out->append(JsonNumber(std::get<double>(field.value)));
  }
}

}  // namespace

absl::string_view LogLevelName(LogLevel level) { return NameOf(kLogLevelNames, level, "info"); }

absl::StatusOr<LogLevel> ParseLogLevel(absl::string_view name) {
  if (auto level = ValueNamed(kLogLevelNames, name)) return *level;
  return absl::InvalidArgumentError(absl::StrCat("log level '", name.substr(0, 32),
                                                 "' is not one of ", NameList(kLogLevelNames)));
}

absl::StatusOr<LogFormat> ParseLogFormat(absl::string_view name) {
  if (auto format = ValueNamed(kLogFormatNames, name)) return *format;
  return absl::InvalidArgumentError(absl::StrCat("log format '", name.substr(0, 32),
                                                 "' is not one of ", NameList(kLogFormatNames)));
}

Logger::Logger(LoggerOptions options, Sink sink)
    : format_(options.format),
      level_(options.level),
      sink_(sink != nullptr ? std::move(sink) : Sink(WriteToStderr)) {}

void Logger::Log(LogLevel level, absl::string_view message,
                 absl::Span<const LogField> fields) const {
  if (!Enabled(level)) return;
  sink_(Format(level, message, fields));
}

std::string Logger::Format(LogLevel level, absl::string_view message,
                           absl::Span<const LogField> fields) const {
  std::string line;
  line.reserve(160 + message.size());
  if (format_ == LogFormat::kJson) {
    absl::StrAppend(&line, "{\"time\":\"",
                    absl::FormatTime("%Y-%m-%dT%H:%M:%E6SZ", absl::Now(), absl::UTCTimeZone()),
                    "\",\"level\":\"", LogLevelName(level), "\",\"msg\":", JsonString(message));
    for (const LogField& field : fields) {
      absl::StrAppend(&line, ",", JsonString(field.key), ":");
      AppendValue(format_, field, &line);
    }
    line += "}\n";
    return line;
  }
  line = "shapeid-server: ";
  if (level != LogLevel::kInfo) {
    absl::StrAppend(&line, absl::AsciiStrToUpper(LogLevelName(level)), ": ");
  }
  // A control character in a message (a name or an error quoted into it) must not start a
  // forged line.
  for (const char c : message) {
    const unsigned char u = static_cast<unsigned char>(c);
    if (u < 0x20 || u == 0x7f) {
      absl::StrAppend(&line, "\\x", absl::Hex(u, absl::kZeroPad2));
    } else {
      line += c;
    }
  }
  for (const LogField& field : fields) {
    // An empty text says nothing to a reader (JSON keeps it: a fixed schema for pipelines).
    const auto* text = std::get_if<absl::string_view>(&field.value);
    if (text != nullptr && text->empty()) continue;
    absl::StrAppend(&line, " ", field.key, "=");
    AppendValue(format_, field, &line);
  }
  line += '\n';
  return line;
}

}  // namespace shapeid
