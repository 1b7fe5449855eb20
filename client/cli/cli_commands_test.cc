// The shapeid commands against an in-process server on a loopback port, on small labeled
// folders written by the test: what users and scripts rely on (results, formats, exit codes,
// a batch that keeps going past a bad file, temporary galleries cleaned up, export / import).

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "absl/strings/str_split.h"
#include "client/cli/cli_testing.h"
#include "client/cli/describe_command.h"
#include "client/cli/eval_command.h"
#include "client/cli/gallery_commands.h"
#include "client/cli/train_classify_commands.h"
#include "client/client_testing.h"
#include "core/io/pcd_writer.h"
#include "core/testing/test_clouds.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "server/server.h"

namespace shapeid {
namespace {

namespace fs = std::filesystem;
using cli_testing::Captured;
using cli_testing::PythonOnJsonLines;
using ::testing::AllOf;
using ::testing::HasSubstr;
using ::testing::StartsWith;
using testing_clouds::kShapeNames;
using testing_clouds::ShapeCloud;

class CliCommandsTest : public ::testing::Test {
 protected:
  void SetUp() override {
    ServerOptions server_options;
    server_options.listen = "127.0.0.1:0";
    auto server = ShapeIdServer::Start(server_options);
    ASSERT_TRUE(server.ok()) << server.status();
    server_ = std::move(server).value();
    root_ = cli_testing::ScratchDir("cli_commands");
    // dataset/<shape>/{train,test}/NN.pcd: 6 train and 3 test clouds per shape.
    for (int kind = 0; kind < 3; ++kind) {
      for (int i = 0; i < 9; ++i) {
        const fs::path dir = root_ / "dataset" / kShapeNames[kind] / (i < 6 ? "train" : "test");
        fs::create_directories(dir);
        ASSERT_TRUE(WritePcd((dir / absl::StrCat(i, ".pcd")).string(),
                             ShapeCloud(kind, 1000 * kind + i, 400))
                        .ok());
      }
    }
  }
  void TearDown() override {
    if (server_) server_->Shutdown(absl::ZeroDuration());
  }

  CliContext Context(OutputFormat format = OutputFormat::kTable) {
    CliContext context;
    context.out = out_.get();
    context.err = err_.get();
    context.format = format;
    context.progress = ProgressMode::kOff;
    context.client.target = server_->address();
    return context;
  }
  std::string Path(const std::string& relative) const { return (root_ / relative).string(); }

  int CreateAndTrain(const std::string& gallery) {
    GalleryCreateOptions create;
    create.name = gallery;
    create.spec = "rphsd:refs=cross7,bins=10";
    Captured out, err;
    CliContext context = Context();
    context.out = out.get();
    context.err = err.get();
    if (int code = RunGalleryCreate(create, context); code != kExitOk) return code;
    TrainOptions train;
    train.gallery = gallery;
    train.paths = {Path("dataset")};
    train.batch.train_batch = 4;
    return RunTrain(train, context);
  }

