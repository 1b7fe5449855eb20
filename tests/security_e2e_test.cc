// End-to-end security: the real shapeid-server and shapeid binaries, configured as an
// operator would (flags, SHAPEID_* environment, a keys file, certificates made by openssl):
// mutual TLS and API keys through the CLI, the refusal to run open on a network address, the
// key helpers, and no key ever in the server's log or the CLI's output.

#include <sys/wait.h>

#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <string>
#include <vector>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_split.h"
#include "absl/strings/strip.h"
#include "core/io/io_testing.h"
#include "core/testing/test_clouds.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "tests/cli_runner.h"
#include "tests/server_process.h"
#include "tests/test_certificates.h"

namespace shapeid {
namespace {

using ::testing::HasSubstr;
using ::testing::Not;
using testing_clouds::ShapeCloud;

// Runs `command` through the shell; its stdout, and its exit code in `exit_code`.
std::string Shell(const std::string& command, int* exit_code) {
  std::string out;
  FILE* pipe = popen(command.c_str(), "r");
  if (pipe == nullptr) return out;
  char buf[4096];
  size_t n;
  while ((n = std::fread(buf, 1, sizeof(buf), pipe)) > 0) out.append(buf, n);
  const int status = pclose(pipe);
  *exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return out;
}

// What the documentation tells operators to run: printf '%s' KEY | sha256sum.
std::string Sha256sum(const std::string& key) {
  int code = -1;
  const std::string out = Shell("printf '%s' " + ShellQuote(key) + " | sha256sum", &code);
  return out.substr(0, out.find(' '));
}

std::string ServerBinary() { return SHAPEID_SERVER_PATH; }

TEST(SecurityE2ETest, RefusesANetworkAddressWithoutTlsOrKeysInOneLine) {
  ServerProcess server({"--listen=0.0.0.0:0"});
  EXPECT_TRUE(server.address().empty()) << "it must not listen";
  EXPECT_EQ(server.WaitForExit(std::chrono::seconds(10)), 2);
  const std::string log = server.StderrText();
  EXPECT_THAT(log, HasSubstr("refusing to listen on 0.0.0.0:0 with neither TLS nor API keys"));
  EXPECT_EQ(std::count(log.begin(), log.end(), '\n'), 1) << log;
}

// --max_answer_bytes: at least 1 MiB, and at most what the project's clients read.
TEST(SecurityE2ETest, RefusesAMaxAnswerBytesTheClientsCannotRead) {
  for (const char* flag : {"--max_answer_bytes=1000", "--max_answer_bytes=268435457"}) {
    ServerProcess server({flag});
    EXPECT_TRUE(server.address().empty()) << flag << ": it must not listen";
    EXPECT_EQ(server.WaitForExit(std::chrono::seconds(10)), 2) << flag;
    EXPECT_THAT(server.StderrText(),
                HasSubstr("--max_answer_bytes must be from 1048576 (1 MiB, more than one sample "
                          "with the largest provenance) to 268435456 (256 MiB, the most the "
                          "project's clients read)"))
        << flag;
  }
  ServerProcess largest({"--max_answer_bytes=268435456"});
  EXPECT_FALSE(largest.address().empty()) << largest.StderrText();
}

TEST(SecurityE2ETest, NewApiKeyAndHashApiKeyAgreeWithSha256sum) {
  int code = -1;
  const std::string out =
      Shell(ShellQuote(ServerBinary()) + " --new_api_key=robot-1:read 2>/dev/null", &code);
  ASSERT_EQ(code, 0);
  const std::vector<std::string> lines = absl::StrSplit(out, '\n', absl::SkipEmpty());
  ASSERT_EQ(lines.size(), 2u) << out;
  const std::string& key = lines[0];
  EXPECT_EQ(key.rfind("shapeid_", 0), 0u);
  EXPECT_EQ(lines[1], "robot-1 read " + Sha256sum(key));

  const std::string hashed = Shell(
      "printf '%s' " + ShellQuote(key) + " | " + ShellQuote(ServerBinary()) + " --hash_api_key",
      &code);
  EXPECT_EQ(code, 0);
  EXPECT_EQ(absl::StripTrailingAsciiWhitespace(hashed), Sha256sum(key));

  Shell("echo short | " + ShellQuote(ServerBinary()) + " --hash_api_key 2>/dev/null", &code);
  EXPECT_EQ(code, 2) << "a short key is refused";
  Shell(ShellQuote(ServerBinary()) + " --new_api_key=robot:root 2>/dev/null", &code);
  EXPECT_EQ(code, 2) << "an unknown scope is refused";
}

// The CLI against a server with mutual TLS and keys from both a file and the environment.
class SecureCliTest : public ::testing::Test {
 protected:
  static constexpr char kRead[] = "shapeid_e2e_read_5f0c9a1e7b2d4c3f8a6e";
  static constexpr char kWrite[] = "shapeid_e2e_write_91d2b7c4e8f3a6d0c5b1";
  static constexpr char kAdmin[] = "shapeid_e2e_admin_3c7e1a9f5b2d8e4c6a0f";
  static constexpr char kWrong[] = "shapeid_e2e_wrong_0000000000000000000";

