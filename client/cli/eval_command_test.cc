// `shapeid eval` on a server and in-process (--local) side by side: the same folder and
// options must give the same output, every prediction included, except for the timings.
// The server runs in this process on a loopback port.

#include "client/cli/eval_command.h"

#include <filesystem>
#include <fstream>
#include <memory>
#include <regex>
#include <string>

#include "absl/strings/str_cat.h"
#include "client/cli/cli_testing.h"
#include "client/cli/eval_testing.h"
#include "client/cli/gallery_commands.h"
#include "client/cli/train_classify_commands.h"
#include "core/descriptor_registry.h"
#include "core/version.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "server/server.h"

namespace shapeid {
namespace {

namespace fs = std::filesystem;
using cli_testing::Captured;
using cli_testing::WithoutTimes;
using ::testing::AllOf;
using ::testing::HasSubstr;
using ::testing::Not;

// In z-scored rphsd:bins=20 space, nearest-neighbor distances of these clouds straddle it.
constexpr double kRejectDistance = 3.0;

// The runs differ in where and when they ran; the local run numbers samples its own way (a
// server's ids are its own) and names each neighbor's training file as listed (a server
// gives the source the training client sent, if any). The rest must match.
std::string WithoutSampleIdentity(const std::string& json) {
  static const std::regex kFile(R"re(,"file":"[^"]*"\})re");
  static const std::regex kId(R"re("sample_id":[0-9]+)re");
  static const std::regex kWhere(R"re("(started|server|server_version)":"[^"]*")re");
  return std::regex_replace(
      std::regex_replace(std::regex_replace(json, kFile, "}"), kId, "\"sample_id\":0"), kWhere,
      "\"$1\":\"\"");
}

class EvalCommandTest : public ::testing::Test {
 protected:
  void SetUp() override {
    ServerOptions server_options;
    server_options.listen = "127.0.0.1:0";
    auto server = ShapeIdServer::Start(server_options);
    ASSERT_TRUE(server.ok()) << server.status();
    server_ = std::move(server).value();
    root_ = cli_testing::ScratchDir("eval_command");
  }
  void TearDown() override {
    if (server_) server_->Shutdown(absl::ZeroDuration());
    fs::remove_all(root_);
  }

  CliContext Context(Captured& out, Captured& err) {
    CliContext context;
    context.out = out.get();
    context.err = err.get();
    context.format = OutputFormat::kJson;
    context.progress = ProgressMode::kOff;
    context.client.target = server_->address();
    return context;
  }

  // Runs `eval` on the server, then with --local, and returns both JSON outputs. The server
  // trains on one stream at a time, so that its galleries hold the samples in file order as
  // the local ones do (the kNN tie-break order, and the order of z-score's sums).
  struct Both {
    std::string server, local;
  };
  Both ServerThenLocal(EvalOptions eval, int expected_exit = kExitOk) {
    Both both;
    eval.with_predictions = true;
    Captured server_out, server_err, local_out, local_err;
    eval.local = false;
    eval.batch.jobs = 1;
    EXPECT_EQ(RunEval(eval, Context(server_out, server_err)), expected_exit)
        << server_err.contents();
    eval.local = true;
    eval.batch.jobs = 3;
    EXPECT_EQ(RunEval(eval, Context(local_out, local_err)), expected_exit) << local_err.contents();
    both.server = server_out.contents();
    both.local = local_out.contents();
    return both;
  }

  std::unique_ptr<ShapeIdServer> server_;
  fs::path root_;
};

TEST_F(EvalCommandTest, HoldOutGivesTheServersPredictionsForEveryFile) {
  cli_testing::WriteLabeledDataset(root_ / "split", /*split=*/true, /*per_label=*/15);
  EvalOptions eval;
  eval.dataset = (root_ / "split").string();
  eval.create.spec = "rphsd:refs=cross7,bins=10";
  const Both both = ServerThenLocal(eval);
  EXPECT_THAT(both.local, HasSubstr("\"mode\":\"holdout\""));
  EXPECT_THAT(both.local, HasSubstr("\"tests\":15,"));
  EXPECT_THAT(both.local, Not(HasSubstr("\"correct\":15,")));  // mistakes to agree on
  EXPECT_EQ(WithoutSampleIdentity(WithoutTimes(both.local)),
            WithoutSampleIdentity(WithoutTimes(both.server)));
}

TEST_F(EvalCommandTest, KFoldWithEveryKnobGivesTheServersPredictions) {
  cli_testing::WriteLabeledDataset(root_ / "flat", /*split=*/false, /*per_label=*/12);
  // A bad file in each: both count it once per round it is in, in the same order.
  std::ofstream((root_ / "flat/sphere/broken.pcd").string()) << "not a pcd file\n";
  EvalOptions eval;
  eval.dataset = (root_ / "flat").string();
  eval.folds = 3;
  eval.seed = 11;
  eval.create.spec = "rphsd:refs=cubic27,bins=20";
  eval.create.k = 5;
  eval.create.weighting = "distance";
  eval.create.scaling = "zscore";
  eval.create.reject_distance = kRejectDistance;
  const Both both = ServerThenLocal(eval, kExitSomeInputsFailed);
  EXPECT_THAT(both.local, HasSubstr("\"mode\":\"kfold\""));
  EXPECT_THAT(both.local, HasSubstr("\"predicted\":\"unknown\""));  // some are rejected
  EXPECT_THAT(both.local, HasSubstr("broken.pcd\",\""));            // in more than one round
  EXPECT_EQ(WithoutSampleIdentity(WithoutTimes(both.local)),
            WithoutSampleIdentity(WithoutTimes(both.server)));

  // The same with the server's defaults for every knob.
  eval.create = GalleryCreateOptions();
  const Both defaults = ServerThenLocal(eval, kExitSomeInputsFailed);
  EXPECT_THAT(defaults.local,
              HasSubstr(absl::StrCat("\"descriptor_spec\":\"", kDefaultDescriptorSpec)));
  EXPECT_EQ(WithoutSampleIdentity(WithoutTimes(defaults.local)),
            WithoutSampleIdentity(WithoutTimes(defaults.server)));
}

TEST_F(EvalCommandTest, AgainstAGalleryTheOutputsNameItAndTheReportTracesErrorsToFiles) {
  cli_testing::WriteLabeledDataset(root_ / "split", /*split=*/true, /*per_label=*/15);
  Captured out, err;
  GalleryCreateOptions create;
  create.name = "parts";
  create.spec = "rphsd:refs=cross7,bins=10";
  ASSERT_EQ(RunGalleryCreate(create, Context(out, err)), kExitOk) << err.contents();
  TrainOptions train;
  train.gallery = "parts";
  train.paths = {(root_ / "split").string()};  // <label>/train/: 10 clouds per label
  ASSERT_EQ(RunTrain(train, Context(out, err)), kExitOk) << err.contents();

  EvalOptions eval;
  eval.gallery = "parts";
  eval.dataset = (root_ / "split").string();
  eval.report_html = (root_ / "report.html").string();
  Captured json, json_err;
  ASSERT_EQ(RunEval(eval, Context(json, json_err)), kExitOk) << json_err.contents();
  EXPECT_THAT(json.contents(),
              AllOf(HasSubstr("\"mode\":\"gallery\""), HasSubstr("\"gallery\":\"parts\""),
                    HasSubstr(absl::StrCat("\"server\":\"", server_->address(), "\"")),
                    HasSubstr(absl::StrCat("\"client_version\":\"", kShapeidVersion,
                                           "\",\"server_version\":\"", kShapeidVersion, "\"")),
                    HasSubstr("\"tests\":15,"), HasSubstr("\"train_samples\":30,")));
  Captured table, table_err;
  CliContext table_context = Context(table, table_err);
  table_context.format = OutputFormat::kTable;
  eval.report_html.clear();
  ASSERT_EQ(RunEval(eval, table_context), kExitOk) << table_err.contents();
  EXPECT_THAT(table.contents(), HasSubstr("  gallery parts (30 samples)\n"));
  EXPECT_THAT(table.contents(), Not(HasSubstr("training ")));

  std::ifstream html((root_ / "report.html").string());
  const std::string page((std::istreambuf_iterator<char>(html)), std::istreambuf_iterator<char>());
  EXPECT_THAT(page,
              AllOf(HasSubstr("<dt>gallery</dt><dd>parts (30 samples)</dd>"),
                    HasSubstr("<div class=\"k\">gallery samples</div><div class=\"v\">30</div>"),
                    HasSubstr(absl::StrCat("<dt>server</dt><dd>", server_->address(), "</dd>")),
                    HasSubstr(absl::StrCat("<dt>shapeid</dt><dd>client ", kShapeidVersion,
                                           ", server ", kShapeidVersion, "</dd>"))));
  // Every error row names the training file its nearest sample was made from (the CLI
  // trained each with its absolute path as the source), and has its picture.
  const std::regex row(R"re(<tr id="e[0-9]+">.*?</tr>)re");
  const std::regex traced(
      R"re(<td class="path">/[^<]*/split/[a-z]+/train/[0-9]+\.pcd</td><td>[a-z]+</td>)re");
  int rows = 0;
  for (auto it = std::sregex_iterator(page.begin(), page.end(), row); it != std::sregex_iterator();
       ++it, ++rows) {
    EXPECT_TRUE(std::regex_search(it->str(), traced)) << it->str();
  }
  EXPECT_GT(rows, 0);
  EXPECT_EQ(eval_testing::CountOf(page, "<img class=\"cloud\""), 2u * rows);
}

}  // namespace
}  // namespace shapeid
