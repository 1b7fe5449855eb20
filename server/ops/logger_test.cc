#include "server/ops/logger.h"

#include <string>
#include <vector>

#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "nlohmann/json.hpp"

namespace shapeid {
namespace {

using ::testing::HasSubstr;
using ::testing::StartsWith;

// A logger whose lines land in `lines`.
Logger Capturing(LoggerOptions options, std::vector<std::string>* lines) {
  return Logger(options, [lines](absl::string_view line) { lines->emplace_back(line); });
}

TEST(LoggerTest, JsonLinesParseWhateverTheFieldsHold) {
  std::vector<std::string> lines;
  const Logger log = Capturing({LogFormat::kJson, LogLevel::kInfo}, &lines);
  // A gallery name as a hostile client might send it: quotes, a newline, a control
  // character, bytes that are not UTF-8.
  const std::string hostile = "a\"b\nc\x01\xff\xfe}{";
  log.Info("rpc", {{"method", "Train"},
                   {"gallery", hostile},
                   {"us", int64_t{712}},
                   {"ratio", 0.25},
                   {"empty", ""}});
  ASSERT_EQ(lines.size(), 1u);
  EXPECT_EQ(lines[0].back(), '\n');
  EXPECT_EQ(lines[0].find('\n'), lines[0].size() - 1) << "one line, whatever the fields hold";
  const nlohmann::json line = nlohmann::json::parse(lines[0]);
  EXPECT_EQ(line["level"], "info");
  EXPECT_EQ(line["msg"], "rpc");
  EXPECT_EQ(line["method"], "Train");
  EXPECT_EQ(line["us"], 712);
  EXPECT_EQ(line["ratio"], 0.25);
  EXPECT_EQ(line["empty"], "");
  // The valid characters survive; the invalid bytes become U+FFFD.
  EXPECT_EQ(line["gallery"], "a\"b\nc\x01\xEF\xBF\xBD\xEF\xBF\xBD}{");
  // RFC 3339 UTC with microseconds.
  EXPECT_THAT(line["time"].get<std::string>(),
              testing::MatchesRegex("[0-9]{4}-[0-9]{2}-[0-9]{2}T[0-9]{2}:[0-9]{2}:"
                                    "[0-9]{2}\\.[0-9]{6}Z"));
}

TEST(LoggerTest, TextLinesQuoteWhatWouldBreakKeyValueParsing) {
  std::vector<std::string> lines;
  const Logger log = Capturing({LogFormat::kText, LogLevel::kInfo}, &lines);
  log.Info("rpc", {{"method", "Classify"},
                   {"gallery", "lab"},
                   {"error", "two words"},
                   {"tricky", "a=b"},
                   {"newline", "x\ny"},
                   {"empty", ""},
                   {"n", 3}});
  ASSERT_EQ(lines.size(), 1u);
  EXPECT_EQ(lines[0],
            "shapeid-server: rpc method=Classify gallery=lab error=\"two words\" "
            "tricky=\"a=b\" newline=\"x\\ny\" n=3\n");
}

TEST(LoggerTest, TextLinesNameTheLevelUnlessInfo) {
  std::vector<std::string> lines;
  const Logger log = Capturing({LogFormat::kText, LogLevel::kDebug}, &lines);
  log.Info("loaded");
  log.Warning("disk is read-only");
  log.Error("cannot load");
  log.Log(LogLevel::kDebug, "detail");
  EXPECT_THAT(lines, testing::ElementsAre("shapeid-server: loaded\n",
                                          "shapeid-server: WARNING: disk is read-only\n",
                                          "shapeid-server: ERROR: cannot load\n",
                                          "shapeid-server: DEBUG: detail\n"));
}

TEST(LoggerTest, AControlCharacterInAMessageCannotStartAForgedLine) {
  std::vector<std::string> lines;
  const Logger log = Capturing({LogFormat::kText, LogLevel::kInfo}, &lines);
  log.Warning("gallery 'x\nshapeid-server: forged' set aside");
  ASSERT_EQ(lines.size(), 1u);
  EXPECT_EQ(lines[0],
            "shapeid-server: WARNING: gallery 'x\\x0ashapeid-server: forged' set aside\n");
}

TEST(LoggerTest, LinesBelowTheLevelAreDroppedAndTheLevelChangesLive) {
  std::vector<std::string> lines;
  Logger log = Capturing({LogFormat::kJson, LogLevel::kWarning}, &lines);
  log.Info("dropped");
  log.Warning("kept");
  EXPECT_FALSE(log.Enabled(LogLevel::kInfo));
  EXPECT_EQ(log.SetLevel(LogLevel::kInfo), LogLevel::kWarning);
  log.Info("kept too");
  EXPECT_EQ(log.SetLevel(LogLevel::kError), LogLevel::kInfo);
  log.Warning("dropped again");
  ASSERT_EQ(lines.size(), 2u);
  EXPECT_THAT(lines[0], HasSubstr("\"msg\":\"kept\""));
  EXPECT_THAT(lines[1], HasSubstr("\"msg\":\"kept too\""));
}

TEST(LoggerTest, ParsesLevelsAndFormatsAndNamesTheChoicesOtherwise) {
  EXPECT_EQ(*ParseLogLevel("debug"), LogLevel::kDebug);
  EXPECT_EQ(*ParseLogLevel("INFO"), LogLevel::kInfo);
  EXPECT_EQ(*ParseLogLevel("Warning"), LogLevel::kWarning);
  EXPECT_EQ(*ParseLogLevel("error"), LogLevel::kError);
  const absl::StatusOr<LogLevel> bad = ParseLogLevel("verbose");
  EXPECT_EQ(bad.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(bad.status().message(), HasSubstr("debug, info, warning, error"));
  EXPECT_EQ(*ParseLogFormat("json"), LogFormat::kJson);
  EXPECT_EQ(*ParseLogFormat("text"), LogFormat::kText);
  EXPECT_THAT(ParseLogFormat("xml").status().message(), HasSubstr("text, json"));
  for (const LogLevel level :
       {LogLevel::kDebug, LogLevel::kInfo, LogLevel::kWarning, LogLevel::kError}) {
    EXPECT_EQ(*ParseLogLevel(LogLevelName(level)), level);
  }
}

TEST(LoggerTest, TheDefaultSinkIsStderr) {
  testing::internal::CaptureStderr();
  Logger log;
  log.Info("to stderr", {{"k", "v"}});
  EXPECT_THAT(testing::internal::GetCapturedStderr(), StartsWith("shapeid-server: to stderr k=v"));
}

}  // namespace
}  // namespace shapeid