  void SetUp() override {
    ASSERT_FALSE(TestCertificates::Dir().empty());
    // Keys as an operator gives them: read and write in the environment, admin in a file.
    setenv(
        "SHAPEID_API_KEYS",
        absl::StrCat("robot read ", Sha256sum(kRead), ";trainer write ", Sha256sum(kWrite)).c_str(),
        1);
    keys_file_ =
        WriteTempFile("keys.txt", absl::StrCat("# operators\nops admin ", Sha256sum(kAdmin), "\n"));
    server_ = std::make_unique<ServerProcess>(std::vector<std::string>{
        "--tls_cert=" + Cert("server.pem"), "--tls_key=" + Cert("server.key"),
        "--tls_client_ca=" + Cert("ca.pem"), "--api_keys_file=" + keys_file_});
    unsetenv("SHAPEID_API_KEYS");
    ASSERT_FALSE(server_->address().empty()) << server_->StderrText();
    // The CLI's TLS settings from the environment, as a robot's service unit would set them.
    setenv("SHAPEID_TLS_CA", Cert("ca.pem").c_str(), 1);
    setenv("SHAPEID_TLS_CLIENT_CERT", Cert("client.pem").c_str(), 1);
    setenv("SHAPEID_TLS_CLIENT_KEY", Cert("client.key").c_str(), 1);
    for (int i = 0; i < 4; ++i) {
      const PointCloud cloud = ShapeCloud(i % 2 == 0 ? 0 : 2, 10 + i, 400);
      std::string text;
      for (size_t p = 0; p < cloud.size(); ++p) {
        absl::StrAppend(&text, cloud.point(p).x(), " ", cloud.point(p).y(), " ", cloud.point(p).z(),
                        "\n");
      }
      files_.push_back(WriteTempFile(absl::StrCat("cloud", i, ".xyz"), text));
    }
  }
  void TearDown() override {
    for (const char* var : {"SHAPEID_TLS_CA", "SHAPEID_TLS_CLIENT_CERT", "SHAPEID_TLS_CLIENT_KEY",
                            "SHAPEID_API_KEY"}) {
      unsetenv(var);
    }
  }

  static std::string Cert(const std::string& file) { return TestCertificates::Path(file); }

  // The CLI with `key` in SHAPEID_API_KEY ("" for none).
  RunResult Run(const std::string& key, std::vector<std::string> args) {
    if (key.empty()) {
      unsetenv("SHAPEID_API_KEY");
    } else {
      setenv("SHAPEID_API_KEY", key.c_str(), 1);
    }
    args.insert(args.begin(), {"--server", server_->address(), "--quiet", "--timeout", "10"});
    RunResult run = Shapeid(args);
    outputs_ += run.out + run.err;
    return run;
  }

