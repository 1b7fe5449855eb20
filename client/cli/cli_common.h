#ifndef SHAPEID_CLIENT_CLI_CLI_COMMON_H_
#define SHAPEID_CLIENT_CLI_CLI_COMMON_H_

// What every `shapeid` command shares: exit codes, output formats, the connection to the
// server, error lines, aligned tables and CSV, a progress reporter, and a parallel loop.

#include <chrono>
#include <cstdio>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "client/client.h"
#include "client/client_options.h"

namespace shapeid {

// Exit codes of the shapeid tool (documented in `shapeid --help`).
inline constexpr int kExitOk = 0;
inline constexpr int kExitSomeInputsFailed = 1;  // the other inputs were still processed
inline constexpr int kExitUsage = 2;             // bad flags, spec or paths; nothing was done
inline constexpr int kExitUnreachable = 3;       // no answer from the server (or deadline)
inline constexpr int kExitRefused = 4;           // the server refused the whole command
// The server answered, but with more than this client reads (kClientMaxReceiveBytes): the
// refusal is this client's, not the server's.
inline constexpr int kExitAnswerTooLarge = 5;

// Kept for describe's original name of exit code 1.
inline constexpr int kExitSomeFilesFailed = kExitSomeInputsFailed;

enum class OutputFormat {
  kTable,  // for people: aligned columns (describe: file then values)
  kJson,   // for scripts: one JSON object per line (JSON Lines)
  kCsv,    // for spreadsheets: RFC 4180 with a header row
};

// "table", "text" (an alias kept for describe), "json" or "csv".
absl::StatusOr<OutputFormat> ParseOutputFormat(absl::string_view text);

enum class ProgressMode {
  kAuto,  // a live bar when stderr is a terminal, otherwise a plain line every few seconds
  kOff,   // nothing (--quiet)
};

// Where a command writes and how it reaches the server. One per invocation.
struct CliContext {
  std::FILE* out = stdout;
  std::FILE* err = stderr;
  OutputFormat format = OutputFormat::kTable;
  ProgressMode progress = ProgressMode::kAuto;
  // target from --server / SHAPEID_SERVER (one server or a comma list of replicas),
  // load_balancing from --load-balancing, deadline from --timeout, TLS from --tls*, the key
  // from SHAPEID_API_KEY / --api-key-file, request_id from --request-id / SHAPEID_REQUEST_ID
  // or NewRequestId()
  ClientOptions client;
};

// The exit code for a command that failed as a whole with `status`: UNAVAILABLE and
// DEADLINE_EXCEEDED mean the server did not answer (3); an answer this client would not read
// (IsClientReceiveLimit) is 5; anything else the server said is a refusal (4).
int ExitCodeForStatus(const absl::Status& status);

// True for errors that would fail every further input of a batch the same way (the server
// is gone, the gallery does not exist or is empty, the caller may not do this, answers are
// larger than this client reads), so a batch
// stops at the first one instead of printing it a thousand times.
bool StopsBatch(const absl::Status& status);

// Writes "shapeid: <what>: <message>\n" to `err`, with a hint for an unreachable server.
void PrintError(std::FILE* err, absl::string_view what, const absl::Status& status,
                const std::string& target = "");

// PrintError for a call to the server that failed: the hint names context.client.target (or
// says that UNIMPLEMENTED means an older server), and the line ends with " [request id ID]"
// (context.client.request_id, which the server logs) when there is one.
void PrintCallError(const CliContext& context, absl::string_view what, const absl::Status& status);

// A fresh random request id for one run of the tool: "cli-" and 16 hex digits.
std::string NewRequestId();

// Connects, mapping a bad option (target, TLS file, API key) to a usage error line. Null and
// an error line on failure.
std::unique_ptr<Client> ConnectOrReport(const CliContext& context);

// The API key held in the file `path` (--api-key-file): its whole content, surrounding
// whitespace ignored. InvalidArgument when it cannot be read, is empty or holds more than one
// word; the message names the file, never its content.
absl::StatusOr<std::string> ReadApiKeyFile(const std::string& path);

// Writes `text` to `file`; false if the stream is in error afterwards.
bool WriteAll(std::FILE* file, absl::string_view text);

// The exit code of a command whose output is all written: kExitOk, or (the output could not be
// written or flushed: a full disk, a closed pipe) kExitSomeInputsFailed after saying so.
int FinishOutput(bool written, const CliContext& context);

// A table of strings rendered as aligned columns (two spaces apart; columns listed in
// `right_aligned` are right-aligned, for numbers) or as CSV.
struct Table {
  std::vector<std::string> header;
  std::vector<std::vector<std::string>> rows;
  std::vector<bool> right_aligned;  // per column; missing entries mean left-aligned
};
std::string RenderTable(const Table& table);
std::string RenderCsv(const Table& table);
// One CSV field, quoted when it holds a comma, quote, CR or LF (RFC 4180).
std::string CsvField(absl::string_view text);

// Display width of UTF-8 text in a terminal: code points, not bytes (good enough for labels
// and paths; wide CJK glyphs are rare in them).
size_t DisplayWidth(absl::string_view text);

// "12.3 ms", "850 µs", "2.41 s".
std::string FormatSeconds(double seconds);
// A protobuf Duration in seconds.
double DurationSeconds(const google::protobuf::Duration& duration);
// "12.34" for 0.1234 (no percent sign).
std::string FormatPercent(double fraction);

// Progress of a batch on stderr: with ProgressMode::kAuto and a terminal, a bar redrawn at
// most ten times a second ("train  [#####.....]  420/908  51.2 files/s  ETA 0:09  2 failed");
// without a terminal a plain line every 5 s; nothing with kOff or fewer than 2 items.
// Thread-safe.
class Progress {
 public:
  Progress(std::FILE* err, ProgressMode mode, std::string verb, size_t total);
  ~Progress();                               // Finish()
  void Advance(size_t done, size_t failed);  // `done` items finished, `failed` of them failed
  // Clears the bar (so the next stderr line starts clean). Idempotent.
  void Finish();
  // Runs `write` with the bar cleared, then redraws it: for error lines during the batch.
  void Interrupt(const std::function<void()>& write);

 private:
  void DrawLocked(bool force);
  using Clock = std::chrono::steady_clock;
  std::FILE* const err_;
  const bool enabled_;
  const bool terminal_;
  const std::string verb_;
  const size_t total_;
  const Clock::time_point start_;
  std::mutex mu_;
  size_t done_ = 0;
  size_t failed_ = 0;
  Clock::time_point last_draw_;
  bool drawn_ = false;
  bool finished_ = false;
};

// Calls body(i) for every i in [0, n) on `jobs` threads (the calling thread is one of them),
// handing out indices in order. Returns when every call has returned. `stop`, when set by a
// body, makes the others take no new index.
void ParallelFor(size_t n, int jobs, const std::function<void(size_t)>& body,
                 const std::function<bool()>& stop = nullptr);

// The sensor-frame flags of describe, train and classify, as typed.
struct SensorFrameFlags {
  std::string up;         // --sensor-up X,Y,Z
  std::string transform;  // --sensor-transform: 12 numbers, the rows of [R | t]
};

// The SensorFrame those flags ask for (empty when neither is given). InvalidArgument naming
// the flag for a wrong count of numbers, a word that is not a number, both flags at once, an
// up of zero length or a transform that is not rigid (checked here, as the server would, so
// that it is a usage error before any file is read).
absl::StatusOr<v1::SensorFrame> ParseSensorFrame(const SensorFrameFlags& flags);

}  // namespace shapeid

#endif  // SHAPEID_CLIENT_CLI_CLI_COMMON_H_
