// End-to-end: the real `shapeid` CLI against the real shapeid-server on loopback, as a user
// would run them: make a labeled dataset from meshes with `shapeid views`, create and train a
// gallery from the folder, batch-classify, evaluate, export and import, and check what scripts
// rely on: JSON that parses, CSV, and every documented exit code.

#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "absl/strings/str_cat.h"
#include "core/io/scene_files.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "tests/cli_runner.h"
#include "tests/server_process.h"

namespace shapeid {
namespace {

namespace fs = std::filesystem;
using ::testing::AllOf;
using ::testing::HasSubstr;
using ::testing::StartsWith;

// Evaluates a python expression over `rows`, the JSON Lines in `text`, with Debian's python3.
std::string Python(const std::string& text, const std::string& expression) {
  const std::string path = WriteTempFile("lines.jsonl", text);
  const std::string script =
      WriteTempFile("check.py", absl::StrCat("import json, sys\nrows = [json.loads(l) for l in "
                                             "open(sys.argv[1])]\nprint((",
                                             expression, "))\n"));
  const std::string out_path = WriteTempFile("python.out", "");
  const std::string command = absl::StrCat("/usr/bin/python3 ", ShellQuote(script), " ",
                                           ShellQuote(path), " >", ShellQuote(out_path), " 2>&1");
  std::system(command.c_str());
  std::string out = Slurp(out_path);
  while (!out.empty() && out.back() == '\n') out.pop_back();
  return out;
}

// Three meshes a sensor tells apart from any side: a cube, a long bar and a pyramid.
void WriteMeshes(const fs::path& dir) {
  fs::create_directories(dir);
  const auto box = [](double x, double y, double z) {
    return absl::StrCat("OFF\n8 6 0\n", -x, " ", -y, " ", -z, "\n", x, " ", -y, " ", -z, "\n", x,
                        " ", y, " ", -z, "\n", -x, " ", y, " ", -z, "\n", -x, " ", -y, " ", z, "\n",
                        x, " ", -y, " ", z, "\n", x, " ", y, " ", z, "\n", -x, " ", y, " ", z,
                        "\n4 0 3 2 1\n4 4 5 6 7\n4 0 1 5 4\n4 2 3 7 6\n4 1 2 6 5\n4 0 4 7 3\n");
  };
  std::ofstream(dir / "cube.off") << box(1, 1, 1);
  std::ofstream(dir / "bar.off") << box(3, 0.4, 0.4);
  std::ofstream(dir / "pyramid.off") << "OFF\n5 5 0\n-1 -1 0\n1 -1 0\n1 1 0\n-1 1 0\n0 0 2\n"
                                        "4 0 3 2 1\n3 0 1 4\n3 1 2 4\n3 2 3 4\n3 3 0 4\n";
}

class CliE2ETest : public ::testing::Test {
 protected:
  // The dataset is made once, by the first test (WriteTempFile needs a running test).
  static void MakeDataset() {
    if (root_ != nullptr) return;
    // One folder per process: ctest runs each test of this file as its own process, in
    // parallel.
    root_ = new fs::path(fs::path(::testing::TempDir()) / absl::StrCat("cli_e2e_", ::getpid()));
    fs::remove_all(*root_);
    WriteMeshes(*root_ / "meshes");
    const RunResult views =
        Shapeid({"views", "--quiet", "--out", (*root_ / "data").string(), "--train-views", "8",
                 "--test-views", "4", "--up", "z", (*root_ / "meshes/cube.off").string(),
                 (*root_ / "meshes/bar.off").string(), (*root_ / "meshes/pyramid.off").string()});
    ASSERT_EQ(views.exit_code, 0) << views.err;
  }
  static void TearDownTestSuite() {
    if (root_ == nullptr) return;
    std::error_code ignored;
    fs::remove_all(*root_, ignored);
    delete root_;
    root_ = nullptr;
  }
  void SetUp() override {
    MakeDataset();
    ASSERT_FALSE(server_.address().empty()) << "shapeid-server did not start";
  }

  RunResult Run(std::vector<std::string> args) {
    args.insert(args.begin(), {"--server", server_.address(), "--quiet"});
    return Shapeid(args);
  }
  static std::string Data(const std::string& relative = "") {
    return (*root_ / "data" / relative).string();
  }

