// Issue 39: what one gallery costs in memory after training and after a restart on the same
// data directory. Starts the build's shapeid-server (a child process with a fresh
// --data_dir), creates one gallery (--augment_views synthetic views per cloud, 0: off), and
// trains --samples clouds in batches, each sample carrying provenance at the documented
// limits (core/gallery/sample_provenance.h: a 4,096-byte source, 64 metadata pairs of 4,096
// bytes in all) unless --no_provenance. It reads the server's VmRSS (/proc/PID/status) with
// the gallery empty, after training, then restarts the server (SIGTERM, a new process on the
// same directory) and reads it again once the gallery has loaded. Medians of --reps runs;
// prints one markdown table row per run and the medians, with the command and machine.
//
//   restart_memory_bench --samples 60000 --reps 3
//   restart_memory_bench --samples 20000 --augment_views 8 --reps 3
//   restart_memory_bench --samples 60000 --no_provenance --reps 3
//
// The server is the only big process it measures; the load generator (this program) is not.
//
// --trim also reads VmRSS after calling malloc_trim(0) in the server (through gdb, which must
// be installed and allowed to attach), after training and after the restart: what the heap
// really holds, without the freed memory glibc keeps.

#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "CLI/CLI.hpp"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "absl/time/clock.h"
#include "absl/time/time.h"
#include "bench/host_info.h"
#include "client/client.h"
#include "core/testing/test_clouds.h"
#include "server/testing/child_server.h"