  std::unique_ptr<ShapeIdServer> server_;
  fs::path root_;
  Captured out_, err_;
};

TEST_F(CliCommandsTest, GalleryLifecycleInEveryFormat) {
  GalleryCreateOptions create;
  create.name = "parts";
  create.k = 3;
  create.weighting = "distance";
  create.scaling = "zscore";
  ASSERT_EQ(RunGalleryCreate(create, Context()), kExitOk) << err_.contents();
  EXPECT_THAT(out_.contents(), AllOf(HasSubstr("NAME"), HasSubstr("parts"), HasSubstr("distance"),
                                     HasSubstr("zscore")));
  // Exists: refused (4), unless --exist-ok.
  EXPECT_EQ(RunGalleryCreate(create, Context()), kExitRefused);
  EXPECT_THAT(err_.contents(), HasSubstr("parts"));
  create.exist_ok = true;
  EXPECT_EQ(RunGalleryCreate(create, Context()), kExitOk);

  Captured json;
  CliContext context = Context(OutputFormat::kJson);
  context.out = json.get();
  ASSERT_EQ(RunGalleryList(context), kExitOk);
  EXPECT_EQ(PythonOnJsonLines(json.contents(),
                              "[(r[\"name\"], r[\"k\"], r[\"weighting\"], r[\"sample_count\"]) "
                              "for r in rows]"),
            "[('parts', 3, 'distance', 0)]");

  Captured csv;
  context = Context(OutputFormat::kCsv);
  context.out = csv.get();
  ASSERT_EQ(RunGalleryList(context), kExitOk);
  EXPECT_THAT(csv.contents(), StartsWith("NAME,SPEC,DIM,K,"));

  EXPECT_EQ(RunGalleryShow("nope", Context()), kExitRefused);
  EXPECT_EQ(RunGalleryDelete("nope", /*missing_ok=*/false, Context()), kExitRefused);
  EXPECT_EQ(RunGalleryDelete("nope", /*missing_ok=*/true, Context()), kExitOk);
  EXPECT_EQ(RunGalleryDelete("parts", false, Context()), kExitOk);
  EXPECT_THAT(out_.contents(), HasSubstr("deleted gallery parts (0 samples)"));
}

TEST_F(CliCommandsTest, AugmentedGalleryShowsItsViewsAndDescriptorCount) {
  GalleryCreateOptions create;
  create.name = "robot";
  create.spec = "dfsd:frame=box";
  create.augment_views = 2;
  ASSERT_EQ(RunGalleryCreate(create, Context()), kExitOk) << err_.contents();
  TrainOptions train;
  train.gallery = "robot";
  train.paths = {Path("dataset")};
  ASSERT_EQ(RunTrain(train, Context()), kExitOk) << err_.contents();

  Captured table;
  CliContext context = Context();
  context.out = table.get();
  ASSERT_EQ(RunGalleryShow("robot", context), kExitOk);
  EXPECT_THAT(table.contents(),
              AllOf(HasSubstr("augment     2 views per cloud (noise 0.01, 300-500 points, fixed "
                              "pose)"),
                    HasSubstr(" descriptors)")));
  Captured json;
  context = Context(OutputFormat::kJson);
  context.out = json.get();
  ASSERT_EQ(RunGalleryShow("robot", context), kExitOk);
  // Every trained cloud has its own descriptor and up to two views.
  EXPECT_EQ(PythonOnJsonLines(json.contents(),
                              "[(r[\"augment_views\"], r[\"sample_count\"] < r[\"vector_count\"] "
                              "<= 3 * r[\"sample_count\"]) for r in rows]"),
            "[(2, True)]");
}

TEST_F(CliCommandsTest, ALearningServersGalleryShowsItsHeadAndClassifyWhoAnswered) {
  server_->Shutdown(absl::ZeroDuration());
  ServerOptions server_options;
  server_options.listen = "127.0.0.1:0";
  server_options.learn = true;
  server_options.learner.settle = absl::Milliseconds(20);
  server_options.learner.poll = absl::Milliseconds(10);
  server_options.learner.head.min_samples = 6;
  server_options.learner.head.mlp.epochs = 5;
  server_ = *ShapeIdServer::Start(server_options);
  ASSERT_EQ(CreateAndTrain("shapes"), kExitOk) << err_.contents();
  std::string shown;
  for (int i = 0; i < 2000 && shown.find("\"head\"") == std::string::npos; ++i) {
    absl::SleepFor(absl::Milliseconds(10));
    Captured json;
    CliContext context = Context(OutputFormat::kJson);
    context.out = json.get();
    ASSERT_EQ(RunGalleryShow("shapes", context), kExitOk);
    shown = json.contents();
  }
  EXPECT_EQ(PythonOnJsonLines(shown,
                              "[(r[\"head\"][\"answers\"], r[\"head\"][\"fitted_version\"] == "
                              "r[\"version\"], r[\"head\"][\"fitted_samples\"] + "
                              "r[\"head\"][\"holdout_samples\"]) for r in rows]"),
            "[(True, True, 18)]");
  Captured table;
  CliContext context = Context();
  context.out = table.get();
  ASSERT_EQ(RunGalleryShow("shapes", context), kExitOk);
  EXPECT_THAT(table.contents(), AllOf(HasSubstr("learned     head fitted on version "),
                                      HasSubstr("held-out vectors; answers with the vote")));
  ClassifyOptions classify;
  classify.gallery = "shapes";
  classify.paths = {Path("dataset/sphere/test/6.pcd")};
  Captured answer;
  context = Context(OutputFormat::kJson);
  context.out = answer.get();
  ASSERT_EQ(RunClassify(classify, context), kExitOk);
  EXPECT_THAT(answer.contents(), HasSubstr("\"by_head\":true"));
}

TEST_F(CliCommandsTest, BadKnobsAreUsageErrors) {
  GalleryCreateOptions create;
  create.name = "x";
  create.scaling = "log";
  EXPECT_EQ(RunGalleryCreate(create, Context()), kExitUsage);
  GalleryRemoveOptions remove;
  remove.name = "x";
  EXPECT_EQ(RunGalleryRemove(remove, Context()), kExitUsage);
}

TEST_F(CliCommandsTest, TrainFolderThenClassifyInInputOrder) {
  ASSERT_EQ(CreateAndTrain("shapes"), kExitOk) << err_.contents();
  Captured show;
  CliContext context = Context();
  context.out = show.get();
  ASSERT_EQ(RunGalleryShow("shapes", context), kExitOk);
  EXPECT_THAT(show.contents(),
              AllOf(HasSubstr("samples     18 in 3 labels"), HasSubstr("rphsd:refs=cross7")));

  ClassifyOptions classify;
  classify.gallery = "shapes";
  classify.paths = {Path("dataset/sphere/test"), Path("dataset/box/test/6.pcd")};
  classify.batch.jobs = 3;
  Captured json;
  context = Context(OutputFormat::kJson);
  context.out = json.get();
  ASSERT_EQ(RunClassify(classify, context), kExitOk) << err_.contents();
  EXPECT_EQ(PythonOnJsonLines(json.contents(),
                              "[(r[\"file\"].split(\"/\")[-3:], r[\"label\"], "
                              "len(r[\"neighbors\"])) for r in rows]"),
            "[(['sphere', 'test', '6.pcd'], 'sphere', 1), "
            "(['sphere', 'test', '7.pcd'], 'sphere', 1), "
            "(['sphere', 'test', '8.pcd'], 'sphere', 1), "
            "(['box', 'test', '6.pcd'], 'box', 1)]");

  Captured table;
  context = Context();
  context.out = table.get();
  classify.call.k = 3;
  classify.paths = {Path("dataset/rod/test/6.pcd")};
  ASSERT_EQ(RunClassify(classify, context), kExitOk);
  const std::vector<std::string> lines = absl::StrSplit(table.contents(), '\n');
  ASSERT_GE(lines.size(), 2u);
  EXPECT_THAT(lines[0], AllOf(StartsWith("FILE"), HasSubstr("LABEL"), HasSubstr("CONFIDENCE")));
  EXPECT_THAT(lines[1], AllOf(HasSubstr("rod"), HasSubstr("100.0%")));
}

TEST_F(CliCommandsTest, ABatchKeepsGoingPastABadFileAndExitsOne) {
  ASSERT_EQ(CreateAndTrain("shapes"), kExitOk) << err_.contents();
  std::ofstream(Path("dataset/box/test/broken.pcd")) << "not a pcd file\n";
  std::ofstream(Path("dataset/box/test/tiny.xyz")) << "0 0 0\n1 1 1\n";  // too few points
  ClassifyOptions classify;
  classify.gallery = "shapes";
  classify.paths = {Path("dataset/box/test")};
  Captured csv;
  CliContext context = Context(OutputFormat::kCsv);
  context.out = csv.get();
  EXPECT_EQ(RunClassify(classify, context), kExitSomeInputsFailed);
  const std::string errors = err_.contents();
  EXPECT_THAT(errors, HasSubstr("broken.pcd"));
  EXPECT_THAT(errors, HasSubstr("tiny.xyz"));
  const std::string rows = csv.contents();
  EXPECT_THAT(rows, StartsWith("file,label,unknown,confidence,points,seconds,neighbor1_label"));
  EXPECT_EQ(std::count(rows.begin(), rows.end(), '\n'), 4);  // header + 3 good files

  // Training the same folder: the bad files are skipped and reported, the rest trained.
  TrainOptions train;
  train.gallery = "shapes";
  train.label = "box";
  train.paths = {Path("dataset/box/test")};
  train.batch.train_batch = 8;  // bad cloud inside a batch: found by resending one by one
  Captured summary;
  context = Context();
  context.out = summary.get();
  EXPECT_EQ(RunTrain(train, context), kExitSomeInputsFailed);
  EXPECT_THAT(summary.contents(), HasSubstr("trained 3 of 5 files into shapes"));
}

TEST_F(CliCommandsTest, ServerWideErrorsStopTheBatchWithTheirExitCode) {
  ClassifyOptions classify;
  classify.gallery = "missing";
  classify.paths = {Path("dataset")};
  EXPECT_EQ(RunClassify(classify, Context()), kExitRefused);
  EXPECT_THAT(err_.contents(), HasSubstr("missing"));

  TrainOptions train;
  train.gallery = "missing";
  train.paths = {Path("dataset")};
  EXPECT_EQ(RunTrain(train, Context()), kExitRefused);

  CliContext down = Context();
  down.client.target = "127.0.0.1:1";  // nothing listens there
  down.client.max_attempts = 1;
  EXPECT_EQ(RunClassify(classify, down), kExitUnreachable);
  EXPECT_EQ(RunHealth(down), kExitUnreachable);
  EXPECT_THAT(err_.contents(), HasSubstr("SHAPEID_SERVER"));
  EXPECT_EQ(RunHealth(Context()), kExitOk);
  EXPECT_THAT(out_.contents(), HasSubstr("SERVING"));
}

TEST_F(CliCommandsTest, UsageErrorsBeforeTouchingTheServer) {
  TrainOptions train;
  train.gallery = "g";
  train.paths = {Path("dataset/box/train/0.pcd")};  // a file without --label
  EXPECT_EQ(RunTrain(train, Context()), kExitUsage);
  EXPECT_THAT(err_.contents(), HasSubstr("--label"));
  ClassifyOptions classify;
  classify.gallery = "g";
  fs::create_directories(root_ / "empty");
  classify.paths = {Path("empty")};
  EXPECT_EQ(RunClassify(classify, Context()), kExitUsage);
  EXPECT_THAT(err_.contents(), HasSubstr("no point-cloud file"));
}

// Samples with the largest provenance make a default `gallery samples` page and a `classify
// --k 1000` answer of about 8.6 MB, past gRPC's default 4 MiB: both read and printed. Over a
// smaller limit of the client's own, the line says the refusal is this client's, with the
// numbers, and the exit code is 5, not 4 (the server refused).
TEST_F(CliCommandsTest, LargeAnswersAreReadAndTheClientsOwnLimitIsNamed) {
  {
    ClientOptions options;
    options.target = server_->address();
    absl::StatusOr<std::unique_ptr<Client>> client = Client::Connect(options);
    ASSERT_TRUE(client.ok()) << client.status();
    ASSERT_TRUE(client_testing::TrainFatProvenanceGallery(**client, "fat", 1000).ok());
  }
  GallerySamplesOptions samples;
  samples.name = "fat";
  Captured listed;
  CliContext context = Context(OutputFormat::kJson);
  context.out = listed.get();
  ASSERT_EQ(RunGallerySamples(samples, context), kExitOk) << err_.contents();
  EXPECT_EQ(PythonOnJsonLines(listed.contents(),
                              "(len(rows), rows[-1][\"sample_id\"], len(rows[0][\"source\"]), "
                              "len(rows[0][\"metadata\"]))"),
            "(1000, 1000, 4096, 64)");

  ClassifyOptions classify;
  classify.gallery = "fat";
  classify.call.k = 1000;
  classify.paths = {Path(absl::StrCat("dataset/", kShapeNames[0], "/test/6.pcd"))};
  Captured classified;
  context = Context(OutputFormat::kJson);
  context.out = classified.get();
  ASSERT_EQ(RunClassify(classify, context), kExitOk) << err_.contents();
  EXPECT_EQ(PythonOnJsonLines(classified.contents(), "[len(r[\"neighbors\"]) for r in rows]"),
            "[1000]");

  for (bool list : {true, false}) {
    Captured err;
    context = Context();
    context.err = err.get();
    context.client.max_receive_bytes = 1 << 20;
    EXPECT_EQ(list ? RunGallerySamples(samples, context) : RunClassify(classify, context),
              kExitAnswerTooLarge);
    EXPECT_THAT(err.contents(),
                AllOf(StartsWith(list ? "shapeid: gallery samples fat: the server's answer is "
                                      : "shapeid: classify fat: the server's answer is "),
                      HasSubstr(" bytes, more than this client's receive limit of 1048576 "
                                "bytes: this client refused it, not the server")));
  }
}

TEST_F(CliCommandsTest, EvalHoldOutAgainstTemporaryGalleryLeavesNoGallery) {
  EvalOptions eval;
  eval.dataset = Path("dataset");
  eval.create.spec = "rphsd:refs=cross7,bins=10";
  const std::string report = Path("report.html");
  eval.report_html = report;
  Captured json;
  CliContext context = Context(OutputFormat::kJson);
  context.out = json.get();
  ASSERT_EQ(RunEval(eval, context), kExitOk) << err_.contents();
  EXPECT_EQ(PythonOnJsonLines(json.contents(),
                              "[(r[\"mode\"], r[\"tests\"], r[\"correct\"], r[\"train_samples\"]) "
                              "for r in rows]"),
            "[('holdout', 9, 9, 18)]");
  std::ifstream html(report);
  std::string page((std::istreambuf_iterator<char>(html)), std::istreambuf_iterator<char>());
  EXPECT_THAT(page, AllOf(HasSubstr("<html"), HasSubstr("sphere")));

  Captured list;
  context = Context(OutputFormat::kJson);
  context.out = list.get();
  ASSERT_EQ(RunGalleryList(context), kExitOk);
  EXPECT_EQ(list.contents(), "");  // the temporary gallery is gone
}

TEST_F(CliCommandsTest, EvalKFoldAndAgainstAGallery) {
  // A flat layout (no train/test): k-fold.
  fs::create_directories(root_ / "flat");
  for (int kind = 0; kind < 3; ++kind) {
    fs::rename(root_ / "dataset" / kShapeNames[kind] / "train", root_ / "flat" / kShapeNames[kind]);
  }
  EvalOptions eval;
  eval.dataset = Path("flat");
  eval.folds = 3;
  eval.create.spec = "rphsd:refs=cross7,bins=10";
  Captured table;
  CliContext context = Context();
  context.out = table.get();
  ASSERT_EQ(RunEval(eval, context), kExitOk) << err_.contents();
  EXPECT_THAT(table.contents(), HasSubstr("accuracy 100.00 % (18/18)"));

  // Against an existing gallery trained on the flat folder: the test clouds left in dataset/.
  GalleryCreateOptions create;
  create.name = "flatshapes";
  create.spec = "rphsd:refs=cross7,bins=10";
  ASSERT_EQ(RunGalleryCreate(create, Context()), kExitOk);
  TrainOptions train;
  train.gallery = "flatshapes";
  train.paths = {Path("flat")};
  ASSERT_EQ(RunTrain(train, Context()), kExitOk) << err_.contents();
  EvalOptions against;
  against.dataset = Path("dataset");
  against.gallery = "flatshapes";
  Captured csv;
  context = Context(OutputFormat::kCsv);
  context.out = csv.get();
  ASSERT_EQ(RunEval(against, context), kExitOk) << err_.contents();
  EXPECT_THAT(csv.contents(), AllOf(HasSubstr("box,3,3,"), HasSubstr("rod,3,3,")));
  against.gallery = "nope";
  EXPECT_EQ(RunEval(against, Context()), kExitRefused);
}

TEST_F(CliCommandsTest, ExportThenImportUnderANewNameClassifiesAlike) {
  ASSERT_EQ(CreateAndTrain("shapes"), kExitOk) << err_.contents();
  Captured exported;
  CliContext context = Context(OutputFormat::kJson);
  context.out = exported.get();
  ASSERT_EQ(RunGalleryExport("shapes", Path("shapes.shapeid"), context), kExitOk)
      << err_.contents();
  EXPECT_EQ(
      PythonOnJsonLines(exported.contents(), "[(r[\"samples\"], r[\"bytes\"]) for r in rows]"),
      absl::StrCat("[(18, ", fs::file_size(Path("shapes.shapeid")), ")]"));

  Captured shown;
  context = Context();
  context.out = shown.get();
  ASSERT_EQ(RunGalleryImport(Path("shapes.shapeid"), "copy", context), kExitOk) << err_.contents();
  EXPECT_THAT(shown.contents(),
              AllOf(HasSubstr("gallery     copy"), HasSubstr("samples     18 in 3 labels"),
                    HasSubstr("made by     descriptor version 1, shapeid "),
                    ::testing::Not(HasSubstr("UNUSABLE"))));

  std::string answers[2];
  for (const char* gallery : {"shapes", "copy"}) {
    ClassifyOptions classify;
    classify.gallery = gallery;
    classify.call.k = 3;
    classify.paths = {Path("dataset")};
    Captured csv;
    context = Context(OutputFormat::kCsv);
    context.out = csv.get();
    ASSERT_EQ(RunClassify(classify, context), kExitOk) << err_.contents();
    // Everything but the timing column.
    std::string rows;
    for (absl::string_view line : absl::StrSplit(csv.contents(), '\n')) {
      std::vector<absl::string_view> fields = absl::StrSplit(line, ',');
      if (fields.size() > 5) fields.erase(fields.begin() + 5);
      absl::StrAppend(&rows, absl::StrJoin(fields, ","), "\n");
    }
    answers[std::string(gallery) == "copy"] = rows;
  }
  EXPECT_EQ(answers[0], answers[1]);
  EXPECT_THAT(answers[0], HasSubstr("sphere"));

  Captured json;
  context = Context(OutputFormat::kJson);
  context.out = json.get();
  ASSERT_EQ(RunGalleryShow("copy", context), kExitOk);
  EXPECT_EQ(PythonOnJsonLines(json.contents(),
                              "[(r[\"descriptor_version\"], bool(r[\"software_version\"]), "
                              "\"incompatible\" in r) for r in rows]"),
            "[(1, True, False)]");
}

TEST_F(CliCommandsTest, ExportAndImportErrorsHaveTheirExitCodes) {
  ASSERT_EQ(CreateAndTrain("shapes"), kExitOk) << err_.contents();
  // Export: a missing gallery is refused (and leaves no file), a missing directory is usage.
  EXPECT_EQ(RunGalleryExport("nope", Path("nope.shapeid"), Context()), kExitRefused);
  EXPECT_FALSE(fs::exists(Path("nope.shapeid")));
  EXPECT_EQ(RunGalleryExport("shapes", Path("no/such/dir/g.shapeid"), Context()), kExitUsage);
  CliContext talkative = Context();
  talkative.progress = ProgressMode::kAuto;  // the summary line is not --quiet
  ASSERT_EQ(RunGalleryExport("shapes", Path("g.shapeid"), talkative), kExitOk);
  EXPECT_THAT(err_.contents(), HasSubstr("exported gallery 'shapes': 18 samples to "));

  // Import: a file that is not there or not an export is usage; the rest are refusals.
  EXPECT_EQ(RunGalleryImport(Path("missing.shapeid"), "", Context()), kExitUsage);
  EXPECT_EQ(RunGalleryImport(Path("dataset/box/train/0.pcd"), "", Context()), kExitUsage);
  EXPECT_THAT(err_.contents(), HasSubstr("0.pcd is not a shapeid gallery export (bad magic)"));
  EXPECT_EQ(RunGalleryImport(Path("g.shapeid"), "", Context()), kExitRefused);  // "shapes" exists
  EXPECT_THAT(err_.contents(), HasSubstr("already exists"));
  const std::string whole = [&] {
    std::ifstream in(Path("g.shapeid"), std::ios::binary);
    return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  }();
  std::ofstream(Path("half.shapeid"), std::ios::binary) << whole.substr(0, whole.size() / 2);
  EXPECT_EQ(RunGalleryImport(Path("half.shapeid"), "half", Context()), kExitRefused);
  EXPECT_THAT(err_.contents(), HasSubstr("half.shapeid is truncated"));
  EXPECT_EQ(RunGalleryShow("half", Context()), kExitRefused);  // nothing was created
}

}  // namespace
}  // namespace shapeid
