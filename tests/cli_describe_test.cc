// End-to-end tests of `shapeid describe`: run the built binary on generated files and check
// what a script would rely on: output formats, exit codes and one error line per failed file.

#include <sys/wait.h>

#include <cctype>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>
#include <string>
#include <vector>

#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "absl/strings/str_split.h"
#include "absl/strings/strip.h"
#include "core/io/io_testing.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "tests/cli_runner.h"

namespace shapeid {
namespace {

namespace fs = std::filesystem;

using ::testing::HasSubstr;
using ::testing::StartsWith;

constexpr char kSpec[] = "rphsd:refs=cross7,bins=10";

std::vector<std::string> Lines(const std::string& text) {
  std::vector<std::string> lines = absl::StrSplit(text, '\n');
  if (!lines.empty() && lines.back().empty()) lines.pop_back();
  return lines;
}

// A deterministic, irregular shape: 300 points on a squashed, twisted ellipsoid.
std::vector<float> Shape(float scale) {
  std::vector<float> xyz;
  for (int i = 0; i < 300; ++i) {
    const double t = 2.399963 * i, h = 1.0 - 2.0 * (i + 0.5) / 300;
    const double r = std::sqrt(1 - h * h);
    xyz.push_back(static_cast<float>(scale * 2.0 * r * std::cos(t + h)));
    xyz.push_back(static_cast<float>(scale * r * std::sin(t)));
    xyz.push_back(static_cast<float>(scale * 0.5 * h * (1.2 + std::cos(t))));
  }
  return xyz;
}

std::string BinaryPcd(const std::vector<float>& xyz, int width, int height) {
  std::string file = absl::StrCat(
      "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH ", width, "\nHEIGHT ",
      height, "\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS ", width * height, "\nDATA binary\n");
  for (float v : xyz) AppendBytes(&file, v);
  return file;
}

std::string Xyz(const std::vector<float>& xyz) {
  std::string file = "# x y z\n";
  for (size_t i = 0; i < xyz.size(); i += 3) {
    absl::StrAppend(&file, xyz[i], " ", xyz[i + 1], " ", xyz[i + 2], "\n");
  }
  return file;
}

// A small JSON syntax checker: enough to know that a line is one valid JSON value.
class JsonChecker {
 public:
  explicit JsonChecker(absl::string_view text) : s_(text) {}
  bool Valid() { return Value() && (Space(), pos_ == s_.size()); }

 private:
  void Space() {
    while (pos_ < s_.size() && (s_[pos_] == ' ' || s_[pos_] == '\t')) ++pos_;
  }
  bool Eat(char c) {
    Space();
    if (pos_ < s_.size() && s_[pos_] == c) return ++pos_, true;
    return false;
  }
  bool Value() {
    Space();
    if (pos_ >= s_.size()) return false;
    const char c = s_[pos_];
    if (c == '{') return Container('}', true);
    if (c == '[') return Container(']', false);
    if (c == '"') return String();
    for (absl::string_view word : {"true", "false", "null"}) {
      if (s_.substr(pos_, word.size()) == word) return pos_ += word.size(), true;
    }
    return Number();
  }
  bool Container(char close, bool object) {
    ++pos_;
    if (Eat(close)) return true;
    do {
      if (object && !(Space(), String() && Eat(':'))) return false;
      if (!Value()) return false;
    } while (Eat(','));
    return Eat(close);
  }
  bool String() {
    if (pos_ >= s_.size() || s_[pos_] != '"') return false;
    for (++pos_; pos_ < s_.size(); ++pos_) {
      const unsigned char c = static_cast<unsigned char>(s_[pos_]);
      if (c < 0x20) return false;
      if (c == '\\') {
        ++pos_;
        if (pos_ >= s_.size()) return false;
        if (s_[pos_] == 'u') {
          if (pos_ + 4 >= s_.size()) return false;
          for (int i = 1; i <= 4; ++i) {
            if (!std::isxdigit(static_cast<unsigned char>(s_[pos_ + i]))) return false;
          }
          pos_ += 4;
        } else if (absl::string_view("\"\\/bfnrt").find(s_[pos_]) == absl::string_view::npos) {
          return false;
        }
      } else if (c == '"') {
        return ++pos_, true;
      }
    }
    return false;
  }
  bool Number() {  // -?(0|[1-9]d*)(.d+)?([eE][+-]?d+)?
    const size_t start = pos_;
    auto digits = [&] {
      const size_t from = pos_;
      while (pos_ < s_.size() && std::isdigit(static_cast<unsigned char>(s_[pos_]))) ++pos_;
      return pos_ > from;
    };
    if (pos_ < s_.size() && s_[pos_] == '-') ++pos_;
    if (pos_ < s_.size() && s_[pos_] == '0') {
      ++pos_;
    } else if (!digits()) {
      return false;
    }
    if (pos_ < s_.size() && s_[pos_] == '.' && (++pos_, !digits())) return false;
    if (pos_ < s_.size() && (s_[pos_] == 'e' || s_[pos_] == 'E')) {
      ++pos_;
      if (pos_ < s_.size() && (s_[pos_] == '+' || s_[pos_] == '-')) ++pos_;
      if (!digits()) return false;
    }
    return pos_ > start;
  }

