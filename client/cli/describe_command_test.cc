#include "client/cli/describe_command.h"

#include <cstdio>
#include <string>

#include "absl/strings/numbers.h"
#include "absl/strings/str_split.h"
#include "core/descriptors/rphsd.h"
#include "core/io/io_testing.h"
#include "core/io/pcd_writer.h"
#include "core/testing/test_clouds.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"

namespace shapeid {
namespace {

using ::testing::HasSubstr;
using ::testing::StartsWith;

// A FILE* whose contents tests can read back.
class CapturedFile {
 public:
  CapturedFile() : file_(std::tmpfile()) {}
  ~CapturedFile() { std::fclose(file_); }
  std::FILE* get() { return file_; }
  std::string contents() {
    std::fflush(file_);
    std::rewind(file_);
    std::string text;
    char buffer[4096];
    for (size_t n; (n = std::fread(buffer, 1, sizeof buffer, file_)) > 0;) text.append(buffer, n);
    return text;
  }

 private:
  std::FILE* file_;
};

TEST(DescribeCommandTest, TextLineRoundTripsFloats) {
  const float values[] = {0.1f, 1.0f / 3.0f, 0.0f, -2.5e-8f, 123456792.0f};
  const std::string line = FormatTextLine("dir/chair 1.pcd", values);
  EXPECT_THAT(line, StartsWith("dir/chair 1.pcd 0.100000001 0.333333343 0 -2.50000003e-08 "));
  ASSERT_EQ(line.back(), '\n');
  const std::vector<absl::string_view> fields =
      absl::StrSplit(absl::string_view(line).substr(16, line.size() - 17), ' ');
  ASSERT_EQ(fields.size(), 5u);
  for (size_t i = 0; i < fields.size(); ++i) {
    float parsed = 0;
    ASSERT_TRUE(absl::SimpleAtof(fields[i], &parsed)) << fields[i];
    EXPECT_EQ(parsed, values[i]);
  }
}

TEST(DescribeCommandTest, JsonLine) {
  const float values[] = {0.5f, 0.25f};
  EXPECT_EQ(FormatJsonLine("a.pcd", "rphsd:bins=2", values),
            "{\"file\":\"a.pcd\",\"spec\":\"rphsd:bins=2\",\"dimension\":2,"
            "\"descriptor\":[0.5,0.25]}\n");
  EXPECT_EQ(FormatJsonLine("e.pcd", "k", {}),
            "{\"file\":\"e.pcd\",\"spec\":\"k\",\"dimension\":0,\"descriptor\":[]}\n");
}

TEST(DescribeCommandTest, FileErrorLineDoesNotRepeatTheFileName) {
  EXPECT_EQ(FileErrorLine("a.pcd", absl::InvalidArgumentError("a.pcd: line 3: bad")),
            "shapeid: a.pcd: line 3: bad\n");
  EXPECT_EQ(FileErrorLine("a.pcd", absl::InvalidArgumentError("cloud has 2 points")),
            "shapeid: a.pcd: cloud has 2 points\n");
}

TEST(DescribeCommandTest, BadSpecIsAUsageErrorBeforeAnyFile) {
  CapturedFile out, err;
  DescribeOptions options;
  options.local = true;
  options.spec = "nosuchdescriptor:x=1";
  options.files = {"/nonexistent/a.pcd"};
  CliContext context;
  context.out = out.get();
  context.err = err.get();
  EXPECT_EQ(RunDescribe(options, context), kExitUsage);
  const std::string message = err.contents();
  EXPECT_THAT(message, HasSubstr("nosuchdescriptor"));
  EXPECT_THAT(message, Not(HasSubstr("a.pcd")));

  EXPECT_EQ(std::count(message.begin(), message.end(), '\n'), 1);
}

// --threads splits a large cloud (RPHSD from 2 x kMinPointsPerThread points) without changing
// a digit of the output.
TEST(DescribeCommandTest, LocalThreadsGiveTheSameLine) {
  const std::string path = WriteTempFile("describe_threads.pcd", "");
  const size_t points = 2 * static_cast<size_t>(Rphsd::kMinPointsPerThread) + 5;
  ASSERT_TRUE(WritePcd(path, testing_clouds::ShapeCloud(1, 7, points), PcdEncoding::kBinary).ok());
  std::string lines[2];
  for (const int threads : {1, 2}) {
    CapturedFile out, err;
    DescribeOptions options;
    options.local = true;
    options.spec = "rphsd";
    options.threads = threads;
    options.files = {path};
    CliContext context;
    context.out = out.get();
    context.err = err.get();
    ASSERT_EQ(RunDescribe(options, context), kExitOk) << err.contents();
    lines[threads - 1] = out.contents();
  }
  EXPECT_THAT(lines[0], StartsWith(path + " "));
  EXPECT_EQ(lines[1], lines[0]);
}

TEST(DescribeCommandTest, HelpFooterListsKindsAndExamples) {
  const std::string footer = DescribeHelpFooter();
  for (const char* kind : {"rphsd", "comsd", "cnsd"}) EXPECT_THAT(footer, HasSubstr(kind));
  EXPECT_THAT(footer, HasSubstr("shapeid describe --local"));
}

}  // namespace
}  // namespace shapeid
