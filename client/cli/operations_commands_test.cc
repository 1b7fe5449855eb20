// `shapeid stats` and `shapeid log-level` against a fake server (client/client_testing.h):
// the printed summary, JSON a script can parse, exit codes, the request id on every call and
// in the error line.

#include "client/cli/operations_commands.h"

#include <algorithm>
#include <memory>
#include <string>
#include <vector>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_split.h"
#include "client/cli/cli_testing.h"
#include "client/client_testing.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"

namespace shapeid {
namespace {

using cli_testing::Captured;
using cli_testing::PythonOnJsonLines;
using client_testing::FakeOperationsService;
using ::testing::AllOf;
using ::testing::ElementsAre;
using ::testing::HasSubstr;
using ::testing::Not;

google::protobuf::Duration Millis(double ms) {
  google::protobuf::Duration d;
  const auto nanos = static_cast<int64_t>(ms * 1e6);
  d.set_seconds(nanos / 1000000000);
  d.set_nanos(static_cast<int32_t>(nanos % 1000000000));
  return d;
}

// A busy server: two methods (one without latency), 12 galleries sent out of order.
v1::ServerStats BusyServer() {
  v1::ServerStats stats;
  stats.set_version("0.12.0");
  stats.mutable_uptime()->set_seconds(2 * 3600 + 13 * 60 + 9);
  stats.set_state("serving");
  stats.set_calls_in_flight(3);
  v1::MethodStats* classify = stats.add_methods();
  classify->set_method("ClassifyCloud");
  classify->set_calls(1204331);
  classify->set_errors(12);
  *classify->mutable_latency_p50() = Millis(0.71);
  *classify->mutable_latency_p99() = Millis(2.4);
  v1::MethodStats* train = stats.add_methods();
  train->set_method("Train");
  train->set_calls(0);
  for (int i = 0; i < 12; ++i) {
    v1::GalleryStats* g = stats.add_galleries();
    g->set_name(absl::StrCat("g", i));
    g->set_samples(i == 5 ? 40000 : 100 * (i + 1));  // g5 is the largest
    g->set_version(i + 1);
  }
  stats.set_samples(40000 + 100 * (78 - 6));
  stats.set_points_received(1234567890);
  stats.set_resident_memory_bytes(uint64_t{412} << 20);
  stats.set_store("/var/lib/shapeid");
  stats.set_log_level("info");
  stats.set_metrics_address("0.0.0.0:9464");
  return stats;
}

// The busy server with the work scheduler: waits for ClassifyCloud (Train queued nothing),
// three lanes, heavy work queued, call memory near its budget.
v1::ServerStats SharedServer() {
  v1::ServerStats stats = BusyServer();
  v1::MethodStats* classify = stats.mutable_methods(0);
  classify->mutable_wait_p50()->set_nanos(15000);
  classify->mutable_wait_p99()->set_nanos(31000000);
  const struct {
    const char* lane;
    uint32_t workers, running;
    uint64_t queued;
  } lanes[] = {{"cheap", 2, 2, 0}, {"heavy", 1, 1, 1234}, {"store", 2, 0, 0}};
  for (const auto& lane : lanes) {
    v1::WorkLaneStats* work = stats.add_work();
    work->set_lane(lane.lane);
    work->set_workers(lane.workers);
    work->set_running(lane.running);
    work->set_queued(lane.queued);
    if (lane.queued > 0) {  // 1,234 pieces of 50 ms from 3 callers
      work->mutable_queued_work()->set_seconds(61);
      work->mutable_queued_work()->set_nanos(700000000);
      work->set_queued_callers(3);
    }
  }
  stats.mutable_caller_backlog()->set_seconds(61);
  stats.mutable_caller_backlog()->set_nanos(700000000);
  stats.set_callers_with_backlog(3);
  stats.set_memory_budget_bytes(uint64_t{2048} << 20);
  stats.set_memory_held_bytes(uint64_t{1900} << 20);
  stats.set_memory_held_peak_bytes(uint64_t{2047} << 20);
  return stats;
}

class OperationsCommandsTest : public ::testing::Test {
 protected:
  void SetUp() override {
    server_ = client_testing::StartFakeServer(&service_, &target_);
    ASSERT_NE(server_, nullptr);
  }
  void TearDown() override { server_->Shutdown(); }

