// The shapeid command-line tool: flags -> an options struct -> a command returning an exit
// code. Commands live in their own files; this file only knows CLI11.

#include <cstdio>
#include <cstdlib>
#include <string>
#include <utility>

#include "CLI/CLI.hpp"
#include "absl/strings/str_join.h"
#include "client/cli/cli_common.h"
#include "client/cli/describe_command.h"
#include "client/cli/eval_command.h"
#include "client/cli/gallery_commands.h"
#include "client/cli/operations_commands.h"
#include "client/cli/scene_command.h"
#include "client/cli/train_classify_commands.h"
#include "client/cli/views_command.h"
#include "core/io/point_cloud_reader.h"
#include "core/io/reader_registry.h"
#include "core/request_id.h"

namespace {

constexpr char kMainFooter[] =
    "Server: --server HOST:PORT, or the SHAPEID_SERVER environment variable (default\n"
    "127.0.0.1:50051; a host without a port gets 50051). Replicas: a comma list,\n"
    "HOST:PORT,HOST:PORT (names looked up once), or dns:///NAME:PORT for every address of\n"
    "NAME; calls go to each in turn and a call a replica cannot serve is retried on another\n"
    "(--load-balancing pick_first: one at a time). Global flags (--server, --load-balancing,\n"
    "--timeout, --format, --quiet, --tls*, --api-key-file, --request-id, --caller-id) go before\n"
    "or after the command.\n"
    "\n"
    "Request ids: every call of one run carries the same x-request-id, which the server writes\n"
    "in its log: --request-id ID (SHAPEID_REQUEST_ID), or a random \"cli-\" and 16 hex digits.\n"
    "A failed call's error line ends with it: [request id ID]; grep the server's log for it.\n"
    "\n"
    "Secure servers (docs/security.md): the API key comes from SHAPEID_API_KEY or\n"
    "--api-key-file (not a flag of its own: command lines are visible to every user of the\n"
    "machine); --tls-ca CA.pem (SHAPEID_TLS_CA) turns TLS on and trusts that CA, --tls alone\n"
    "trusts the system's CAs; --tls-client-cert/--tls-client-key\n"
    "(SHAPEID_TLS_CLIENT_CERT/_KEY) for mutual TLS.\n"
    "\n"
    "Output (--format): table for people (default), json (one JSON object per line) for\n"
    "scripts, csv (header row, RFC 4180) for spreadsheets. Results go to stdout; errors and\n"
    "progress to stderr (a live bar on a terminal, a line every 5 s otherwise; --quiet: none).\n"
    "\n"
    "Exit status:\n"
    "  0  everything succeeded\n"
    "  1  some inputs failed (one line each on stderr); the others were processed\n"
    "  2  usage error: bad flags, spec or paths; nothing was done\n"
    "  3  the server is unreachable or did not answer in time\n"
    "  4  the server refused the command (unknown or existing gallery, bad argument...)\n"
    "  5  the server's answer was larger than this client reads (256 MiB): this client\n"
    "     refused it, not the server; ask for less (--k, --limit)\n"
    "\n"
    "Examples:\n"
    "  shapeid gallery create parts --spec rphsd --k 3\n"
    "  shapeid train --gallery parts dataset/            # dataset/<label>/... per label\n"
    "  shapeid train --gallery parts --label bolt scans/bolt-*.pcd\n"
    "  shapeid classify --gallery parts new-scans/\n"
    "  shapeid scene --gallery parts --picture scene.png frame.pcd  # objects on a table\n"
    "  shapeid eval --gallery parts --test dataset/      # dataset/<label>/test/...\n"
    "  shapeid eval --folds 5 --spec rphsd --report report.html dataset/\n"
    "  shapeid describe --local --spec comsd:grid=50 chair.pcd\n"
    "  shapeid stats                                     # the server's calls, latency, memory\n"
    "Run 'shapeid COMMAND --help' for each command's flags.\n";

// How the commands that read files read them.
void AddReadFlags(CLI::App* command, shapeid::ReadOptions* read, bool* skip_unsupported) {
  command->add_flag("--drop-nonfinite", read->drop_non_finite,
                    "Remove points with NaN or infinite coordinates (organized PCD clouds) "
                    "instead of failing on them");
  command
      ->add_option("--mesh-points", read->sample_points,
                   "Points sampled on each mesh's faces (.ply with faces, .off, .obj, .stl, "
                   ".vtk with polygons); 0 reads the vertices")
      ->check(CLI::Range(size_t{0}, size_t{10000000}))
      ->capture_default_str();
  command
      ->add_option_function<std::string>(
          "--input-format",
          [read](const std::string& name) {
            read->input_format = shapeid::CloudFormatForName(name).value();  // checked below
          },
          "Read every input as this format whatever its extension; needed for standard input "
          "(FILE \"-\"). Without it a file is read by its extension, or, when that is missing "
          "or unknown, by its first bytes (" +
              shapeid::FormatsWithSignatures() +
              "): " + absl::StrJoin(shapeid::CloudFormatNames(), ", "))
      ->check([](const std::string& name) {
        const absl::StatusOr<shapeid::CloudFormat> format = shapeid::CloudFormatForName(name);
        return format.ok() ? std::string() : std::string(format.status().message());
      });
  command->add_flag("--skip-unsupported", *skip_unsupported,
                    "Ignore files of other formats inside folders (by default they are listed "
                    "and the exit status is 1)");
}

// Flags shared by the batch commands.
void AddBatchFlags(CLI::App* command, shapeid::BatchOptions* batch) {
  command->add_option("--jobs,-j", batch->jobs, "Parallel streams to the server")
      ->check(CLI::Range(1, 256))
      ->capture_default_str();
  AddReadFlags(command, &batch->read, &batch->skip_unsupported);
}

// The sensor's frame of describe, train and classify (the proto's SensorFrame).
void AddSensorFrameFlags(CLI::App* command, shapeid::SensorFrameFlags* flags) {
  command->add_option("--sensor-up", flags->up,
                      "Which way is up in the clouds' frame, X,Y,Z (a camera's optical frame: "
                      "0,-1,0); the points are turned so that it is the gallery's up");
  command->add_option("--sensor-transform", flags->transform,
                      "A rigid transform from the clouds' frame to the gallery's (a sensor-to-"
                      "base transform): 12 numbers, the rows of [R | t]");
}

void AddGalleryKnobs(CLI::App* command, shapeid::GalleryCreateOptions* create) {
  command->add_option("--spec", create->spec,
                      "Descriptor spec, KIND[:param=value,...] (default: the server's, dfsd)");
  command->add_option("--k", create->k, "Neighbors that vote (default 1)")
      ->check(CLI::Range(1u, 1000000u));
  command->add_option("--weighting", create->weighting, "Votes: uniform or distance")
      ->check(CLI::IsMember({"uniform", "distance"}));
  command
      ->add_option("--scaling", create->scaling,
                   "Per-feature scaling before distances: none, zscore or maxabs")
      ->check(CLI::IsMember({"none", "zscore", "maxabs"}));
  command
      ->add_option("--reject-distance", create->reject_distance,
                   "Answer \"unknown\" when the nearest sample is farther than this "
                   "(0: never)")
      ->check(CLI::NonNegativeNumber);
  command
      ->add_option("--augment-views", create->augment_views,
                   "Also train N synthetic single-view scans of each cloud (one side, 1 % "
                   "noise, 300-500 points): for robots that see one side of objects trained "
                   "whole. Costs (1 + N) x memory and search time (0: off)")
      ->check(CLI::Range(0u, 64u));
  command
      ->add_option("--augment-mix", create->augment_mix,
                   "How the synthetic views are made: camera (a depth camera's visible side) "
                   "or varied (camera, plane cuts and occluded cameras in turn, noise 0 to 2 %)")
      ->check(CLI::IsMember({"camera", "varied"}));
  command->add_flag("--augment-random-pose", create->augment_random_pose,
                    "Turn each synthetic view to a random 3D pose (for descriptors that are "
                    "not rotation invariant)");
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app("shapeid: 3D object recognition from point clouds", "shapeid");
  app.set_version_flag("--version", std::string("shapeid ") + SHAPEID_VERSION);
  app.require_subcommand(1);
  app.fallthrough();
  app.footer(kMainFooter);

  shapeid::CliContext context;
  if (const char* server = std::getenv("SHAPEID_SERVER"); server != nullptr && *server) {
    context.client.target = server;
  }
  std::string format = "table";
  double timeout_seconds = 30;
  bool quiet = false;
  app.add_option("--server", context.client.target,
                 "shapeid-server address: HOST[:PORT] (port 50051 if none), a comma list of "
                 "replicas, or a gRPC target (dns:///NAME:PORT, unix:///PATH)")
      ->envname("SHAPEID_SERVER")
      ->capture_default_str();
  app.add_option("--load-balancing", context.client.load_balancing,
                 "How calls spread over replicas: round_robin (each in turn, skipping those not "
                 "serving) or pick_first (one until it fails)")
      ->envname("SHAPEID_LOAD_BALANCING")
      ->check(CLI::IsMember({"round_robin", "pick_first"}))
      ->capture_default_str();
  app.add_option("--timeout", timeout_seconds, "Seconds allowed for each call, retries included")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--format", format, "Output: table, json or csv")
      ->check(CLI::IsMember({"table", "text", "json", "csv"}))
      ->capture_default_str();
  app.add_flag("--quiet,-q", quiet, "No progress or summary lines on stderr");
  std::string api_key_file;
  app.add_option("--api-key-file", api_key_file,
                 "File holding the API key to send (instead of SHAPEID_API_KEY)")
      ->envname("SHAPEID_API_KEY_FILE");
  app.add_flag("--tls", context.client.tls,
               "Connect with TLS, trusting the system's CAs (implied by --tls-ca)")
      ->envname("SHAPEID_TLS");
  app.add_option("--tls-ca", context.client.tls_ca_file,
                 "PEM file of the CA that signs the server's certificate; turns TLS on")
      ->envname("SHAPEID_TLS_CA");
  // Not SHAPEID_TLS_CERT/_KEY: those are the server's own certificate (shapeid-server
  // --tls_cert), and a container that runs both must not mix them up.
  app.add_option("--tls-client-cert", context.client.tls_cert_file,
                 "PEM certificate of this client, for servers that require one (mutual TLS)")
      ->envname("SHAPEID_TLS_CLIENT_CERT");
  app.add_option("--tls-client-key", context.client.tls_key_file,
                 "PEM private key of --tls-client-cert")
      ->envname("SHAPEID_TLS_CLIENT_KEY");
  app.add_option("--tls-server-name", context.client.tls_server_name,
                 "Name the server's certificate must carry, when not the --server host")
      ->envname("SHAPEID_TLS_SERVER_NAME");
  app.add_option("--request-id", context.client.request_id,
                 "Id sent with every call of this run, and logged by the server (default: a "
                 "random cli-XXXXXXXXXXXXXXXX)")
      ->envname("SHAPEID_REQUEST_ID")
      ->check([](const std::string& id) {
        const absl::Status status = shapeid::CheckRequestId(id);
        return status.ok() ? std::string() : std::string(status.message());
      });
  app.add_option("--caller-id", context.client.caller_id,
                 "This client's own name for the server's fair shares, on a server without API "
                 "keys where several robots share one host (1-64 of A-Z a-z 0-9 . _ : -)")
      ->envname("SHAPEID_CALLER_ID")
      ->check([](const std::string& id) {
        return shapeid::IsValidCallerId(id)
                   ? std::string()
                   : std::string("a caller id is 1 to 64 characters of A-Z a-z 0-9 . _ : -");
      });

  // describe
  shapeid::DescribeOptions describe;
  CLI::App* describe_cmd = app.add_subcommand(
      "describe", "Compute the shape descriptor of each point-cloud file, one line per file");
  describe_cmd->fallthrough();
  describe_cmd->add_flag("--local", describe.local,
                         "Compute in this process instead of on the server");
  describe_cmd->add_option("--spec", describe.spec,
                           "Descriptor spec: KIND[:param=value,...] (default dfsd)");
  describe_cmd->add_option("--gallery", describe.gallery,
                           "Describe with this gallery's spec (server only)");
  describe_cmd
      ->add_option("--threads", describe.threads,
                   "With --local: threads for one large cloud (default: one per core)")
      ->check(CLI::NonNegativeNumber);
  AddReadFlags(describe_cmd, &describe.read, &describe.skip_unsupported);
  shapeid::SensorFrameFlags sensor_flags;  // one subcommand runs: they share it
  AddSensorFrameFlags(describe_cmd, &sensor_flags);
  describe_cmd
      ->add_option("FILE", describe.files,
                   "Point-cloud files or folders (- reads standard input): " +
                       shapeid::SupportedExtensions())
      ->required()
      ->type_name("");
  describe_cmd->footer(shapeid::DescribeHelpFooter());

  // gallery create|list|show|delete|remove|samples|export|import
  CLI::App* gallery_cmd =
      app.add_subcommand("gallery", "Create, list, show, delete, export and import galleries");
  gallery_cmd->fallthrough();
  gallery_cmd->require_subcommand(1);
  shapeid::GalleryCreateOptions create;
  CLI::App* create_cmd = gallery_cmd->add_subcommand("create", "Create an empty gallery");
  create_cmd->fallthrough();
  create_cmd->add_option("NAME", create.name, "Gallery name")->required();
  AddGalleryKnobs(create_cmd, &create);
  create_cmd->add_flag("--exist-ok", create.exist_ok,
                       "Succeed when the gallery already exists (its settings are kept)");
  CLI::App* list_cmd = gallery_cmd->add_subcommand("list", "List the galleries");
  list_cmd->fallthrough();
  std::string gallery_name;
  CLI::App* show_cmd = gallery_cmd->add_subcommand("show", "Show a gallery and its labels");
  show_cmd->fallthrough();
  show_cmd->add_option("NAME", gallery_name, "Gallery name")->required();
  bool missing_ok = false;
  CLI::App* delete_cmd =
      gallery_cmd->add_subcommand("delete", "Delete a gallery and all its samples");
  delete_cmd->fallthrough();
  delete_cmd->add_option("NAME", gallery_name, "Gallery name")->required();
  delete_cmd->add_flag("--missing-ok", missing_ok, "Succeed when the gallery does not exist");
  shapeid::GalleryRemoveOptions remove;
  CLI::App* remove_cmd = gallery_cmd->add_subcommand("remove", "Remove samples by label and/or id");
  remove_cmd->fallthrough();
  remove_cmd->add_option("NAME", remove.name, "Gallery name")->required();
  remove_cmd->add_option("--label", remove.labels, "Remove every sample of this label");
  remove_cmd->add_option("--id", remove.sample_ids, "Remove the sample with this id");
  shapeid::GallerySamplesOptions samples;
  CLI::App* samples_cmd = gallery_cmd->add_subcommand(
      "samples", "List a gallery's samples with where each came from (source, metadata)");
  samples_cmd->fallthrough();
  samples_cmd->add_option("NAME", samples.name, "Gallery name")->required();
  samples_cmd->add_option("--label", samples.label, "Only the samples of this label");
  samples_cmd->add_option("--limit", samples.limit, "At most this many samples (0: all)")
      ->capture_default_str();
  std::string gallery_file, import_name;
  CLI::App* export_cmd = gallery_cmd->add_subcommand(
      "export", "Write a gallery to a portable file (a backup, or to move it to another server)");
  export_cmd->fallthrough();
  export_cmd->add_option("NAME", gallery_name, "Gallery name")->required();
  export_cmd->add_option("FILE", gallery_file, "File to write ('-': stdout)")->required();
  CLI::App* import_cmd = gallery_cmd->add_subcommand(
      "import", "Create a gallery from a file written by 'gallery export'");
  import_cmd->fallthrough();
  import_cmd->add_option("FILE", gallery_file, "File to read ('-': stdin)")->required();
  import_cmd->add_option("--name", import_name,
                         "Import under this name instead of the exported one");

  CLI::App* descriptors_cmd =
      app.add_subcommand("descriptors", "List the server's descriptor kinds and parameters");
  descriptors_cmd->fallthrough();
  CLI::App* health_cmd =
      app.add_subcommand("health", "Check that the server is serving (exit 0) or not (exit 3)");
  health_cmd->fallthrough();

  CLI::App* stats_cmd = app.add_subcommand(
      "stats", "The server's live summary: state, memory, calls and latency, galleries");
  stats_cmd->fallthrough();
  std::string log_level;
  CLI::App* log_level_cmd = app.add_subcommand(
      "log-level", "Set the server's log level until it restarts (admin key on secure servers)");
  log_level_cmd->fallthrough();
  log_level_cmd->add_option("LEVEL", log_level, "debug, info, warning or error")->required();

  // train
  shapeid::TrainOptions train;
  CLI::App* train_cmd = app.add_subcommand(
      "train", "Add labeled clouds to a gallery: --label L FILE..., or labeled folders");
  train_cmd->fallthrough();
  train_cmd->add_option("--gallery,-g", train.gallery, "Gallery to add to")->required();
  train_cmd->add_option("--label,-l", train.label,
                        "Label of every file given; without it each path is a folder with "
                        "one sub-folder per label (<label>/train/ used where present)");
  train_cmd
      ->add_option("--batch", train.batch.train_batch,
                   "Samples per Train stream (each stream is all-or-nothing)")
      ->check(CLI::Range(size_t{1}, size_t{100000}))
      ->capture_default_str();
  AddBatchFlags(train_cmd, &train.batch);
  AddSensorFrameFlags(train_cmd, &sensor_flags);
  train_cmd
      ->add_option("--metadata", train.metadata,
                   "KEY=VALUE kept with every sample of this call (repeatable), beside its "
                   "file's path; shown with neighbors and by `gallery samples`")
      ->type_name("KEY=VALUE")
      ->allow_extra_args(false);  // one value per --metadata: the files after it stay files
  train_cmd->add_option("PATH", train.paths, "Files or folders")->required()->type_name("");

  // classify
  shapeid::ClassifyOptions classify;
  CLI::App* classify_cmd =
      app.add_subcommand("classify", "Classify each cloud: label, confidence, nearest samples");
  classify_cmd->fallthrough();
  classify_cmd->add_option("--gallery,-g", classify.gallery, "Gallery to search")->required();
  classify_cmd->add_option("--k", classify.call.k, "Neighbors that vote (default: the gallery's)")
      ->check(CLI::Range(1u, 1000000u));
  classify_cmd->add_flag("--exact", classify.call.exact,
                         "Search every stored vector, even where the server searches the gallery "
                         "approximately (see `gallery info`)");
  classify_cmd->add_option("--top", classify.top, "Nearest samples shown per file")
      ->check(CLI::Range(0, 100))
      ->capture_default_str();
  AddBatchFlags(classify_cmd, &classify.batch);
  AddSensorFrameFlags(classify_cmd, &sensor_flags);
  classify_cmd->add_option("PATH", classify.paths, "Files or folders")->required()->type_name("");

  // eval
  shapeid::EvalOptions eval;
  CLI::App* eval_cmd = app.add_subcommand(
      "eval", "Accuracy on a labeled folder: hold-out, k-fold, or against a gallery");
  eval_cmd->fallthrough();
  eval_cmd->add_option("--gallery,-g", eval.gallery,
                       "Test against this existing gallery (no training; server only)");
  eval_cmd->add_flag("--local", eval.local,
                     "Train and classify in this process on temporary galleries: no server, "
                     "the same results; --jobs threads");
  eval_cmd
      ->add_option("--test,DIR", eval.dataset,
                   "Labeled folder: <label>/{train,test}/ (hold-out) or <label>/ "
                   "(k-fold)")
      ->required();
  eval_cmd->add_option("--folds", eval.folds, "Stratified k-fold cross-validation with K folds")
      ->check(CLI::Range(2, 100));
  eval_cmd->add_option("--seed", eval.seed, "Seed of the k-fold shuffle")->capture_default_str();
  AddGalleryKnobs(eval_cmd, &eval.create);
  eval_cmd
      ->add_option("--learn", eval.create.learn,
                   "With --local: mlp fits each round's gallery its trained head (a small "
                   "network over the gallery's vectors, issue 40) before testing, and answers "
                   "with the head and the kNN vote together; off (default): the kNN vote")
      ->check(CLI::IsMember({"off", "mlp"}));
  eval_cmd->add_option("--report", eval.report_html, "Also write a self-contained HTML report");
  eval_cmd->add_flag("--predictions", eval.with_predictions,
                     "json: include every test cloud's prediction and its neighbors");
  eval.batch.jobs = 4;
  AddBatchFlags(eval_cmd, &eval.batch);
  eval_cmd->footer(
      "Modes:\n"
      "  eval --gallery G --test DIR   classify DIR/<label>/test/ (or DIR/<label>/) against G\n"
      "  eval DIR                      DIR/<label>/{train,test}/: train a temporary gallery, test\n"
      "  eval --folds K DIR            DIR/<label>/: stratified K-fold, a temporary gallery per "
      "fold\n"
      "Temporary galleries take --spec/--k/--weighting/--scaling/--reject-distance and are\n"
      "deleted afterwards.\n"
      "\n"
      "--local runs the hold-out or k-fold rounds in this process with the server's own gallery\n"
      "code (no server needed): the same predictions, --jobs threads describing clouds,\n"
      "samples added in file order; without --spec, this build's default descriptor. Not with\n"
      "--gallery.\n"
      "  shapeid eval --local --spec rphsd ../shared/data/modelnet10\n"
      "  shapeid eval --local --folds 5 --report report.html dataset/\n");

  // scene
  shapeid::SceneCommandOptions scene;
  CLI::App* scene_cmd = app.add_subcommand(
      "scene", "Find the objects in sensor frames (a table with things on it) and classify each");
  scene_cmd->fallthrough();
  shapeid::AddSceneFlags(scene_cmd, &scene);
  AddReadFlags(scene_cmd, &scene.read, &scene.skip_unsupported);
  scene_cmd->get_option("--drop-nonfinite")
      ->description(
          "Remove points with NaN or infinite coordinates before sending them; by default they "
          "are sent, skipped and counted by the server, so that indices and --colored keep the "
          "file's points");
  AddSensorFrameFlags(scene_cmd, &sensor_flags);

  // views
  shapeid::ViewsOptions views;
  CLI::App* views_cmd = app.add_subcommand(
      "views", "Simulate depth-sensor scans of meshes: a labeled <mesh>/{train,test}/ dataset");
  views_cmd->fallthrough();
  shapeid::AddViewsFlags(views_cmd, &views);

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    if (e.get_exit_code() == static_cast<int>(CLI::ExitCodes::Success)) {
      return app.exit(e);  // --help, --version
    }
    std::fprintf(stderr, "shapeid: %s (see shapeid --help)\n", e.what());
    return shapeid::kExitUsage;
  }
  context.format = *shapeid::ParseOutputFormat(format);  // checked by IsMember above
  context.progress = quiet ? shapeid::ProgressMode::kOff : shapeid::ProgressMode::kAuto;
  context.client.deadline = absl::Seconds(timeout_seconds);
  // One id for every call of this run, so that the server's log lines of a batch share it.
  if (context.client.request_id.empty()) context.client.request_id = shapeid::NewRequestId();
  // The key: from the environment only, or from a file; never echoed.
  if (const char* key = std::getenv("SHAPEID_API_KEY"); key != nullptr && *key) {
    context.client.api_key = key;
  }
  if (!api_key_file.empty()) {
    if (!context.client.api_key.empty()) {
      std::fprintf(stderr,
                   "shapeid: both SHAPEID_API_KEY and --api-key-file (or SHAPEID_API_KEY_FILE) "
                   "are set; keep one\n");
      return shapeid::kExitUsage;
    }
    absl::StatusOr<std::string> key = shapeid::ReadApiKeyFile(api_key_file);
    if (!key.ok()) {
      std::fprintf(stderr, "shapeid: %s\n", std::string(key.status().message()).c_str());
      return shapeid::kExitUsage;
    }
    context.client.api_key = *std::move(key);
  }