  std::string keys_file_;
  std::vector<std::string> files_;
  std::unique_ptr<ServerProcess> server_;
  std::string outputs_;  // everything the CLI printed
};

TEST_F(SecureCliTest, ScopesThroughTheCliOverMutualTls) {
  EXPECT_EQ(Run("", {"health"}).exit_code, 0) << "health needs no key";

  const RunResult missing = Run("", {"gallery", "create", "parts"});
  EXPECT_EQ(missing.exit_code, 4);
  EXPECT_THAT(missing.err, HasSubstr("missing API key"));
  EXPECT_THAT(missing.err, HasSubstr("SHAPEID_API_KEY or --api-key-file"));
  const RunResult wrong = Run(kWrong, {"gallery", "list"});
  EXPECT_EQ(wrong.exit_code, 4);
  EXPECT_THAT(wrong.err, HasSubstr("unknown API key"));
  const RunResult robot_creates = Run(kRead, {"gallery", "create", "parts"});
  EXPECT_EQ(robot_creates.exit_code, 4);
  EXPECT_THAT(robot_creates.err, HasSubstr("key 'robot' lacks scope write"));

  ASSERT_EQ(Run(kWrite, {"gallery", "create", "parts"}).exit_code, 0);
  const RunResult trained =
      Run(kWrite, {"train", "--gallery", "parts", "--label", "box", files_[0], files_[2]});
  ASSERT_EQ(trained.exit_code, 0) << trained.err;
  ASSERT_EQ(Run(kWrite, {"train", "--gallery", "parts", "--label", "rod", files_[1]}).exit_code, 0);
  const RunResult classified = Run(kRead, {"classify", "--gallery", "parts", files_[3]});
  EXPECT_EQ(classified.exit_code, 0) << classified.err;
  EXPECT_THAT(classified.out, HasSubstr("rod"));

  const RunResult trainer_deletes = Run(kWrite, {"gallery", "delete", "parts"});
  EXPECT_EQ(trainer_deletes.exit_code, 4);
  EXPECT_THAT(trainer_deletes.err, HasSubstr("key 'trainer' lacks scope admin"));
  unsetenv("SHAPEID_API_KEY");
  const std::string admin_file = WriteTempFile("admin.key", std::string(kAdmin) + "\n");
  RunResult deleted = Shapeid(
      {"--server", server_->address(), "--api-key-file", admin_file, "gallery", "delete", "parts"});
  outputs_ += deleted.out + deleted.err;
  EXPECT_EQ(deleted.exit_code, 0) << deleted.err;

  // Without the client certificate the handshake fails: unreachable.
  unsetenv("SHAPEID_TLS_CLIENT_CERT");
  unsetenv("SHAPEID_TLS_CLIENT_KEY");
  const RunResult no_cert = Run(kAdmin, {"gallery", "list"});
  EXPECT_EQ(no_cert.exit_code, 3) << no_cert.err;

  // No key, and no digest, in anything the server logged or the CLI printed.
  EXPECT_EQ(server_->Terminate(std::chrono::seconds(5)), 0);
  const std::string log = server_->StderrText();
  EXPECT_THAT(log, HasSubstr("security: TLS with client certificates (mutual TLS), 3 API keys "
                             "(1 read, 1 write, 1 admin)"));
  for (const char* key : {kRead, kWrite, kAdmin, kWrong}) {
    EXPECT_THAT(log, Not(HasSubstr(key)));
    EXPECT_THAT(log, Not(HasSubstr(Sha256sum(key))));
    EXPECT_THAT(outputs_, Not(HasSubstr(key)));
  }
  EXPECT_THAT(log, Not(HasSubstr("shapeid_e2e_")));
}

}  // namespace
}  // namespace shapeid