  CliContext Context(OutputFormat format = OutputFormat::kTable) {
    CliContext context;
    context.out = out_.get();
    context.err = err_.get();
    context.format = format;
    context.progress = ProgressMode::kOff;
    context.client.target = target_;
    context.client.request_id = "cli-00000000deadbeef";
    return context;
  }

  FakeOperationsService service_{BusyServer()};
  std::string target_;
  std::unique_ptr<grpc::Server> server_;
  Captured out_, err_;
};

TEST_F(OperationsCommandsTest, StatsTableSummarisesAndShowsTheTenLargestGalleries) {
  ASSERT_EQ(RunStats(Context()), kExitOk) << err_.contents();
  const std::vector<std::string> lines = absl::StrSplit(out_.contents(), '\n');
  ASSERT_EQ(lines.size(), 21u) << out_.contents();
  EXPECT_EQ(lines[0],
            absl::StrCat("server ", target_, "  shapeid 0.12.0  serving  up 2h13m  in flight 3"));
  EXPECT_EQ(lines[1],
            "store /var/lib/shapeid  memory 412 MiB  log level info  metrics 0.0.0.0:9464");
  EXPECT_EQ(lines[2], "galleries 12  samples 47,200  points received 1,234,567,890");
  EXPECT_EQ(lines[3], "");
  // Numbers right-aligned under their headers; no latency without calls.
  EXPECT_EQ(lines[4], "METHOD             CALLS  ERRORS     P50     P99");
  EXPECT_EQ(lines[5], "ClassifyCloud  1,204,331      12  710 µs  2.4 ms");
  EXPECT_EQ(lines[6], "Train                  0       0       -       -");
  EXPECT_EQ(lines[7], "");
  EXPECT_EQ(lines[8], "GALLERY  SAMPLES  VERSION");
  EXPECT_EQ(lines[9], "g5        40,000        6");
  EXPECT_EQ(lines[10], "g11        1,200       12");
  EXPECT_EQ(lines[18], "g2           300        3");                  // the tenth
  EXPECT_EQ(lines[19], "... and 2 smaller galleries (300 samples)");  // g0 and g1
  EXPECT_EQ(err_.contents(), "");
}

TEST_F(OperationsCommandsTest, StatsJsonIsOneObjectWithEveryField) {
  ASSERT_EQ(RunStats(Context(OutputFormat::kJson)), kExitOk) << err_.contents();
  const std::string json = out_.contents();
  EXPECT_EQ(std::count(json.begin(), json.end(), '\n'), 1);
  EXPECT_EQ(PythonOnJsonLines(
                out_.contents(),
                "[(r[\"version\"], r[\"uptime_seconds\"], r[\"state\"], r[\"calls_in_flight\"], "
                "r[\"store\"], r[\"resident_memory_bytes\"], r[\"log_level\"], "
                "r[\"metrics_address\"], r[\"gallery_count\"], r[\"samples\"], "
                "r[\"points_received\"], len(r[\"galleries\"]), r[\"galleries\"][5], "
                "r[\"target\"] != \"\") for r in rows]"),
            "[('0.12.0', 7989, 'serving', 3, '/var/lib/shapeid', 432013312, 'info', "
            "'0.0.0.0:9464', 12, 47200, 1234567890, 12, "
            "{'name': 'g5', 'samples': 40000, 'version': 6}, True)]");
  EXPECT_EQ(PythonOnJsonLines(out_.contents(), "[r[\"methods\"] for r in rows]"),
            "[[{'method': 'ClassifyCloud', 'calls': 1204331, 'errors': 12, "
            "'latency_p50_seconds': 0.00071, 'latency_p99_seconds': 0.0024}, "
            "{'method': 'Train', 'calls': 0, 'errors': 0, 'latency_p50_seconds': None, "
            "'latency_p99_seconds': None}]]");
}

TEST_F(OperationsCommandsTest, StatsCsvIsTheMethodTable) {
  ASSERT_EQ(RunStats(Context(OutputFormat::kCsv)), kExitOk) << err_.contents();
  EXPECT_EQ(out_.contents(),
            "method,calls,errors,latency_p50_seconds,latency_p99_seconds\r\n"
            "ClassifyCloud,1204331,12,0.00071,0.0024\r\n"
            "Train,0,0,,\r\n");
}

TEST_F(OperationsCommandsTest, AnIdleServerSaysSo) {
  FakeOperationsService idle;
  std::string target;
  std::unique_ptr<grpc::Server> server = client_testing::StartFakeServer(&idle, &target);
  CliContext context = Context();
  context.client.target = target;
  ASSERT_EQ(RunStats(context), kExitOk) << err_.contents();
  EXPECT_THAT(out_.contents(), AllOf(HasSubstr("up 0s  in flight 0"), HasSubstr("memory 0 B"),
                                     HasSubstr("metrics off"), HasSubstr("galleries 0  samples 0"),
                                     HasSubstr("\n\nno calls yet\n"), Not(HasSubstr("GALLERY"))));
  server->Shutdown();
}

TEST_F(OperationsCommandsTest, LogLevelPrintsTheChangeInEveryFormat) {
  ASSERT_EQ(RunLogLevel("warning", Context()), kExitOk) << err_.contents();
  EXPECT_EQ(out_.contents(), "log level: info -> warning\n");
  Captured json;
  CliContext context = Context(OutputFormat::kJson);
  context.out = json.get();
  ASSERT_EQ(RunLogLevel("debug", context), kExitOk) << err_.contents();
  EXPECT_EQ(
      PythonOnJsonLines(json.contents(), "[(r[\"previous_level\"], r[\"level\"]) for r in rows]"),
      "[('warning', 'debug')]");
  Captured csv;
  context = Context(OutputFormat::kCsv);
  context.out = csv.get();
  ASSERT_EQ(RunLogLevel("error", context), kExitOk) << err_.contents();
  EXPECT_EQ(csv.contents(), "previous_level,level\r\ndebug,error\r\n");
  EXPECT_EQ(err_.contents(), "");
  // Every call carried the run's request id.
  EXPECT_THAT(service_.request_ids(),
              ElementsAre("cli-00000000deadbeef", "cli-00000000deadbeef", "cli-00000000deadbeef"));
}

TEST_F(OperationsCommandsTest, AnUnknownLevelIsAUsageErrorBeforeAnyCall) {
  for (const char* level : {"verbose", "warn", ""}) {  // any case is fine: "INFO" is info
    EXPECT_EQ(RunLogLevel(level, Context()), kExitUsage) << level;
  }
  EXPECT_THAT(err_.contents(),
              HasSubstr("shapeid: log-level: unknown level \"verbose\"; use debug, info, "
                        "warning or error\n"));
  EXPECT_EQ(out_.contents(), "");
  EXPECT_THAT(service_.request_ids(), ::testing::IsEmpty());
}

TEST_F(OperationsCommandsTest, AFailedCallNamesItsRequestIdAndExitsAsOthers) {
  CliContext context = Context();
  context.client.max_attempts = 1;
  service_.RefuseNext(1);  // UNAVAILABLE: the server did not serve it (3)
  EXPECT_EQ(RunStats(context), kExitUnreachable);
  EXPECT_THAT(err_.contents(),
              AllOf(HasSubstr("shapeid: stats: loading its galleries (is shapeid-server running"),
                    HasSubstr("[request id cli-00000000deadbeef]\n")));

  // A server from before these calls: UNIMPLEMENTED, a refusal (4), said plainly.
  v1::ShapeId::CallbackService older;
  std::string target;
  std::unique_ptr<grpc::Server> server = client_testing::StartFakeServer(&older, &target);
  context.client.target = target;
  EXPECT_EQ(RunLogLevel("info", context), kExitRefused);
  EXPECT_THAT(err_.contents(),
              HasSubstr("(the server is older than this shapeid and lacks the call) "
                        "[request id cli-00000000deadbeef]\n"));
  server->Shutdown();

  context.client.target = "127.0.0.1:1";  // nothing listens
  EXPECT_EQ(RunStats(context), kExitUnreachable);
  context.client.request_id = "not allowed";
  EXPECT_EQ(RunStats(context), kExitUsage);
  EXPECT_THAT(err_.contents(), HasSubstr("A-Z a-z 0-9 . _ : / + = -"));
}

// The same commands against a server with the work scheduler (SharedServer): target_ is its.
class SchedulerStatsTest : public OperationsCommandsTest {
 protected:
  void SetUp() override {
    OperationsCommandsTest::SetUp();
    shared_server_ = client_testing::StartFakeServer(&shared_, &target_);
    ASSERT_NE(shared_server_, nullptr);
  }
  void TearDown() override {
    shared_server_->Shutdown();
    OperationsCommandsTest::TearDown();
  }