  {
    absl::StatusOr<shapeid::v1::SensorFrame> frame = shapeid::ParseSensorFrame(sensor_flags);
    if (!frame.ok()) {
      std::fprintf(stderr, "shapeid: %s\n", std::string(frame.status().message()).c_str());
      return shapeid::kExitUsage;
    }
    describe.sensor_frame = *frame;
    train.batch.sensor_frame = *frame;
    classify.call.sensor_frame = *frame;
    scene.call.sensor_frame = *std::move(frame);
  }
  if (*describe_cmd) return shapeid::RunDescribe(describe, context);
  if (*create_cmd) return shapeid::RunGalleryCreate(create, context);
  if (*list_cmd) return shapeid::RunGalleryList(context);
  if (*show_cmd) return shapeid::RunGalleryShow(gallery_name, context);
  if (*delete_cmd) return shapeid::RunGalleryDelete(gallery_name, missing_ok, context);
  if (*remove_cmd) return shapeid::RunGalleryRemove(remove, context);
  if (*samples_cmd) return shapeid::RunGallerySamples(samples, context);
  if (*export_cmd) return shapeid::RunGalleryExport(gallery_name, gallery_file, context);
  if (*import_cmd) return shapeid::RunGalleryImport(gallery_file, import_name, context);
  if (*descriptors_cmd) return shapeid::RunDescriptors(context);
  if (*health_cmd) return shapeid::RunHealth(context);
  if (*stats_cmd) return shapeid::RunStats(context);
  if (*log_level_cmd) return shapeid::RunLogLevel(log_level, context);
  if (*train_cmd) return shapeid::RunTrain(train, context);
  if (*classify_cmd) return shapeid::RunClassify(classify, context);
  if (*eval_cmd) return shapeid::RunEval(eval, context);
  if (*views_cmd) return shapeid::RunViews(views, context);
  if (*scene_cmd) return shapeid::RunScene(scene, context);
  return shapeid::kExitUsage;
}