namespace shapeid {
namespace {

constexpr char kGallery[] = "restart";

double MiB(int64_t bytes) { return static_cast<double>(bytes) / (1 << 20); }

double Median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0.0 : v[v.size() / 2];
}

std::unique_ptr<Client> Connect(const std::string& target) {
  ClientOptions options;
  options.target = target;
  options.deadline = absl::Minutes(10);
  options.max_attempts = 1;
  absl::StatusOr<std::unique_ptr<Client>> client = Client::Connect(options);
  if (!client.ok()) {
    std::fprintf(stderr, "restart_memory_bench: %s\n", client.status().ToString().c_str());
    std::exit(1);
  }
  return *std::move(client);
}

// `text` repeated and cut to exactly `bytes` bytes.
std::string Filled(const std::string& text, size_t bytes) {
  std::string out;
  while (out.size() < bytes) out += text;
  out.resize(bytes);
  return out;
}

// Provenance at the limits, different for every sample: a 4,096-byte source and 64 pairs of
// a 16-byte key and a 48-byte value (4,096 bytes of keys and values).
void FillProvenance(uint64_t i, TrainSample& sample) {
  sample.source = Filled(absl::StrCat("/data/scans/session-", i % 97, "/cloud-", i, ".pcd/"), 4096);
  for (int k = 0; k < 64; ++k) {
    sample.metadata[Filled(absl::StrCat("key", k < 10 ? "0" : "", k, "-"), 16)] =
        Filled(absl::StrCat("value of sample ", i, " key ", k, "; "), 48);
  }
}

struct Options {
  std::string server = SHAPEID_SERVER_PATH;
  std::string dir;
  int64_t samples = 60000;
  int batch = 500;
  int streams = 2;
  int points = 512;
  int augment_views = 0;
  bool no_provenance = false;
  int reps = 3;
  double settle_seconds = 3;
  bool keep_data = false;
  bool trim = false;
};

struct Run {
  int64_t empty = 0, trained = 0, restarted = 0, restarted_peak = 0;
  int64_t trained_trimmed = 0, restarted_trimmed = 0;  // --trim only
  double train_seconds = 0, load_seconds = 0;
};

// The server's VmRSS after it has called malloc_trim(0) (gdb attaches and calls it).
int64_t TrimmedResidentBytes(const ChildServer& server) {
  const std::string command = absl::StrCat(
      "gdb -p ", server.pid(), " -batch -ex 'call (int)malloc_trim(0)' > /dev/null 2>&1");
  if (std::system(command.c_str()) != 0) return 0;
  return server.ResidentBytes();
}

absl::Status StartServer(const Options& o, ChildServer& server, const std::string& log) {
  return server.Start(
      o.server,
      {"--listen=127.0.0.1:0", "--data_dir=" + o.dir + "/data", "--log_level=warning",
       absl::StrCat("--max_samples_per_gallery=", std::max<int64_t>(o.samples, 1))},
      log, absl::Minutes(10));
}

absl::StatusOr<Run> MeasureOnce(const Options& o) {
  std::filesystem::remove_all(o.dir + "/data");
  Run run;
  {
    ChildServer server;
    if (absl::Status s = StartServer(o, server, o.dir + "/train.stderr"); !s.ok()) return s;
    std::unique_ptr<Client> client = Connect(server.address());
    v1::CreateGalleryRequest create;
    create.set_name(kGallery);
    if (o.augment_views > 0) create.mutable_augmentation()->set_views(o.augment_views);
    if (absl::StatusOr<v1::Gallery> made = client->CreateGallery(create); !made.ok()) {
      return made.status();
    }
    absl::SleepFor(absl::Seconds(o.settle_seconds));
    run.empty = server.ResidentBytes();

    const absl::Time start = absl::Now();
    std::atomic<int64_t> next{0};
    std::atomic<bool> failed{false};
    absl::Status error;
    std::vector<std::thread> streams;
    for (int t = 0; t < o.streams; ++t) {
      streams.emplace_back([&, t] {
        std::unique_ptr<Client> own = Connect(server.address());
        std::vector<PointCloud> clouds;
        std::vector<TrainSample> batch;
        while (!failed) {
          const int64_t first = next.fetch_add(o.batch);
          if (first >= o.samples) return;
          const int64_t end = std::min<int64_t>(first + o.batch, o.samples);
          clouds.clear();
          batch.clear();
          clouds.reserve(static_cast<size_t>(end - first));
          for (int64_t i = first; i < end; ++i) {
            clouds.push_back(testing_clouds::ShapeCloud(static_cast<int>(i % 3),
                                                        static_cast<uint32_t>(i + 1),
                                                        static_cast<size_t>(o.points)));
          }
          for (int64_t i = first; i < end; ++i) {
            TrainSample sample;
            sample.label = absl::StrCat("class-", i % 40);
            sample.sample_id = static_cast<uint64_t>(i + 1);
            sample.cloud = &clouds[static_cast<size_t>(i - first)];
            if (!o.no_provenance) FillProvenance(static_cast<uint64_t>(i), sample);
            batch.push_back(std::move(sample));
          }
          absl::StatusOr<v1::TrainResponse> trained = own->Train(kGallery, batch);
          if (!trained.ok() && !failed.exchange(true)) {
            error = trained.status();
            std::fprintf(stderr, "stream %d: Train: %s\n", t, error.ToString().c_str());
          }
        }
      });
    }
    for (std::thread& s : streams) s.join();
    if (failed) return error;
    run.train_seconds = absl::ToDoubleSeconds(absl::Now() - start);
    absl::SleepFor(absl::Seconds(o.settle_seconds));
    run.trained = server.ResidentBytes();
    if (o.trim) run.trained_trimmed = TrimmedResidentBytes(server);
    if (server.Terminate(absl::Minutes(2)) != 0) {
      return absl::InternalError("the server did not exit cleanly on SIGTERM");
    }
  }
  ChildServer server;
  const absl::Time start = absl::Now();
  if (absl::Status s = StartServer(o, server, o.dir + "/load.stderr"); !s.ok()) return s;
  run.load_seconds = absl::ToDoubleSeconds(absl::Now() - start);
  std::unique_ptr<Client> client = Connect(server.address());
  absl::StatusOr<v1::Gallery> loaded = client->GetGallery(kGallery);
  if (!loaded.ok()) return loaded.status();
  if (loaded->sample_count() != static_cast<uint64_t>(o.samples)) {
    return absl::InternalError(absl::StrCat("the restarted server holds ", loaded->sample_count(),
                                            " samples, not ", o.samples));
  }
  absl::SleepFor(absl::Seconds(o.settle_seconds));
  run.restarted = server.ResidentBytes();
  run.restarted_peak = server.PeakResidentBytes();
  if (o.trim) run.restarted_trimmed = TrimmedResidentBytes(server);
  server.Terminate(absl::Minutes(2));
  return run;
}

int Main(int argc, char** argv) {
  CLI::App app("restart_memory_bench: a gallery's server memory after training and restart");
  Options o;
  app.add_option("--server", o.server, "the shapeid-server binary to measure");
  app.add_option("--dir", o.dir, "work directory (default: a fresh one under the temp dir)");
  app.add_option("--samples", o.samples, "samples trained");
  app.add_option("--batch", o.batch, "samples per Train call");
  app.add_option("--streams", o.streams, "Train calls at once");
  app.add_option("--points", o.points, "points per training cloud");
  app.add_option("--augment_views", o.augment_views, "synthetic views per cloud (0: off)");
  app.add_flag("--no_provenance", o.no_provenance, "train without provenance");
  app.add_option("--reps", o.reps, "runs; the table gives each and the medians");
  app.add_option("--settle_seconds", o.settle_seconds, "pause before each RSS reading");
  app.add_flag("--keep_data", o.keep_data, "keep the last run's data directory (DIR/data)");
  app.add_flag("--trim", o.trim, "also read VmRSS after malloc_trim(0) in the server (gdb)");
  CLI11_PARSE(app, argc, argv);
  if (o.dir.empty()) {
    o.dir = absl::StrCat(std::filesystem::temp_directory_path().string(), "/restart_memory_bench_",
                         getpid());
  }
  std::filesystem::create_directories(o.dir);

  std::vector<std::string> args(argv, argv + argc);
  std::printf("command: %s\nserver: %s\nmachine: %s, %u hardware threads, load %s\n\n",
              absl::StrJoin(args, " ").c_str(), o.server.c_str(), bench::CpuModel().c_str(),
              std::thread::hardware_concurrency(), bench::LoadAverages().c_str());
  std::printf(
      "| run | RSS empty (MiB) | RSS trained (MiB) | RSS after restart (MiB) | restart / "
      "trained | peak during load (MiB) | per sample (KiB) | train (s) | load (s) |\n"
      "|---|---|---|---|---|---|---|---|---|\n");
  std::vector<double> empty, trained, restarted, ratio, peak, per_sample;
  for (int r = 0; r < o.reps; ++r) {
    absl::StatusOr<Run> run = MeasureOnce(o);
    if (!run.ok()) {
      std::fprintf(stderr, "restart_memory_bench: %s\n", run.status().ToString().c_str());
      return 1;
    }
    empty.push_back(MiB(run->empty));
    trained.push_back(MiB(run->trained));
    restarted.push_back(MiB(run->restarted));
    ratio.push_back(static_cast<double>(run->restarted) / static_cast<double>(run->trained));
    peak.push_back(MiB(run->restarted_peak));
    per_sample.push_back(static_cast<double>(run->trained - run->empty) / 1024.0 /
                         static_cast<double>(std::max<int64_t>(o.samples, 1)));
    std::printf("| %d | %.1f | %.1f | %.1f | %.3f | %.1f | %.2f | %.1f | %.1f |\n", r + 1,
                empty.back(), trained.back(), restarted.back(), ratio.back(), peak.back(),
                per_sample.back(), run->train_seconds, run->load_seconds);
    if (o.trim) {
      std::printf("|   | after malloc_trim(0): | %.1f | %.1f | %.3f | | | | |\n",
                  MiB(run->trained_trimmed), MiB(run->restarted_trimmed),
                  static_cast<double>(run->restarted_trimmed) /
                      static_cast<double>(std::max<int64_t>(run->trained_trimmed, 1)));
    }
    std::fflush(stdout);
  }
  std::printf("| median | %.1f | %.1f | %.1f | %.3f | %.1f | %.2f | | |\n", Median(empty),
              Median(trained), Median(restarted), Median(ratio), Median(peak), Median(per_sample));
  if (!o.keep_data) std::filesystem::remove_all(o.dir);
  return 0;
}

}  // namespace
}  // namespace shapeid

int main(int argc, char** argv) { return shapeid::Main(argc, argv); }