  FakeOperationsService shared_{SharedServer()};
  std::unique_ptr<grpc::Server> shared_server_;
};

TEST_F(SchedulerStatsTest, StatsTableShowsCallMemoryWaitsAndLanes) {
  ASSERT_EQ(RunStats(Context()), kExitOk) << err_.contents();
  const std::vector<std::string> lines = absl::StrSplit(out_.contents(), '\n');
  ASSERT_EQ(lines.size(), 27u) << out_.contents();
  EXPECT_EQ(lines[2], "galleries 12  samples 47,200  points received 1,234,567,890");
  EXPECT_EQ(lines[3], "call memory held 1,900 MiB  peak 2,047 MiB  budget 2,048 MiB");
  EXPECT_EQ(lines[4], "");
  // The waits beside the latency; "-" for a method whose calls queued nothing.
  EXPECT_EQ(lines[5], "METHOD             CALLS  ERRORS     P50     P99  WAIT P50  WAIT P99");
  EXPECT_EQ(lines[6], "ClassifyCloud  1,204,331      12  710 µs  2.4 ms     15 µs     31 ms");
  EXPECT_EQ(lines[7], "Train                  0       0       -       -         -         -");
  EXPECT_EQ(lines[8], "");
  // The queued work's estimated CPU time, and how many callers it is from.
  EXPECT_EQ(lines[9], "WORK   WORKERS  RUNNING  QUEUED  ESTIMATED  CALLERS");
  EXPECT_EQ(lines[10], "cheap        2        2       0          0        0");
  EXPECT_EQ(lines[11], "heavy        1        1   1,234     61.7 s        3");
  EXPECT_EQ(lines[12], "store        2        0       0          0        0");
  EXPECT_EQ(lines[13], "");
  EXPECT_EQ(lines[14], "GALLERY  SAMPLES  VERSION");
  EXPECT_EQ(err_.contents(), "");
}

TEST_F(SchedulerStatsTest, StatsJsonCarriesWaitsLanesAndMemoryInBytes) {
  ASSERT_EQ(RunStats(Context(OutputFormat::kJson)), kExitOk) << err_.contents();
  EXPECT_EQ(PythonOnJsonLines(out_.contents(),
                              "[(r[\"memory_budget_bytes\"], r[\"memory_held_bytes\"], "
                              "r[\"memory_held_peak_bytes\"], r[\"caller_backlog_seconds\"], "
                              "r[\"callers_with_backlog\"], r[\"work\"]) for r in rows]"),
            "[(2147483648, 1992294400, 2146435072, 61.7, 3, "
            "[{'lane': 'cheap', 'workers': 2, 'running': 2, 'queued': 0, "
            "'queued_work_seconds': 0, 'queued_callers': 0}, "
            "{'lane': 'heavy', 'workers': 1, 'running': 1, 'queued': 1234, "
            "'queued_work_seconds': 61.7, 'queued_callers': 3}, "
            "{'lane': 'store', 'workers': 2, 'running': 0, 'queued': 0, "
            "'queued_work_seconds': 0, 'queued_callers': 0}])]");
  EXPECT_EQ(PythonOnJsonLines(out_.contents(),
                              "[[(m[\"method\"], m[\"latency_p99_seconds\"], "
                              "m[\"wait_p50_seconds\"], m[\"wait_p99_seconds\"]) "
                              "for m in r[\"methods\"]] for r in rows]"),
            "[[('ClassifyCloud', 0.0024, 1.5e-05, 0.031), ('Train', None, None, None)]]");
}

TEST_F(SchedulerStatsTest, StatsCsvAddsTheWaitColumns) {
  ASSERT_EQ(RunStats(Context(OutputFormat::kCsv)), kExitOk) << err_.contents();
  EXPECT_EQ(out_.contents(),
            "method,calls,errors,latency_p50_seconds,latency_p99_seconds,wait_p50_seconds,"
            "wait_p99_seconds\r\n"
            "ClassifyCloud,1204331,12,0.00071,0.0024,1.5e-05,0.031\r\n"
            "Train,0,0,,,,\r\n");
}

TEST_F(SchedulerStatsTest, AnIdleServerWithoutABudgetShowsItsLanes) {
  v1::ServerStats stats;
  for (const char* name : {"cheap", "heavy", "store"}) {
    v1::WorkLaneStats* lane = stats.add_work();
    lane->set_lane(name);
    lane->set_workers(1);
  }
  FakeOperationsService idle(stats);
  std::string target;
  std::unique_ptr<grpc::Server> server = client_testing::StartFakeServer(&idle, &target);
  CliContext context = Context();
  context.client.target = target;
  ASSERT_EQ(RunStats(context), kExitOk) << err_.contents();
  EXPECT_THAT(out_.contents(),
              AllOf(HasSubstr("\ncall memory held 0 MiB  peak 0 MiB  budget none\n\nno calls yet\n"
                              "\nWORK   WORKERS  RUNNING  QUEUED  ESTIMATED  CALLERS\n"
                              "cheap        1        0       0          0        0\n"),
                    Not(HasSubstr("GALLERY"))));
  Captured json;
  context.out = json.get();
  context.format = OutputFormat::kJson;
  ASSERT_EQ(RunStats(context), kExitOk) << err_.contents();
  EXPECT_EQ(PythonOnJsonLines(json.contents(),
                              "[(r[\"memory_budget_bytes\"], len(r[\"work\"]), r[\"methods\"]) "
                              "for r in rows]"),
            "[(0, 3, [])]");
  server->Shutdown();
}

// BusyServer, from before the scheduler, keeps its output (the tests above); none of the new
// JSON keys either, rather than zeros that would read as "no budget".
TEST_F(OperationsCommandsTest, AServerWithoutTheSchedulerGetsNoWaitLaneOrMemoryFigures) {
  ASSERT_EQ(RunStats(Context(OutputFormat::kJson)), kExitOk) << err_.contents();
  EXPECT_EQ(
      PythonOnJsonLines(out_.contents(),
                        "[sorted(k for k in r if \"work\" in k or k.startswith(\"memory_\")) + "
                        "sorted(k for m in r[\"methods\"] for k in m if \"wait\" in k) "
                        "for r in rows]"),
      "[[]]");
}

TEST(OperationsFormatTest, MemoryInMib) {
  EXPECT_EQ(FormatMib(0), "0 MiB");
  EXPECT_EQ(FormatMib(4096), "<0.1 MiB");
  EXPECT_EQ(FormatMib(uint64_t{7} << 19), "3.5 MiB");
  EXPECT_EQ(FormatMib(uint64_t{2048} << 20), "2,048 MiB");
  EXPECT_EQ(FormatMib((uint64_t{100} << 20) - 1), "100 MiB");
}

TEST(OperationsFormatTest, NumbersForPeople) {
  EXPECT_EQ(GroupDigits(0), "0");
  EXPECT_EQ(GroupDigits(999), "999");
  EXPECT_EQ(GroupDigits(1000), "1,000");
  EXPECT_EQ(GroupDigits(48112), "48,112");
  EXPECT_EQ(GroupDigits(18446744073709551615u), "18,446,744,073,709,551,615");
  EXPECT_EQ(FormatUptime(45), "45s");
  EXPECT_EQ(FormatUptime(12 * 60 + 5), "12m5s");
  EXPECT_EQ(FormatUptime(2 * 3600 + 13 * 60 + 59), "2h13m");
  EXPECT_EQ(FormatUptime(3 * 86400 + 4 * 3600 + 1), "3d4h");
  EXPECT_EQ(FormatBytes(512), "512 B");
  EXPECT_EQ(FormatBytes(3300), "3.2 KiB");
  EXPECT_EQ(FormatBytes(uint64_t{412} << 20), "412 MiB");
  EXPECT_EQ(FormatBytes(uint64_t{3} << 29), "1.5 GiB");
}

}  // namespace
}  // namespace shapeid
