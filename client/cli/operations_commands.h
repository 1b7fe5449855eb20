#ifndef SHAPEID_CLIENT_CLI_OPERATIONS_COMMANDS_H_
#define SHAPEID_CLIENT_CLI_OPERATIONS_COMMANDS_H_

// `shapeid stats` and `shapeid log-level`: what an operator asks a running server (one
// replica: the one the call reaches).

#include <string>

#include "client/cli/cli_common.h"
#include "shapeid/v1/shapeid.pb.h"

namespace shapeid {

// The server's live summary (GetServerStats). Table: the summary lines (call memory in MiB
// among them), the calls, latency and queue wait of each method called so far, the work
// lanes' workers, running and queued work, and the 10 largest galleries. json: one object
// with every field (all galleries; bytes and seconds). csv: the method table. A server
// without the work scheduler (no lanes in its answer) gets no wait, lane or call-memory
// figures in any format. Exit codes as ExitCodeForStatus.
int RunStats(const CliContext& context);

// Sets the server's log level to `level` (debug, info, warning or error; anything else is a
// usage error before any call) and prints "log level: OLD -> NEW" (json: one object; csv: a
// row). Exit codes as ExitCodeForStatus.
int RunLogLevel(const std::string& level, const CliContext& context);

// Renderings, for tests.
std::string StatsText(const v1::ServerStats& stats, const std::string& target);
std::string StatsJson(const v1::ServerStats& stats, const std::string& target);  // with '\n'
// "48,112".
std::string GroupDigits(uint64_t value);
// "45s", "12m5s", "2h13m", "3d4h".
std::string FormatUptime(int64_t seconds);
// "512 B", "3.2 KiB", "412 MiB", "1.5 GiB".
std::string FormatBytes(uint64_t bytes);
// "0 MiB", "<0.1 MiB", "3.5 MiB", "2,048 MiB": memory compared with --memory_budget_mib.
std::string FormatMib(uint64_t bytes);

}  // namespace shapeid

#endif  // SHAPEID_CLIENT_CLI_OPERATIONS_COMMANDS_H_
