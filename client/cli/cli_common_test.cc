#include "client/cli/cli_common.h"

#include <atomic>
#include <cstdio>
#include <string>
#include <vector>

#include "gmock/gmock.h"
#include "gtest/gtest.h"

namespace shapeid {
namespace {

using ::testing::HasSubstr;

std::string Contents(std::FILE* file) {
  std::fflush(file);
  std::rewind(file);
  std::string text;
  char buffer[4096];
  size_t n;
  while ((n = std::fread(buffer, 1, sizeof buffer, file)) > 0) text.append(buffer, n);
  return text;
}

TEST(CliCommonTest, OutputFormats) {
  EXPECT_EQ(*ParseOutputFormat("table"), OutputFormat::kTable);
  EXPECT_EQ(*ParseOutputFormat("text"), OutputFormat::kTable);
  EXPECT_EQ(*ParseOutputFormat("json"), OutputFormat::kJson);
  EXPECT_EQ(*ParseOutputFormat("csv"), OutputFormat::kCsv);
  EXPECT_TRUE(absl::IsInvalidArgument(ParseOutputFormat("xml").status()));
}

TEST(CliCommonTest, RequestIdsAreRandomAndValid) {
  const std::string a = NewRequestId(), b = NewRequestId();
  EXPECT_THAT(a, ::testing::MatchesRegex("cli-[0-9a-f]{16}"));
  EXPECT_NE(a, b);
  EXPECT_TRUE(CheckRequestId(a).ok());
}

TEST(CliCommonTest, ACallErrorEndsWithItsRequestId) {
  CliContext context;
  context.err = std::tmpfile();
  context.client.target = "10.0.0.1:50051";
  PrintCallError(context, "gallery show parts", absl::NotFoundError("no gallery \"parts\""));
  context.client.request_id = "cli-0123456789abcdef";
  PrintCallError(context, "stats", absl::UnavailableError("connection refused"));
  EXPECT_EQ(Contents(context.err),
            "shapeid: gallery show parts: no gallery \"parts\"\n"
            "shapeid: stats: connection refused (is shapeid-server running at 10.0.0.1:50051? set "
            "--server or SHAPEID_SERVER; a TLS server needs --tls-ca) [request id "
            "cli-0123456789abcdef]\n");
  std::fclose(context.err);
}

TEST(CliCommonTest, ExitCodesSeparateUnreachableFromRefused) {
  EXPECT_EQ(ExitCodeForStatus(absl::OkStatus()), kExitOk);
  EXPECT_EQ(ExitCodeForStatus(absl::UnavailableError("down")), kExitUnreachable);
  EXPECT_EQ(ExitCodeForStatus(absl::DeadlineExceededError("slow")), kExitUnreachable);
  EXPECT_EQ(ExitCodeForStatus(absl::NotFoundError("no gallery")), kExitRefused);
  EXPECT_EQ(ExitCodeForStatus(absl::InvalidArgumentError("bad")), kExitRefused);
}

TEST(CliCommonTest, OnlyServerWideErrorsStopABatch) {
  EXPECT_TRUE(StopsBatch(absl::UnavailableError("")));
  EXPECT_TRUE(StopsBatch(absl::NotFoundError("")));
  EXPECT_TRUE(StopsBatch(absl::FailedPreconditionError("")));
  EXPECT_TRUE(StopsBatch(absl::PermissionDeniedError("")));
  EXPECT_FALSE(StopsBatch(absl::InvalidArgumentError("cloud has 2 points")));
  EXPECT_FALSE(StopsBatch(absl::ResourceExhaustedError("too many points")));
}

TEST(CliCommonTest, TableAlignsColumnsAndTrimsTrailingSpace) {
  Table table{{"NAME", "N"}, {{"a", "1"}, {"longer", "100"}}, {false, true}};
  EXPECT_EQ(RenderTable(table),
            "NAME      N\n"
            "a         1\n"
            "longer  100\n");
  // Widths count code points: "é" is one column.
  Table utf{{"X", "Y"}, {{"\xc3\xa9", "1"}}, {}};
  EXPECT_EQ(RenderTable(utf), "X  Y\n\xc3\xa9  1\n");
}

TEST(CliCommonTest, CsvQuotesOnlyWhenNeeded) {
  EXPECT_EQ(CsvField("plain"), "plain");
  EXPECT_EQ(CsvField("a,b"), "\"a,b\"");
  EXPECT_EQ(CsvField("say \"hi\""), "\"say \"\"hi\"\"\"");
  EXPECT_EQ(CsvField("two\nlines"), "\"two\nlines\"");
  Table table{{"a", "b"}, {{"1", "x,y"}}, {}};
  EXPECT_EQ(RenderCsv(table), "a,b\r\n1,\"x,y\"\r\n");
}

TEST(CliCommonTest, HumanUnits) {
  EXPECT_EQ(FormatSeconds(0.000250), "250 µs");
  EXPECT_EQ(FormatSeconds(0.0123), "12.3 ms");
  EXPECT_EQ(FormatSeconds(2.5), "2.5 s");
  EXPECT_EQ(FormatPercent(0.91666), "91.67");
}

TEST(CliCommonTest, UnreachableErrorSaysHowToPointAtTheServer) {
  std::FILE* err = std::tmpfile();
  PrintError(err, "classify parts", absl::UnavailableError("failed to connect"), "host:1");
  const std::string text = Contents(err);
  EXPECT_THAT(text, HasSubstr("shapeid: classify parts: failed to connect"));
  EXPECT_THAT(text, HasSubstr("SHAPEID_SERVER"));
  EXPECT_EQ(text.back(), '\n');
  std::fclose(err);
}

TEST(CliCommonTest, ProgressWithoutTerminalPrintsPlainLinesOnlyWhenSlow) {
  std::FILE* err = std::tmpfile();
  {
    Progress progress(err, ProgressMode::kAuto, "train", 10);
    for (int i = 0; i < 10; ++i) progress.Advance(1, i == 3 ? 1 : 0);
  }
  // A fast batch on a non-terminal prints nothing (the command's summary follows).
  EXPECT_EQ(Contents(err), "");
  std::fclose(err);
  std::FILE* quiet = std::tmpfile();
  {
    Progress progress(quiet, ProgressMode::kOff, "train", 10);
    progress.Interrupt([&] { std::fputs("an error line\n", quiet); });
    progress.Advance(10, 0);
  }
  EXPECT_EQ(Contents(quiet), "an error line\n");
  std::fclose(quiet);
}

TEST(CliCommonTest, ParallelForVisitsEveryIndexOnceAndStops) {
  std::vector<std::atomic<int>> visits(1000);
  ParallelFor(visits.size(), 4, [&](size_t i) { visits[i]++; });
  for (const auto& v : visits) EXPECT_EQ(v.load(), 1);

  std::atomic<int> done{0};
  std::atomic<bool> stop{false};
  ParallelFor(
      1000, 3,
      [&](size_t i) {
        if (i == 10) stop = true;
        done++;
      },
      [&] { return stop.load(); });
  EXPECT_LT(done.load(), 1000);
  ParallelFor(0, 4, [&](size_t) { FAIL() << "no index to visit"; });
}

}  // namespace
}  // namespace shapeid
