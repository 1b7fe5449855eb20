#include "client/cli/operations_commands.h"

#include <algorithm>
#include <memory>
#include <vector>

#include "absl/strings/ascii.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "core/json.h"

namespace shapeid {
namespace {

constexpr size_t kGalleriesShown = 10;

// CSV seconds: 9 digits are plenty for a latency, and stay readable.
std::string CsvSeconds(const google::protobuf::Duration& d) {
  return absl::StrFormat("%.9g", DurationSeconds(d));
}

std::string OrDash(const std::string& text) { return text.empty() ? "-" : text; }

// A latency as "0.71 ms", or "-" when the server sent none (no calls).
std::string Latency(bool set, const google::protobuf::Duration& d) {
  return set ? FormatSeconds(DurationSeconds(d)) : "-";
}

std::string LatencyJson(bool set, const google::protobuf::Duration& d) {
  return set ? JsonNumber(DurationSeconds(d)) : "null";
}

std::string CsvLatency(bool set, const google::protobuf::Duration& d) {
  return set ? CsvSeconds(d) : "";
}

// A server from before the work scheduler sends no lanes, and then no waits or call memory
// either: its output stays as it was, rather than showing its zeros as "no budget".
bool HasWork(const v1::ServerStats& stats) { return stats.work_size() > 0; }

Table MethodTable(const v1::ServerStats& stats, bool csv) {
  const bool waits = HasWork(stats);
  Table table;
  if (csv) {
    table.header = {"method", "calls", "errors", "latency_p50_seconds", "latency_p99_seconds"};
    if (waits) table.header.insert(table.header.end(), {"wait_p50_seconds", "wait_p99_seconds"});
  } else {
    table.header = {"METHOD", "CALLS", "ERRORS", "P50", "P99"};
    if (waits) table.header.insert(table.header.end(), {"WAIT P50", "WAIT P99"});
    table.right_aligned.assign(table.header.size(), true);
    table.right_aligned[0] = false;
  }
  for (const v1::MethodStats& m : stats.methods()) {
    std::vector<std::string>& row = table.rows.emplace_back();
    if (csv) {
      row = {m.method(), absl::StrCat(m.calls()), absl::StrCat(m.errors()),
             CsvLatency(m.has_latency_p50(), m.latency_p50()),
             CsvLatency(m.has_latency_p99(), m.latency_p99())};
      if (waits) {
        row.push_back(CsvLatency(m.has_wait_p50(), m.wait_p50()));
        row.push_back(CsvLatency(m.has_wait_p99(), m.wait_p99()));
      }
    } else {
      row = {m.method(), GroupDigits(m.calls()), GroupDigits(m.errors()),
             Latency(m.has_latency_p50(), m.latency_p50()),
             Latency(m.has_latency_p99(), m.latency_p99())};
      if (waits) {
        row.push_back(Latency(m.has_wait_p50(), m.wait_p50()));
        row.push_back(Latency(m.has_wait_p99(), m.wait_p99()));
      }
    }
  }
  return table;
}

Table WorkTable(const v1::ServerStats& stats) {
  // ESTIMATED: the queued pieces' estimated CPU time; CALLERS: how many callers they are from.
  Table table{{"WORK", "WORKERS", "RUNNING", "QUEUED", "ESTIMATED", "CALLERS"},
              {},
              {false, true, true, true, true, true}};
  for (const v1::WorkLaneStats& lane : stats.work()) {
    table.rows.push_back(
        {lane.lane(), GroupDigits(lane.workers()), GroupDigits(lane.running()),
         GroupDigits(lane.queued()),
         lane.queued() == 0 ? std::string("0") : FormatSeconds(DurationSeconds(lane.queued_work())),
         GroupDigits(lane.queued_callers())});
  }
  return table;
}

// As the server reads it (server/ops/logger.cc): any case.
bool KnownLevel(const std::string& level) {
  const std::string lower = absl::AsciiStrToLower(level);
  return lower == "debug" || lower == "info" || lower == "warning" || lower == "error";
}

}  // namespace

std::string GroupDigits(uint64_t value) {
  const std::string digits = absl::StrCat(value);
  std::string out;
  for (size_t i = 0; i < digits.size(); ++i) {
    if (i > 0 && (digits.size() - i) % 3 == 0) out += ',';
    out += digits[i];
  }
  return out;
}

std::string FormatUptime(int64_t seconds) {
  seconds = std::max<int64_t>(seconds, 0);
  const int64_t days = seconds / 86400, hours = seconds / 3600 % 24;
  const int64_t minutes = seconds / 60 % 60, rest = seconds % 60;
  if (days > 0) return absl::StrCat(days, "d", hours, "h");
  if (hours > 0) return absl::StrCat(hours, "h", minutes, "m");
  if (minutes > 0) return absl::StrCat(minutes, "m", rest, "s");
  return absl::StrCat(rest, "s");
}

std::string FormatBytes(uint64_t bytes) {
  const double b = static_cast<double>(bytes);
  if (bytes < 1024) return absl::StrCat(bytes, " B");
  if (bytes < (uint64_t{1} << 20)) return absl::StrFormat("%.1f KiB", b / 1024);
  if (bytes < (uint64_t{1} << 30)) return absl::StrFormat("%.0f MiB", b / (1 << 20));
  return absl::StrFormat("%.1f GiB", b / (1 << 30));
}

std::string FormatMib(uint64_t bytes) {
  const double mib = static_cast<double>(bytes) / (1 << 20);
  if (bytes == 0) return "0 MiB";
  if (mib < 0.1) return "<0.1 MiB";
  if (mib < 10) return absl::StrFormat("%.1f MiB", mib);
  return absl::StrCat(GroupDigits(static_cast<uint64_t>(mib + 0.5)), " MiB");
}

std::string StatsText(const v1::ServerStats& stats, const std::string& target) {
  std::string text = absl::StrCat(
      "server ", target, "  shapeid ", OrDash(stats.version()), "  ", OrDash(stats.state()),
      "  up ", FormatUptime(stats.uptime().seconds()), "  in flight ", stats.calls_in_flight(),
      "\n", "store ", OrDash(stats.store()), "  memory ",
      FormatBytes(stats.resident_memory_bytes()), "  log level ", OrDash(stats.log_level()),
      "  metrics ", stats.metrics_address().empty() ? "off" : stats.metrics_address(), "\n",
      "galleries ", GroupDigits(stats.galleries_size()), "  samples ", GroupDigits(stats.samples()),
      "  points received ", GroupDigits(stats.points_received()), "\n");
  if (HasWork(stats)) {
    absl::StrAppend(
        &text, "call memory held ", FormatMib(stats.memory_held_bytes()), "  peak ",
        FormatMib(stats.memory_held_peak_bytes()), "  budget ",
        stats.memory_budget_bytes() == 0 ? "none" : FormatMib(stats.memory_budget_bytes()), "\n");
  }
  absl::StrAppend(&text, "\n");
  if (stats.methods_size() == 0) {
    absl::StrAppend(&text, "no calls yet\n");
  } else {
    absl::StrAppend(&text, RenderTable(MethodTable(stats, /*csv=*/false)));
  }
  if (HasWork(stats)) absl::StrAppend(&text, "\n", RenderTable(WorkTable(stats)));
  if (stats.galleries_size() == 0) return text;
  // Largest first, as the server sends them; sorted again so that any server's top 10 shows.
  std::vector<v1::GalleryStats> galleries(stats.galleries().begin(), stats.galleries().end());
  std::stable_sort(galleries.begin(), galleries.end(),
                   [](const v1::GalleryStats& a, const v1::GalleryStats& b) {
                     return a.samples() > b.samples();
                   });
  Table table{{"GALLERY", "SAMPLES", "VERSION"}, {}, {false, true, true}};
  uint64_t rest_samples = 0;
  for (size_t i = 0; i < galleries.size(); ++i) {
    if (i < kGalleriesShown) {
      table.rows.push_back({galleries[i].name(), GroupDigits(galleries[i].samples()),
                            absl::StrCat(galleries[i].version())});
    } else {
      rest_samples += galleries[i].samples();
    }
  }
  absl::StrAppend(&text, "\n", RenderTable(table));
  if (galleries.size() > kGalleriesShown) {
    absl::StrAppend(&text, "... and ", GroupDigits(galleries.size() - kGalleriesShown),
                    " smaller galleries (", GroupDigits(rest_samples), " samples)\n");
  }
  return text;
}

std::string StatsJson(const v1::ServerStats& stats, const std::string& target) {
  std::string methods;
  for (const v1::MethodStats& m : stats.methods()) {
    absl::StrAppend(&methods, methods.empty() ? "" : ",", "{\"method\":", JsonString(m.method()),
                    ",\"calls\":", m.calls(), ",\"errors\":", m.errors(),
                    ",\"latency_p50_seconds\":", LatencyJson(m.has_latency_p50(), m.latency_p50()),
                    ",\"latency_p99_seconds\":", LatencyJson(m.has_latency_p99(), m.latency_p99()));
    if (HasWork(stats)) {
      absl::StrAppend(&methods,
                      ",\"wait_p50_seconds\":", LatencyJson(m.has_wait_p50(), m.wait_p50()),
                      ",\"wait_p99_seconds\":", LatencyJson(m.has_wait_p99(), m.wait_p99()));
    }
    absl::StrAppend(&methods, "}");
  }
  // Keys of the work scheduler only from a server that has one (HasWork).
  std::string work;
  if (HasWork(stats)) {
    std::string lanes;
    for (const v1::WorkLaneStats& lane : stats.work()) {
      absl::StrAppend(&lanes, lanes.empty() ? "" : ",", "{\"lane\":", JsonString(lane.lane()),
                      ",\"workers\":", lane.workers(), ",\"running\":", lane.running(),
                      ",\"queued\":", lane.queued(),
                      ",\"queued_work_seconds\":", CsvSeconds(lane.queued_work()),
                      ",\"queued_callers\":", lane.queued_callers(), "}");
    }
    work = absl::StrCat(",\"caller_backlog_seconds\":", CsvSeconds(stats.caller_backlog()),
                        ",\"callers_with_backlog\":", stats.callers_with_backlog(),
                        ",\"memory_budget_bytes\":", stats.memory_budget_bytes(),
                        ",\"memory_held_bytes\":", stats.memory_held_bytes(),
                        ",\"memory_held_peak_bytes\":", stats.memory_held_peak_bytes(),
                        ",\"work\":[", lanes, "]");
  }
  std::string galleries;
  for (const v1::GalleryStats& g : stats.galleries()) {
    absl::StrAppend(&galleries, galleries.empty() ? "" : ",", "{\"name\":", JsonString(g.name()),
                    ",\"samples\":", g.samples(), ",\"version\":", g.version(), "}");
  }
  return absl::StrCat(
      "{\"target\":", JsonString(target), ",\"version\":", JsonString(stats.version()),
      ",\"uptime_seconds\":", JsonNumber(DurationSeconds(stats.uptime())),
      ",\"state\":", JsonString(stats.state()), ",\"calls_in_flight\":", stats.calls_in_flight(),
      ",\"store\":", JsonString(stats.store()),
      ",\"resident_memory_bytes\":", stats.resident_memory_bytes(),
      ",\"log_level\":", JsonString(stats.log_level()),
      ",\"metrics_address\":", JsonString(stats.metrics_address()),
      ",\"gallery_count\":", stats.galleries_size(), ",\"samples\":", stats.samples(),
      ",\"points_received\":", stats.points_received(), work, ",\"methods\":[", methods, "]",
      ",\"galleries\":[", galleries, "]}\n");
}

int RunStats(const CliContext& context) {
  std::unique_ptr<Client> client = ConnectOrReport(context);
  if (client == nullptr) return kExitUsage;
  absl::StatusOr<v1::ServerStats> stats = client->GetServerStats();
  if (!stats.ok()) {
    PrintCallError(context, "stats", stats.status());
    return ExitCodeForStatus(stats.status());
  }
  switch (context.format) {
    case OutputFormat::kJson:
      return FinishOutput(WriteAll(context.out, StatsJson(*stats, context.client.target)), context);
    case OutputFormat::kCsv:
      return FinishOutput(WriteAll(context.out, RenderCsv(MethodTable(*stats, /*csv=*/true))),
                          context);
    case OutputFormat::kTable:
      break;
  }
  return FinishOutput(WriteAll(context.out, StatsText(*stats, context.client.target)), context);
}

int RunLogLevel(const std::string& level, const CliContext& context) {
  if (!KnownLevel(level)) {
    WriteAll(context.err, absl::StrCat("shapeid: log-level: unknown level \"", level,
                                       "\"; use debug, info, warning or error\n"));
    return kExitUsage;
  }
  std::unique_ptr<Client> client = ConnectOrReport(context);
  if (client == nullptr) return kExitUsage;
  absl::StatusOr<v1::SetLogLevelResponse> set = client->SetLogLevel(level);
  if (!set.ok()) {
    PrintCallError(context, absl::StrCat("log-level ", level), set.status());
    return ExitCodeForStatus(set.status());
  }
  std::string text;
  switch (context.format) {
    case OutputFormat::kJson:
      text = absl::StrCat("{\"target\":", JsonString(context.client.target),
                          ",\"previous_level\":", JsonString(set->previous_level()),
                          ",\"level\":", JsonString(set->level()), "}\n");
      break;
    case OutputFormat::kCsv:
      text = RenderCsv({{"previous_level", "level"}, {{set->previous_level(), set->level()}}, {}});
      break;
    case OutputFormat::kTable:
      text = absl::StrCat("log level: ", set->previous_level(), " -> ", set->level(), "\n");
      break;
  }
  // Live configuration is per replica: say so when --server names several.
  const std::string& target = context.client.target;
  if (context.progress != ProgressMode::kOff &&
      (target.find(',') != std::string::npos || target.rfind("dns:", 0) == 0)) {
    WriteAll(context.err,
             "shapeid: log-level: only the replica that answered changed its level; give each "
             "replica's HOST:PORT to --server to set them all\n");
  }
  return FinishOutput(WriteAll(context.out, text), context);
}

}  // namespace shapeid