  absl::string_view s_;
  size_t pos_ = 0;
};

std::vector<float> ParseFloats(const std::vector<absl::string_view>& fields) {
  std::vector<float> values;
  for (absl::string_view f : fields) {
    float v = 0;
    EXPECT_TRUE(absl::SimpleAtof(f, &v)) << "not a float: \"" << f << "\"";
    EXPECT_TRUE(std::isfinite(v)) << f;
    values.push_back(v);
  }
  return values;
}

// The values of a text line whose first field is `file`.
std::vector<float> TextValues(const std::string& line, const std::string& file) {
  EXPECT_THAT(line, StartsWith(file + " "));
  if (line.size() <= file.size()) return {};
  const std::vector<absl::string_view> fields =
      absl::StrSplit(absl::string_view(line).substr(file.size() + 1), ' ');
  return ParseFloats(fields);
}

TEST(CliDescribeTest, TextOutputHasOneLinePerFile) {
  const std::string pcd = WriteTempFile("shape.pcd", BinaryPcd(Shape(1), 300, 1));
  const std::string xyz = WriteTempFile("shape.xyz", Xyz(Shape(3)));
  const RunResult run = Shapeid({"describe", "--local", "--spec", kSpec, pcd, xyz});
  ASSERT_EQ(run.exit_code, 0) << run.err;
  EXPECT_EQ(run.err, "");
  const std::vector<std::string> lines = Lines(run.out);
  ASSERT_EQ(lines.size(), 2u) << run.out;
  const std::vector<float> a = TextValues(lines[0], pcd);
  const std::vector<float> b = TextValues(lines[1], xyz);
  EXPECT_GT(a.size(), 0u);
  EXPECT_EQ(a.size(), b.size());
}

TEST(CliDescribeTest, JsonLinesCarryTheSameValues) {
  const std::string pcd = WriteTempFile("shape \"quoted\".pcd", BinaryPcd(Shape(1), 300, 1));
  const RunResult text = Shapeid({"describe", "--local", "--spec", kSpec, pcd});
  const RunResult json = Shapeid({"describe", "--local", "--spec", kSpec, "--format", "json", pcd});
  ASSERT_EQ(text.exit_code, 0) << text.err;
  ASSERT_EQ(json.exit_code, 0) << json.err;
  const std::vector<std::string> lines = Lines(json.out);
  ASSERT_EQ(lines.size(), 1u) << json.out;
  const std::string& line = lines[0];
  EXPECT_TRUE(JsonChecker(line).Valid()) << line;
  EXPECT_THAT(line, StartsWith("{\"file\":"));
  EXPECT_THAT(line, HasSubstr("shape \\\"quoted\\\".pcd\""));
  EXPECT_THAT(line, HasSubstr("\"spec\":\"rphsd:"));  // canonical: every parameter filled
  EXPECT_THAT(line, HasSubstr("\"dimension\":"));
  EXPECT_THAT(line, HasSubstr("\"descriptor\":["));

  // The dimension and the array agree, and the values equal the text output's.
  const size_t dim_at = line.find("\"dimension\":") + 12;
  const size_t array_at = line.find("\"descriptor\":[") + 14;
  size_t dimension = 0;
  ASSERT_TRUE(absl::SimpleAtoi(line.substr(dim_at, line.find(',', dim_at) - dim_at), &dimension));
  const std::string array = line.substr(array_at, line.rfind(']') - array_at);
  const std::vector<float> values = ParseFloats(absl::StrSplit(array, ','));
  EXPECT_EQ(values.size(), dimension);
  EXPECT_EQ(values, TextValues(Lines(text.out).at(0), pcd));
}

TEST(CliDescribeTest, MissingFileFailsAloneAndExitsOne) {
  const std::string good = WriteTempFile("good.pcd", BinaryPcd(Shape(1), 300, 1));
  const std::string missing = testing::TempDir() + "shapeid_cli_no_such_file.pcd";
  const std::string also_good = WriteTempFile("also_good.xyz", Xyz(Shape(2)));
  const RunResult run = Shapeid({"describe", "--local", "--spec", kSpec, good, missing, also_good});
  EXPECT_EQ(run.exit_code, 1);
  const std::vector<std::string> out = Lines(run.out);
  ASSERT_EQ(out.size(), 2u) << run.out;
  EXPECT_THAT(out[0], StartsWith(good + " "));
  EXPECT_THAT(out[1], StartsWith(also_good + " "));
  const std::vector<std::string> err = Lines(run.err);
  ASSERT_EQ(err.size(), 1u) << run.err;
  EXPECT_THAT(err[0], StartsWith("shapeid: " + missing + ": "));
}

TEST(CliDescribeTest, NonFinitePointsFailUnlessDropped) {
  std::vector<float> xyz = Shape(1);
  for (int i = 0; i < 3; ++i) xyz[30 + i] = std::numeric_limits<float>::quiet_NaN();
  const std::string organized = WriteTempFile("organized.pcd", BinaryPcd(xyz, 30, 10));
  const RunResult kept = Shapeid({"describe", "--local", "--spec", kSpec, organized});
  EXPECT_EQ(kept.exit_code, 1);
  EXPECT_EQ(kept.out, "");
  EXPECT_THAT(kept.err, StartsWith("shapeid: " + organized + ": "));
  EXPECT_THAT(kept.err,
              HasSubstr("point 10 has a non-finite coordinate (x is nan); 1 of 300 points"));
  EXPECT_THAT(kept.err, HasSubstr("--drop-nonfinite removes them"));
  const RunResult dropped =
      Shapeid({"describe", "--local", "--spec", kSpec, "--drop-nonfinite", organized});
  EXPECT_EQ(dropped.exit_code, 0) << dropped.err;
  EXPECT_EQ(Lines(dropped.out).size(), 1u);
}

TEST(CliDescribeTest, StandardInputWithAnInputFormat) {
  const std::string pcd = WriteTempFile("piped.pcd", BinaryPcd(Shape(1), 300, 1));
  const RunResult file = Shapeid({"describe", "--local", "--spec", kSpec, pcd});
  ASSERT_EQ(file.exit_code, 0) << file.err;
  const RunResult piped =
      Shapeid({"describe", "--local", "--spec", kSpec, "--input-format", "pcd", "-"}, pcd);
  ASSERT_EQ(piped.exit_code, 0) << piped.err;
  EXPECT_EQ(TextValues(Lines(piped.out).at(0), "-"), TextValues(Lines(file.out).at(0), pcd));
  // Without the format, a usage error (exit 2) in one clear line naming the flag, from every
  // command that reads clouds, before any is read or sent.
  const RunResult unnamed = Shapeid({"describe", "--local", "--spec", kSpec, "-"}, pcd);
  EXPECT_EQ(unnamed.exit_code, 2);
  EXPECT_EQ(unnamed.out, "");
  EXPECT_THAT(unnamed.err,
              StartsWith("shapeid: describe: standard input (\"-\") has no extension"));
  EXPECT_THAT(unnamed.err, HasSubstr("--input-format (pcd, ply,"));
  for (const std::vector<std::string>& command :
       std::vector<std::vector<std::string>>{{"train", "--gallery", "g", "--label", "box", "-"},
                                             {"classify", "--gallery", "g", "-"},
                                             {"scene", "--gallery", "g", "-"}}) {
    const RunResult run = Shapeid(command, pcd);
    EXPECT_EQ(run.exit_code, 2) << command[0] << ": " << run.err;
    EXPECT_THAT(run.err, HasSubstr("--input-format (pcd, ply,")) << command[0];
  }
  const RunResult unknown =
      Shapeid({"describe", "--local", "--spec", kSpec, "--input-format", "e57", "-"}, pcd);
  EXPECT_EQ(unknown.exit_code, 2);
}

TEST(CliDescribeTest, AFoldersOtherFilesAreListedAndFailTheRunUnlessSkipped) {
  const std::string pcd = WriteTempFile("mixed_dir_shape.pcd", BinaryPcd(Shape(1), 300, 1));
  const fs::path dir = fs::path(testing::TempDir()) / "shapeid_cli_mixed_folder";
  fs::remove_all(dir);
  fs::create_directories(dir);
  fs::copy_file(pcd, dir / "shape.pcd");
  std::ofstream(dir / "notes.md") << "# notes\n";
  std::ofstream(dir / "tile.laz") << "LASF";
  const RunResult listed = Shapeid({"describe", "--local", "--spec", kSpec, dir.string()});
  EXPECT_EQ(listed.exit_code, 1);
  EXPECT_EQ(Lines(listed.out).size(), 1u) << listed.out;
  EXPECT_THAT(listed.err,
              HasSubstr("2 files are in no format shapeid reads and were not "
                        "processed: " +
                        (dir / "notes.md").string() + ", " + (dir / "tile.laz").string()));
  EXPECT_THAT(listed.err, HasSubstr("--skip-unsupported"));
  const RunResult skipped =
      Shapeid({"describe", "--local", "--spec", kSpec, "--skip-unsupported", dir.string()});
  EXPECT_EQ(skipped.exit_code, 0) << skipped.err;
  EXPECT_EQ(skipped.err, "");
  EXPECT_EQ(Lines(skipped.out).size(), 1u);
}

TEST(CliDescribeTest, TheSensorFrameTurnsACameraCloudUpright) {
  // The shape as a camera with y down sees it: its up (+z) is the camera's -y.
  const std::vector<float> upright = Shape(1);
  std::vector<float> camera;
  for (size_t i = 0; i < upright.size(); i += 3) {
    camera.insert(camera.end(), {upright[i], -upright[i + 2], upright[i + 1]});
  }
  const std::string upright_file = WriteTempFile("upright.pcd", BinaryPcd(upright, 300, 1));
  const std::string camera_file = WriteTempFile("camera.pcd", BinaryPcd(camera, 300, 1));
  const std::string spec = "dfsd:frame=upright";
  const RunResult expected = Shapeid({"describe", "--local", "--spec", spec, upright_file});
  ASSERT_EQ(expected.exit_code, 0) << expected.err;
  const std::vector<float> want = TextValues(Lines(expected.out).at(0), upright_file);
  for (const std::vector<std::string>& flags :
       {std::vector<std::string>{"--sensor-up", "0,-1,0"},
        {"--sensor-transform", "1,0,0,0, 0,0,1,0, 0,-1,0,0"}}) {
    std::vector<std::string> args = {"describe", "--local", "--spec", spec};
    args.insert(args.end(), flags.begin(), flags.end());
    args.push_back(camera_file);
    const RunResult run = Shapeid(args);
    ASSERT_EQ(run.exit_code, 0) << run.err;
    const std::vector<float> got = TextValues(Lines(run.out).at(0), camera_file);
    ASSERT_EQ(got.size(), want.size());
    for (size_t v = 0; v < got.size(); ++v) {
      EXPECT_NEAR(got[v], want[v], 1e-3 * (1 + std::abs(want[v]))) << flags[0] << " value " << v;
    }
  }
  const RunResult unturned = Shapeid({"describe", "--local", "--spec", spec, camera_file});
  EXPECT_NE(TextValues(Lines(unturned.out).at(0), camera_file), want);
  // Usage errors, before any file is read.
  for (const std::vector<std::string>& flags :
       {std::vector<std::string>{"--sensor-up", "0,0"},
        {"--sensor-up", "0,0,0"},
        {"--sensor-up", "0,up,0"},
        {"--sensor-transform", "2,0,0,0,0,1,0,0,0,0,1,0"},
        {"--sensor-up", "0,0,1", "--sensor-transform", "1,0,0,0,0,1,0,0,0,0,1,0"}}) {
    std::vector<std::string> args = {"describe", "--local", "--spec", spec};
    args.insert(args.end(), flags.begin(), flags.end());
    args.push_back(camera_file);
    const RunResult run = Shapeid(args);
    EXPECT_EQ(run.exit_code, 2) << absl::StrJoin(flags, " ");
    EXPECT_EQ(run.out, "");
    EXPECT_THAT(run.err, HasSubstr("--sensor-")) << run.err;
  }
}

TEST(CliDescribeTest, BadSpecExitsTwoBeforeReadingFiles) {
  const std::string good = WriteTempFile("good.pcd", BinaryPcd(Shape(1), 300, 1));
  for (const char* spec : {"rphsd:nosuchparam=1", "nosuchkind", "rphsd:bins"}) {
    const RunResult run = Shapeid({"describe", "--local", "--spec", spec, good});
    EXPECT_EQ(run.exit_code, 2) << spec;
    EXPECT_EQ(run.out, "") << spec;
    EXPECT_EQ(Lines(run.err).size(), 1u) << run.err;
  }
}

TEST(CliDescribeTest, WithoutLocalAskTheServerAndSayWhenItIsDown) {
  const std::string good = WriteTempFile("good.pcd", BinaryPcd(Shape(1), 300, 1));
  const RunResult run = Shapeid({"--server", "127.0.0.1:1", "--timeout", "2", "describe", good});
  EXPECT_EQ(run.exit_code, 3);
  EXPECT_EQ(run.out, "");
  EXPECT_EQ(Lines(run.err).size(), 1u) << run.err;
  EXPECT_THAT(run.err, HasSubstr("SHAPEID_SERVER"));
}

TEST(CliDescribeTest, UsageErrorsExitTwo) {
  const std::string good = WriteTempFile("good.pcd", BinaryPcd(Shape(1), 300, 1));
  for (const std::vector<std::string>& args : {std::vector<std::string>{},
                                               {"describe", "--local"},
                                               {"describe", "--local", "--format", "xml", good},
                                               {"frobnicate"}}) {
    const RunResult run = Shapeid(args);
    EXPECT_EQ(run.exit_code, 2) << absl::StrJoin(args, " ");
    EXPECT_EQ(run.out, "");
    EXPECT_EQ(Lines(run.err).size(), 1u) << run.err;
  }
}

TEST(CliDescribeTest, HelpAndVersion) {
  const RunResult help = Shapeid({"describe", "--help"});
  EXPECT_EQ(help.exit_code, 0);
  for (const char* kind : {"rphsd", "comsd", "cnsd", "--spec", "--format", "Examples"}) {
    EXPECT_THAT(help.out, HasSubstr(kind));
  }
  const RunResult top = Shapeid({"--help"});
  EXPECT_EQ(top.exit_code, 0);
  EXPECT_THAT(top.out, HasSubstr("describe"));
  const RunResult version = Shapeid({"--version"});
  EXPECT_EQ(version.exit_code, 0);
  EXPECT_THAT(version.out, StartsWith("shapeid "));
}

}  // namespace
}  // namespace shapeid
