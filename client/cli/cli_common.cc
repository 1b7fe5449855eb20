#include "client/cli/cli_common.h"

#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <random>
#include <thread>
#include <utility>

#include "absl/strings/ascii.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/strings/str_split.h"
#include "core/rigid_transform.h"
#include "core/status_macros.h"

namespace shapeid {

absl::StatusOr<OutputFormat> ParseOutputFormat(absl::string_view text) {
  if (text == "table" || text == "text") return OutputFormat::kTable;
  if (text == "json") return OutputFormat::kJson;
  if (text == "csv") return OutputFormat::kCsv;
  return absl::InvalidArgumentError(
      absl::StrCat("unknown output format \"", text, "\"; use table, json or csv"));
}

int ExitCodeForStatus(const absl::Status& status) {
  if (status.ok()) return kExitOk;
  if (absl::IsUnavailable(status) || absl::IsDeadlineExceeded(status)) return kExitUnreachable;
  if (IsClientReceiveLimit(status)) return kExitAnswerTooLarge;
  return kExitRefused;
}

bool StopsBatch(const absl::Status& status) {
  if (IsClientReceiveLimit(status)) return true;
  switch (status.code()) {
    case absl::StatusCode::kUnavailable:
    case absl::StatusCode::kDeadlineExceeded:
    case absl::StatusCode::kNotFound:            // the gallery (files are read locally)
    case absl::StatusCode::kFailedPrecondition:  // an empty gallery
    case absl::StatusCode::kUnauthenticated:
    case absl::StatusCode::kPermissionDenied:
    case absl::StatusCode::kUnimplemented:  // an older server
    case absl::StatusCode::kCancelled:
      return true;
    default:
      return false;
  }
}

namespace {

std::string ErrorLine(absl::string_view what, const absl::Status& status,
                      const std::string& target) {
  std::string line = absl::StrCat("shapeid: ", what, what.empty() ? "" : ": ", status.message());
  if (absl::IsUnavailable(status) && !target.empty()) {
    absl::StrAppend(&line, " (is shapeid-server running at ", target,
                    "? set --server or SHAPEID_SERVER; a TLS server needs --tls-ca)");
  } else if (absl::IsUnauthenticated(status)) {
    absl::StrAppend(&line, " (give the key in SHAPEID_API_KEY or --api-key-file)");
  }
  return line;
}

}  // namespace

void PrintError(std::FILE* err, absl::string_view what, const absl::Status& status,
                const std::string& target) {
  WriteAll(err, ErrorLine(what, status, target) + '\n');
}

void PrintCallError(const CliContext& context, absl::string_view what, const absl::Status& status) {
  std::string line = ErrorLine(what, status, context.client.target);
  if (absl::IsUnimplemented(status)) {
    absl::StrAppend(&line, " (the server is older than this shapeid and lacks the call)");
  }
  if (!context.client.request_id.empty()) {
    absl::StrAppend(&line, " [request id ", context.client.request_id, "]");
  }
  WriteAll(context.err, line + '\n');
}

std::string NewRequestId() {
  std::random_device random;
  const uint64_t bits = (uint64_t{random()} << 32) ^ random();
  return absl::StrFormat("cli-%016x", bits);
}

std::unique_ptr<Client> ConnectOrReport(const CliContext& context) {
  absl::StatusOr<std::unique_ptr<Client>> client = Client::Connect(context.client);
  if (!client.ok()) {
    PrintError(context.err, "connecting", client.status());
    return nullptr;
  }
  return std::move(client).value();
}

absl::StatusOr<std::string> ReadApiKeyFile(const std::string& path) {
  std::FILE* f = std::fopen(path.c_str(), "rb");
  if (f == nullptr) {
    return absl::InvalidArgumentError(
        absl::StrCat("cannot read the API key file '", path, "': ", std::strerror(errno)));
  }
  std::string text;
  char buf[4096];
  size_t n;
  while ((n = std::fread(buf, 1, sizeof(buf), f)) > 0 && text.size() < (1 << 16)) {
    text.append(buf, n);
  }
  std::fclose(f);
  const absl::string_view key = absl::StripAsciiWhitespace(text);
  if (key.empty()) {
    return absl::InvalidArgumentError(absl::StrCat("the API key file '", path, "' is empty"));
  }
  for (char c : key) {
    if (c <= ' ' || c == 0x7f) {
      return absl::InvalidArgumentError(absl::StrCat(
          "the API key file '", path, "' holds more than one word; it must hold only the key"));
    }
  }
  return std::string(key);
}

bool WriteAll(std::FILE* file, absl::string_view text) {
  if (!text.empty()) std::fwrite(text.data(), 1, text.size(), file);
  return std::ferror(file) == 0;
}

size_t DisplayWidth(absl::string_view text) {
  size_t width = 0;
  for (char c : text) {
    if ((static_cast<unsigned char>(c) & 0xC0) != 0x80) ++width;
  }
  return width;
}

std::string RenderTable(const Table& table) {
  const size_t columns = table.header.size();
  std::vector<size_t> width(columns, 0);
  for (size_t c = 0; c < columns; ++c) width[c] = DisplayWidth(table.header[c]);
  for (const auto& row : table.rows) {
    for (size_t c = 0; c < columns && c < row.size(); ++c) {
      width[c] = std::max(width[c], DisplayWidth(row[c]));
    }
  }
  std::string out;
  const auto append_row = [&](const std::vector<std::string>& row) {
    std::string line;
    for (size_t c = 0; c < columns; ++c) {
      const std::string& cell = c < row.size() ? row[c] : std::string();
      const size_t pad = width[c] - DisplayWidth(cell);
      const bool right = c < table.right_aligned.size() && table.right_aligned[c];
      if (c > 0) line += "  ";
      if (right) line.append(pad, ' ');
      line += cell;
      if (!right && c + 1 < columns) line.append(pad, ' ');
    }
    while (!line.empty() && line.back() == ' ') line.pop_back();
    out += line;
    out += '\n';
  };
  append_row(table.header);
  for (const auto& row : table.rows) append_row(row);
  return out;
}

std::string CsvField(absl::string_view text) {
  if (text.find_first_of(",\"\r\n") == absl::string_view::npos) return std::string(text);
  std::string quoted = "\"";
  for (char c : text) {
    if (c == '"') quoted += '"';
    quoted += c;
  }
  quoted += '"';
  return quoted;
}

std::string RenderCsv(const Table& table) {
  std::string out;
  const auto append_row = [&](const std::vector<std::string>& row) {
    for (size_t c = 0; c < row.size(); ++c) {
      if (c > 0) out += ',';
      out += CsvField(row[c]);
    }
    out += "\r\n";  // RFC 4180 line ending: spreadsheets expect it, scripts split either way
  };
  append_row(table.header);
  for (const auto& row : table.rows) append_row(row);
  return out;
}

std::string FormatSeconds(double seconds) {
  if (seconds < 1e-3) return absl::StrFormat("%.0f µs", seconds * 1e6);
  if (seconds < 1) return absl::StrFormat("%.3g ms", seconds * 1e3);
  return absl::StrFormat("%.3g s", seconds);
}

double DurationSeconds(const google::protobuf::Duration& duration) {
  // Division, not 1e-9 * nanos: correctly rounded, so 2.4 ms prints as 0.0024.
  return static_cast<double>(duration.seconds()) + duration.nanos() / 1e9;
}

int FinishOutput(bool written, const CliContext& context) {
  if (std::fflush(context.out) != 0 || !written) {
    WriteAll(context.err, "shapeid: cannot write the output\n");
    return kExitSomeInputsFailed;
  }
  return kExitOk;
}

std::string FormatPercent(double fraction) { return absl::StrFormat("%.2f", 100 * fraction); }

Progress::Progress(std::FILE* err, ProgressMode mode, std::string verb, size_t total)
    : err_(err),
      enabled_(mode == ProgressMode::kAuto && total >= 2),
      terminal_(enabled_ && ::isatty(::fileno(err)) == 1),
      verb_(std::move(verb)),
      total_(total),
      start_(Clock::now()),
      last_draw_(start_) {}

Progress::~Progress() { Finish(); }

void Progress::Advance(size_t done, size_t failed) {
  if (!enabled_) return;
  std::lock_guard<std::mutex> lock(mu_);
  done_ += done;
  failed_ += failed;
  DrawLocked(/*force=*/false);
}

void Progress::Interrupt(const std::function<void()>& write) {
  std::lock_guard<std::mutex> lock(mu_);
  if (terminal_ && drawn_) std::fputs("\r\033[K", err_);
  write();
  if (terminal_ && drawn_ && !finished_) DrawLocked(/*force=*/true);
}

void Progress::Finish() {
  if (!enabled_) return;
  std::lock_guard<std::mutex> lock(mu_);
  if (finished_) return;
  finished_ = true;
  if (terminal_ && drawn_) std::fputs("\r\033[K", err_);
  std::fflush(err_);
}

void Progress::DrawLocked(bool force) {
  if (finished_) return;
  const Clock::time_point now = Clock::now();
  const auto since_draw = now - last_draw_;
  const bool last = done_ >= total_;
  if (!force && !last) {
    if (terminal_ && since_draw < std::chrono::milliseconds(100)) return;
    if (!terminal_ && since_draw < std::chrono::seconds(5)) return;
  }
  if (!terminal_ && last) return;  // the command's own summary follows
  last_draw_ = now;
  const double elapsed = std::chrono::duration<double>(now - start_).count();
  const double rate = elapsed > 0 ? static_cast<double>(done_) / elapsed : 0;
  std::string eta = "--:--";
  if (rate > 0 && done_ < total_) {
    const long seconds = std::lround(static_cast<double>(total_ - done_) / rate);
    eta = absl::StrFormat("%d:%02d", seconds / 60, seconds % 60);
  }
  const std::string failed = failed_ > 0 ? absl::StrCat("  ", failed_, " failed") : "";
  if (terminal_) {
    constexpr int kBar = 24;
    const int filled = static_cast<int>(kBar * done_ / std::max<size_t>(total_, 1));
    std::fprintf(err_, "\r\033[K%s  [%s%s]  %zu/%zu  %.1f/s  ETA %s%s", verb_.c_str(),
                 std::string(static_cast<size_t>(filled), '#').c_str(),
                 std::string(static_cast<size_t>(kBar - filled), '.').c_str(), done_, total_, rate,
                 eta.c_str(), failed.c_str());
  } else {
    std::fprintf(err_, "%s: %zu/%zu (%.0f %%), %.1f/s, ETA %s%s\n", verb_.c_str(), done_, total_,
                 100.0 * static_cast<double>(done_) / static_cast<double>(total_), rate,
                 eta.c_str(), failed.c_str());
  }
  drawn_ = true;
  std::fflush(err_);
}

void ParallelFor(size_t n, int jobs, const std::function<void(size_t)>& body,
                 const std::function<bool()>& stop) {
  std::atomic<size_t> next{0};
  const auto work = [&] {
    for (;;) {
      if (stop && stop()) return;
      const size_t i = next.fetch_add(1);
      if (i >= n) return;
      body(i);
    }
  };
  const size_t threads = std::min<size_t>(static_cast<size_t>(std::max(jobs, 1)), n);
  std::vector<std::thread> workers;
  for (size_t t = 1; t < threads; ++t) workers.emplace_back(work);
  work();
  for (std::thread& worker : workers) worker.join();
}

absl::StatusOr<v1::SensorFrame> ParseSensorFrame(const SensorFrameFlags& flags) {
  v1::SensorFrame frame;
  if (!flags.up.empty() && !flags.transform.empty()) {
    return absl::InvalidArgumentError(
        "--sensor-up and --sensor-transform: give one (a transform fixes up too)");
  }
  const auto numbers = [](absl::string_view flag, const std::string& text,
                          size_t count) -> absl::StatusOr<std::vector<double>> {
    std::vector<double> values;
    for (absl::string_view word : absl::StrSplit(text, ',')) {
      double value;
      if (!absl::SimpleAtod(word, &value)) {
        return absl::InvalidArgumentError(absl::StrCat(flag, ": \"", word, "\" is not a number"));
      }
      values.push_back(value);
    }
    if (values.size() != count) {
      return absl::InvalidArgumentError(
          absl::StrCat(flag, ": ", values.size(), " numbers; expected ", count));
    }
    return values;
  };
  if (!flags.up.empty()) {
    SHAPEID_ASSIGN_OR_RETURN(const std::vector<double> up, numbers("--sensor-up", flags.up, 3));
    if (absl::Status s = RotationTakingUpTo(up, {0, 0, 1}).status(); !s.ok()) {
      return absl::InvalidArgumentError(absl::StrCat("--sensor-up: ", s.message()));
    }
    frame.mutable_up()->Assign(up.begin(), up.end());
  }
  if (!flags.transform.empty()) {
    SHAPEID_ASSIGN_OR_RETURN(const std::vector<double> rows,
                             numbers("--sensor-transform", flags.transform, 12));
    if (absl::Status s = RigidTransformFromRows(rows).status(); !s.ok()) {
      return absl::InvalidArgumentError(absl::StrCat("--sensor-transform: ", s.message()));
    }
    frame.mutable_transform()->Assign(rows.begin(), rows.end());
  }
  return frame;
}

}  // namespace shapeid