  static fs::path* root_;
  ServerProcess server_;
};
fs::path* CliE2ETest::root_ = nullptr;

TEST_F(CliE2ETest, ViewsMakeALabeledTrainTestLayout) {
  for (const char* label : {"cube", "bar", "pyramid"}) {
    EXPECT_TRUE(fs::exists(Data(absl::StrCat(label, "/train/view-007.pcd")))) << label;
    EXPECT_TRUE(fs::exists(Data(absl::StrCat(label, "/test/view-003.pcd")))) << label;
    EXPECT_FALSE(fs::exists(Data(absl::StrCat(label, "/test/view-004.pcd")))) << label;
  }
}

TEST_F(CliE2ETest, TrainJsonGivesEachFilesSampleIdSoANeighborTracesBackToItsFile) {
  ASSERT_EQ(Run({"gallery", "create", "traced", "--spec", "rphsd:refs=cross7,bins=10"}).exit_code,
            0);
  const RunResult trained = Run({"train", "--gallery", "traced", "--format", "json", Data()});
  ASSERT_EQ(trained.exit_code, 0) << trained.err;
  EXPECT_EQ(Python(trained.out,
                   "len(rows[0]['samples']), len({s['sample_id'] for s in rows[0]['samples']}), "
                   "sorted(rows[0]['samples'], key=lambda s: s['file']) == rows[0]['samples']"),
            "(24, 24, True)");
  const std::string file = Data("cube/train/view-007.pcd");
  const std::string id = Python(
      trained.out, absl::StrCat("[s['sample_id'] for s in rows[0]['samples'] if s['file'] == '",
                                file, "' and s['label'] == 'cube'][0]"));
  const RunResult classified = Run({"classify", "--gallery", "traced", "--format", "json", file});
  ASSERT_EQ(classified.exit_code, 0) << classified.err;
  EXPECT_EQ(Python(classified.out, "rows[0]['neighbors'][0]['sample_id']"), id);
  // The server itself says which file: the source train sent, an absolute path.
  EXPECT_EQ(Python(classified.out, "rows[0]['neighbors'][0]['source']"),
            fs::absolute(file).lexically_normal().string());

  // --metadata goes with every sample of the call; `gallery samples` lists them all, by id.
  // Two files after --metadata: each --metadata takes one value, the files stay files.
  const std::string extra = Data("bar/test/view-000.pcd");
  const RunResult tagged =
      Run({"train", "--gallery", "traced", "--label", "bar", "--metadata", "camera=d435",
           "--metadata", "session=7", extra, Data("bar/test/view-001.pcd")});
  ASSERT_EQ(tagged.exit_code, 0) << tagged.err;
  const RunResult listed = Run({"gallery", "samples", "traced", "--format", "json"});
  ASSERT_EQ(listed.exit_code, 0) << listed.err;
  EXPECT_EQ(
      Python(listed.out,
             "len(rows), [r['sample_id'] for r in rows] == sorted(r['sample_id'] for r in "
             "rows), all(r['source'].startswith('/') for r in rows), "
             "[r['metadata'] for r in rows if r['source'].endswith('bar/test/view-000.pcd')]"),
      "(26, True, True, [{'camera': 'd435', 'session': '7'}])");
  const RunResult bars = Run({"gallery", "samples", "traced", "--label", "bar", "--limit", "3"});
  ASSERT_EQ(bars.exit_code, 0) << bars.err;
  EXPECT_THAT(bars.out, AllOf(StartsWith("ID"), HasSubstr("SOURCE"), HasSubstr("bar")));
  EXPECT_EQ(std::count(bars.out.begin(), bars.out.end(), '\n'), 4);  // header and 3 samples
  const RunResult csv = Run({"gallery", "samples", "traced", "--format", "csv"});
  ASSERT_EQ(csv.exit_code, 0) << csv.err;
  EXPECT_THAT(csv.out, StartsWith("sample_id,label,views,source,metadata\r\n"));

  const RunResult bad =
      Run({"train", "--gallery", "traced", "--label", "bar", "--metadata", "no-equals", extra});
  EXPECT_EQ(bad.exit_code, 2);
  EXPECT_THAT(bad.err, HasSubstr("--metadata no-equals: expected KEY=VALUE"));
  const RunResult missing = Run({"gallery", "samples", "nosuch"});
  EXPECT_EQ(missing.exit_code, 4);
  EXPECT_THAT(missing.err, HasSubstr("no gallery named 'nosuch'"));
}

TEST_F(CliE2ETest, CreateTrainClassifyEvaluate) {
  RunResult created = Run({"gallery", "create", "demo", "--spec", "rphsd:refs=cross7,bins=10"});
  ASSERT_EQ(created.exit_code, 0) << created.err;

  RunResult trained = Run({"train", "--gallery", "demo", "--jobs", "2", Data()});
  ASSERT_EQ(trained.exit_code, 0) << trained.err;
  EXPECT_THAT(trained.out, HasSubstr("trained 24 of 24 files into demo"));

  RunResult classified =
      Run({"classify", "--gallery", "demo", "--format", "json", Data("pyramid/test")});
  ASSERT_EQ(classified.exit_code, 0) << classified.err;
  EXPECT_EQ(Python(classified.out,
                   "len(rows), set(r['label'] for r in rows) <= "
                   "{'bar', 'cube', 'pyramid'}, all(r['points'] > 100 for r in "
                   "rows), [len(r['neighbors']) for r in rows]"),
            "(4, True, True, [1, 1, 1, 1])");

  RunResult evaluated =
      Run({"eval", "--gallery", "demo", "--test", Data(), "--format", "json", "--predictions"});
  ASSERT_EQ(evaluated.exit_code, 0) << evaluated.err;
  EXPECT_EQ(Python(evaluated.out,
                   "rows[0]['mode'], rows[0]['tests'], "
                   "rows[0]['accuracy'] >= 0.75, len(rows[0]['predictions'])"),
            "('gallery', 12, True, 12)");

  RunResult table = Run({"eval", "--gallery", "demo", "--test", Data()});
  ASSERT_EQ(table.exit_code, 0) << table.err;
  EXPECT_THAT(table.out, AllOf(HasSubstr("accuracy"), HasSubstr("pyramid")));

  RunResult csv = Run({"gallery", "list", "--format", "csv"});
  ASSERT_EQ(csv.exit_code, 0);
  EXPECT_THAT(csv.out,
              AllOf(StartsWith("NAME,SPEC,"), HasSubstr("\r\ndemo,\"rphsd:refs=cross7,bins=10")));
}

// The scene flow as a user runs it: frames of the models with their truth, then `scene` on a
// frame against a gallery of the models' views, scored against that truth.
TEST_F(CliE2ETest, ComposedScenesCarryTheirTruthAndTheSceneCommandFindsEachObject) {
  const fs::path out = *root_ / "scene-set";
  const RunResult composed = Shapeid({"views",
                                      "--quiet",
                                      "--out",
                                      out.string(),
                                      "--train-views",
                                      "0",
                                      "--test-views",
                                      "0",
                                      "--scenes",
                                      "1",
                                      "--scene-objects",
                                      "3",
                                      "--touching",
                                      "0",
                                      "--up",
                                      "z",
                                      "--seed",
                                      "4",
                                      (*root_ / "meshes/cube.off").string(),
                                      (*root_ / "meshes/bar.off").string(),
                                      (*root_ / "meshes/pyramid.off").string()});
  ASSERT_EQ(composed.exit_code, 0) << composed.err;
  const absl::StatusOr<SceneFile> scene = ReadSceneFile((out / "scenes").string(), "0000");
  ASSERT_TRUE(scene.ok()) << scene.status();
  ASSERT_EQ(scene->objects.size(), 3u);
  std::vector<size_t> truth_points(4, 0);
  for (const uint16_t id : scene->truth) ++truth_points[id];
  for (size_t id = 1; id <= 3; ++id) EXPECT_GT(truth_points[id], 100u) << id;

  ASSERT_EQ(Run({"gallery", "create", "tabletop", "--spec", "dfsd:frame=upright"}).exit_code, 0);
  ASSERT_EQ(Run({"train", "--gallery", "tabletop", Data()}).exit_code, 0);
  const RunResult found = Run({"scene", "--gallery", "tabletop", "--format", "json", "--indices",
                               (out / "scenes/0000.pcd").string()});
  ASSERT_EQ(found.exit_code, 0) << found.err;
  // Each object found is one placed object: most of its points carry one truth id, and each
  // truth id is found once.
  std::string ids;
  for (const uint16_t id : scene->truth) absl::StrAppend(&ids, ids.empty() ? "" : ",", id);
  const std::string best =
      "__import__('collections').Counter(truth[i] for i in x['indices']).most_common(1)[0]";
  EXPECT_EQ(Python(found.out,
                   absl::StrCat("(lambda truth, o: (len(o), sorted(", best, "[0] for x in o), all(",
                                best, "[1] >= 0.9 * len(x['indices']) for x in o)))([", ids,
                                "], rows[0]['objects'])")),
            "(3, [1, 2, 3], True)");
}

TEST_F(CliE2ETest, TheSensorFrameReachesTheServer) {
  ASSERT_EQ(Run({"gallery", "create", "framed", "--spec", "rphsd:refs=cross7,bins=10"}).exit_code,
            0);
  ASSERT_EQ(Run({"train", "--gallery", "framed", Data()}).exit_code, 0);
  const auto distances = [&](const std::vector<std::string>& flags) {
    std::vector<std::string> args = {"classify", "--gallery", "framed", "--format", "json"};
    args.insert(args.end(), flags.begin(), flags.end());
    args.push_back(Data("bar/test/view-000.pcd"));
    const RunResult run = Run(args);
    EXPECT_EQ(run.exit_code, 0) << run.err;
    return Python(run.out, "[round(n['distance'], 5) for n in rows[0]['neighbors']]");
  };
  const std::string plain = distances({});
  // A translation moves nothing a descriptor sees; turning the cloud on its side does.
  EXPECT_EQ(distances({"--sensor-transform", "1,0,0,5, 0,1,0,-3, 0,0,1,2"}), plain);
  EXPECT_NE(distances({"--sensor-up", "1,0,0"}), plain);
  // Train takes the frame too: trained on its side, the same view matches only when turned.
  ASSERT_EQ(Run({"gallery", "create", "sideways", "--spec", "rphsd:refs=cross7,bins=10"}).exit_code,
            0);
  ASSERT_EQ(Run({"train", "--gallery", "sideways", "--sensor-up", "1,0,0", "--label", "bar",
                 Data("bar/test/view-000.pcd")})
                .exit_code,
            0);
  const RunResult turned = Run({"classify", "--gallery", "sideways", "--format", "json",
                                "--sensor-up", "1,0,0", Data("bar/test/view-000.pcd")});
  ASSERT_EQ(turned.exit_code, 0) << turned.err;
  EXPECT_EQ(Python(turned.out, "rows[0]['neighbors'][0]['distance'] < 1e-4"), "True");
}

TEST_F(CliE2ETest, ExitCodesAsDocumented) {
  ASSERT_EQ(Run({"gallery", "create", "g"}).exit_code, 0);
  ASSERT_EQ(Run({"train", "--gallery", "g", Data()}).exit_code, 0);

  // 1: a bad file among good ones; the good ones are still classified.
  const std::string bad = WriteTempFile("bad.pcd", "VERSION 0.7\nFIELDS x y z\ngarbage\n");
  RunResult some = Run({"classify", "--gallery", "g", bad, Data("cube/test/view-000.pcd")});
  EXPECT_EQ(some.exit_code, 1);
  EXPECT_THAT(some.err, HasSubstr("bad.pcd"));
  EXPECT_THAT(some.out, HasSubstr("view-000.pcd"));

  // 2: usage.
  EXPECT_EQ(Run({"classify", "--gallery", "g"}).exit_code, 2);
  EXPECT_EQ(Run({"classify", "--gallery", "g", "--no-such-flag", Data()}).exit_code, 2);
  EXPECT_EQ(Run({"frobnicate"}).exit_code, 2);

  // 3: unreachable.
  RunResult down = Shapeid({"--server", "127.0.0.1:1", "--timeout", "2", "health"});
  EXPECT_EQ(down.exit_code, 3);
  RunResult down_classify =
      Shapeid({"--server", "127.0.0.1:1", "--timeout", "2", "classify", "--gallery", "g", Data()});
  EXPECT_EQ(down_classify.exit_code, 3);
  EXPECT_THAT(down_classify.err, HasSubstr("SHAPEID_SERVER"));

  // 4: refused.
  EXPECT_EQ(Run({"gallery", "show", "missing"}).exit_code, 4);
  EXPECT_EQ(Run({"gallery", "create", "g"}).exit_code, 4);
  EXPECT_EQ(Run({"gallery", "create", "g", "--exist-ok"}).exit_code, 0);

  // 0 and the server's health.
  RunResult health = Run({"health"});
  EXPECT_EQ(health.exit_code, 0);
  EXPECT_THAT(health.out, StartsWith("SERVING"));
  RunResult describe = Run({"describe", "--gallery", "g", Data("bar/test/view-000.pcd")});
  EXPECT_EQ(describe.exit_code, 0) << describe.err;
}

TEST_F(CliE2ETest, ExportImportClassifiesAlikeAndATruncatedFileIsRefused) {
  ASSERT_EQ(Run({"gallery", "create", "orig", "--spec", "rphsd:refs=cross7,bins=10", "--k", "3"})
                .exit_code,
            0);
  ASSERT_EQ(Run({"train", "--gallery", "orig", Data()}).exit_code, 0);
  const std::string file = WriteTempFile("orig.shapeid", "old contents, replaced");
  RunResult exported = Run({"gallery", "export", "orig", file, "--format", "json"});
  ASSERT_EQ(exported.exit_code, 0) << exported.err;
  EXPECT_EQ(Python(exported.out, "rows[0]['samples'], rows[0]['bytes']"),
            absl::StrCat("(24, ", fs::file_size(file), ")"));

  RunResult imported = Run({"gallery", "import", file, "--name", "copy"});
  ASSERT_EQ(imported.exit_code, 0) << imported.err;
  EXPECT_THAT(imported.out,
              AllOf(HasSubstr("gallery     copy"), HasSubstr("samples     24 in 3 labels")));
  // Through a pipe too: export to stdout, import from stdin.
  const std::string pipe =
      absl::StrCat(SHAPEID_CLI_PATH, " --server ", server_.address(),
                   " --quiet gallery export orig - | ", SHAPEID_CLI_PATH, " --server ",
                   server_.address(), " --quiet gallery import - --name piped", " >/dev/null");
  ASSERT_EQ(std::system(pipe.c_str()), 0);

  std::string predictions[3];
  const char* galleries[] = {"orig", "copy", "piped"};
  for (int g = 0; g < 3; ++g) {
    RunResult classified = Run({"classify", "--gallery", galleries[g], "--k", "3", "--top", "3",
                                "--format", "json", Data()});
    ASSERT_EQ(classified.exit_code, 0) << classified.err;
    predictions[g] = Python(classified.out,
                            "[(r['file'], r['label'], [(n['sample_id'], n['distance']) for n in "
                            "r['neighbors']]) for r in rows]");
  }
  EXPECT_THAT(predictions[0], HasSubstr("pyramid"));
  EXPECT_EQ(predictions[1], predictions[0]);
  EXPECT_EQ(predictions[2], predictions[0]);

  // Half a file: refused with a clear message, exit 4, and no gallery appears.
  const std::string whole = Slurp(file);
  const std::string half = WriteTempFile("half.shapeid", whole.substr(0, whole.size() / 2));
  RunResult cut = Run({"gallery", "import", half, "--name", "half"});
  EXPECT_EQ(cut.exit_code, 4);
  EXPECT_THAT(cut.err, AllOf(HasSubstr("half.shapeid is truncated"), HasSubstr("gallery import")));
  EXPECT_EQ(Run({"gallery", "show", "half"}).exit_code, 4);
  RunResult list = Run({"gallery", "list", "--format", "json"});
  EXPECT_EQ(Python(list.out, "sorted(r['name'] for r in rows)"), "['copy', 'orig', 'piped']");
}

TEST_F(CliE2ETest, ServerFromTheEnvironment) {
  const std::string command =
      absl::StrCat("SHAPEID_SERVER=", server_.address(), " ", SHAPEID_CLI_PATH, " health");
  EXPECT_EQ(std::system((command + " >/dev/null").c_str()), 0);
}

}  // namespace
}  // namespace shapeid
