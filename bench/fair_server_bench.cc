// A shared server that one client cannot freeze (issue 25), at full size: one caller
// ("abuser") streams heavy Describe calls (by default two at once, 10,000,000 points each,
// the default dfsd) while another caller ("lab") classifies 1,024-point clouds with
// ClassifyCloud and a probe checks grpc.health.v1 on the main port and on --health_listen,
// each with the 3 s deadline of a Kubernetes probe. The lab's and the probes' latencies idle
// and under the abuse, every failure by caller, the server's resident memory before and at
// its peak against its memory budget.
//
//   fair_server_bench                        the build's shapeid-server, ~1 min
//   fair_server_bench --server OLD/shapeid-server --no_budget_flags
//                                            an older build (before issue 25) in the same way
//   fair_server_bench --points 2000000 --seconds 5   smaller
//   fair_server_bench --abuse learn          issue 40: the server fits a trained head over a
//                                            gallery of --learn_samples clouds with 16 views each
//                                            (trained before the phase), at nice 19; the phase
//                                            lasts until the head is published
//   fair_server_bench --abuse cheap|scenes|huge_scenes|answers --flag=--memory_budget_mib=1024
//                                            issue 39's floods: a read key keeping its share of
//                                            the cheap lane full with 1,024-point
//                                            ClassifyCloud calls; frames of thousands of
//                                            objects; 10^7-point RecognizeScene calls that can
//                                            never fit the budget; Classify with k = 2,000 of
//                                            samples carrying provenance at its limits
//
// In every mode the lab also runs one heavy describe (1,000,000 points) idle and a few under
// the abuse: its wait is what the abuser's work ahead of it costs it.
// The server is a child process with its own data directory; the load generator shares the
// machine, as in the trial. Figures and their reading: docs/reliability.md.

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "CLI/CLI.hpp"
#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/time/clock.h"
#include "absl/time/time.h"
#include "bench/bench_clouds.h"
#include "bench/flooder.h"
#include "bench/percentile.h"
#include "client/client.h"
#include "core/testing/test_clouds.h"
#include "server/security/api_keys.h"
#include "server/testing/child_server.h"
#include "shapeid/v1/shapeid.grpc.pb.h"

namespace shapeid {
namespace {

using bench::Percentile;

constexpr char kAbuserKey[] = "abuser-key-0123456789abcdefghijklmnopqrstuv";
constexpr char kLabKey[] = "lab-key-0123456789abcdefghijklmnopqrstuvwxyz";
constexpr char kReaderKey[] = "reader-key-0123456789abcdefghijklmnopqrstuv";

// A frame of `specks` tiny objects (12 points, 1 cm apart, 1 m between objects) and no
// support: what a careless segmentation of a noisy frame gives, thousands of clusters.
std::string SpeckFrame(int specks) {
  std::vector<float> xyz;
  for (int i = 0; i < specks; ++i) {
    for (int j = 0; j < 12; ++j) {
      xyz.insert(xyz.end(), {static_cast<float>(i % 100) + 0.01f * static_cast<float>(j % 3),
                             static_cast<float>(i / 100) + 0.01f * static_cast<float>(j / 3),
                             0.013f * static_cast<float>(j % 2)});
    }
  }
  return std::string(reinterpret_cast<const char*>(xyz.data()), xyz.size() * sizeof(float));
}

// Provenance at the documented limits (core/gallery/sample_provenance.h): a 4 KiB source and
// 4 KiB of metadata.
void FatProvenance(uint64_t id, v1::SampleHeader* sample) {
  sample->set_source(absl::StrCat("file:///scans/", id, "/", std::string(4000, 's')));
  for (int m = 0; m < 32; ++m) {
    (*sample->mutable_metadata())[absl::StrCat("key", m)] = std::string(100, 'v');
  }
}

// A TCP port free on the loopback now (the kernel's pick), for --health_listen.
int FreePort() {
  const int fd = socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  socklen_t size = sizeof address;
  int port = 0;
  if (bind(fd, reinterpret_cast<sockaddr*>(&address), sizeof address) == 0 &&
      getsockname(fd, reinterpret_cast<sockaddr*>(&address), &size) == 0) {
    port = ntohs(address.sin_port);
  }
  close(fd);
  return port;
}

std::unique_ptr<Client> Connect(const std::string& target, const std::string& key,
                                absl::Duration deadline, size_t chunk_points = 0) {
  ClientOptions options;
  if (chunk_points > 0) options.chunk_points = chunk_points;
  options.target = target;
  options.api_key = key;
  options.deadline = deadline;
  options.max_attempts = 1;
  absl::StatusOr<std::unique_ptr<Client>> client = Client::Connect(options);
  if (!client.ok()) {
    std::fprintf(stderr, "fair_server_bench: %s\n", client.status().ToString().c_str());
    std::exit(1);
  }
  return *std::move(client);
}

// Latencies (ms) and failures of one kind of call during one phase.
struct Series {
  std::mutex mu;
  std::vector<double> ms;
  std::map<std::string, int> failures;  // status code -> count

  void Add(absl::Time start, const absl::Status& status) {
    const double elapsed = absl::ToDoubleMilliseconds(absl::Now() - start);
    std::lock_guard<std::mutex> lock(mu);
    if (status.ok()) {
      ms.push_back(elapsed);
    } else {
      ++failures[std::string(absl::StatusCodeToString(status.code()))];
    }
  }
  int FailureCount() {
    std::lock_guard<std::mutex> lock(mu);
    int count = 0;
    for (const auto& [code, n] : failures) count += n;
    return count;
  }
  std::string Failures() {
    std::lock_guard<std::mutex> lock(mu);
    std::string text;
    for (const auto& [code, count] : failures) absl::StrAppend(&text, code, " x", count, " ");
    return text.empty() ? "none" : text;
  }
};

struct Phase {
  Series classify, health_main, health_port, heavy;
};

// The lab classifies and the probe checks both ports until `stop`.
void Observe(Client& lab, Client& main_probe, Client& port_probe, const PointCloud& query,
             const std::atomic<bool>& stop, Phase& phase) {
  std::thread prober([&] {
    while (!stop.load()) {
      absl::Time start = absl::Now();
      phase.health_main.Add(start, main_probe.CheckHealth());
      start = absl::Now();
      phase.health_port.Add(start, port_probe.CheckHealth());
      absl::SleepFor(absl::Milliseconds(20));
    }
  });
  while (!stop.load()) {
    const absl::Time start = absl::Now();
    phase.classify.Add(start, lab.Classify("lab", query).status());
  }
  prober.join();
}

void PrintRow(const char* what, Series& idle, Series& abuse) {
  const double idle_p99 = Percentile(idle.ms, 0.99);
  std::printf("%-28s %9.2f %9.2f %10.2f %10.2f %10.1f %8.1fx  %s\n", what, Percentile(idle.ms, 0.5),
              idle_p99, Percentile(abuse.ms, 0.5), Percentile(abuse.ms, 0.99),
              Percentile(abuse.ms, 1.0), idle_p99 > 0 ? Percentile(abuse.ms, 0.99) / idle_p99 : 0.0,
              abuse.Failures().c_str());
}

int Main(int argc, char** argv) {
  CLI::App app("fair_server_bench: a heavy caller against a classifying one and health probes");
  std::string server_path = SHAPEID_SERVER_PATH;
  size_t points = 10'000'000;
  int heavy = 2;
  double seconds = 20;
  double idle_seconds = 5;
  bool no_budget_flags = false;
  std::vector<std::string> extra;
  std::string mode = "describe";
  int in_flight = 0;
  int answer_samples = 2'000;
  int learn_samples = 4'000;
  app.add_option("--abuse", mode,
                 "describe (heavy Describe streams), cheap, scenes, huge_scenes, answers or "
                 "streams (--heavy streams of --points in 12 MB messages)");
  app.add_option("--in_flight", in_flight,
                 "calls the abuser keeps open (0: 512 cheap, 4 scenes, 8 answers)");
  app.add_option("--answer_samples", answer_samples,
                 "samples with fat provenance in the answers mode's gallery (k = all of them)");
  app.add_option("--learn_samples", learn_samples,
                 "the learn mode's gallery: clouds, each stored with 16 augmented views");
  app.add_option("--server", server_path, "the shapeid-server binary to measure");
  app.add_option("--points", points, "points per heavy Describe");
  app.add_option("--heavy", heavy, "heavy Describe streams the abuser keeps open at once");
  app.add_option("--seconds", seconds, "the abuse phase lasts at least this long");
  app.add_option("--idle_seconds", idle_seconds, "the idle phase");
  app.add_flag("--no_budget_flags", no_budget_flags,
               "a server without --memory_budget_mib (older than issue 25)");
  app.add_option("--flag", extra, "an extra server flag (repeatable)");
  CLI11_PARSE(app, argc, argv);
  if (mode != "describe" && mode != "cheap" && mode != "scenes" && mode != "huge_scenes" &&
      mode != "answers" && mode != "streams" && mode != "learn") {
    std::fprintf(stderr,
                 "fair_server_bench: --abuse describe, cheap, scenes, huge_scenes, answers, "
                 "streams or learn\n");
    return 2;
  }
  // Many streams at once, each a cloud in messages of a million points (12 MB): what gRPC
  // buffers before the service sees a message.
  const bool streams = mode == "streams";
  if (streams) mode = "describe";
  if (in_flight <= 0) in_flight = mode == "cheap" ? 512 : mode == "answers" ? 8 : 4;

  const std::string dir = absl::StrCat(std::filesystem::temp_directory_path().string(),
                                       "/fair_server_bench_", getpid());
  std::filesystem::create_directories(dir);
  const std::string health_address = absl::StrCat("127.0.0.1:", FreePort());
  std::vector<std::string> flags = {
      "--listen=127.0.0.1:0", "--health_listen=" + health_address, "--data_dir=" + dir + "/data",
      "--log_level=warning",
      absl::StrCat("--api_keys=abuser write ", Sha256Hex(kAbuserKey), ";lab write ",
                   Sha256Hex(kLabKey), ";reader read ", Sha256Hex(kReaderKey))};
  flags.insert(flags.end(), extra.begin(), extra.end());
  ChildServer server;
  if (absl::Status s = server.Start(server_path, flags, dir + "/server.stderr"); !s.ok()) {
    std::fprintf(stderr, "fair_server_bench: %s\n", s.ToString().c_str());
    return 1;
  }
  std::printf("server: %s (pid %d), health port %s; %u hardware threads\n", server_path.c_str(),
              static_cast<int>(server.pid()), health_address.c_str(),
              std::thread::hardware_concurrency());

  std::unique_ptr<Client> lab = Connect(server.address(), kLabKey, absl::Seconds(30));
  std::unique_ptr<Client> main_probe = Connect(server.address(), "", absl::Seconds(3));
  std::unique_ptr<Client> port_probe = Connect(health_address, "", absl::Seconds(3));
  v1::CreateGalleryRequest create;
  create.set_name("lab");
  if (absl::StatusOr<v1::Gallery> made = lab->CreateGallery(create); !made.ok()) {
    std::fprintf(stderr, "CreateGallery: %s\n", made.status().ToString().c_str());
    return 1;
  }
  std::vector<PointCloud> clouds;
  for (uint32_t i = 0; i < 40; ++i) clouds.push_back(testing_clouds::ShapeCloud(i % 4, i, 1024));
  std::vector<TrainSample> samples;
  for (uint32_t i = 0; i < 40; ++i) samples.push_back({absl::StrCat("kind", i % 4), 0, &clouds[i]});
  if (absl::StatusOr<v1::TrainResponse> trained = lab->Train("lab", samples); !trained.ok()) {
    std::fprintf(stderr, "Train: %s\n", trained.status().ToString().c_str());
    return 1;
  }
  const PointCloud query = testing_clouds::ShapeCloud(2, 1000, 1024);

  Phase idle, abuse;
  {
    std::atomic<bool> stop{false};
    std::thread observer([&] { Observe(*lab, *main_probe, *port_probe, query, stop, idle); });
    absl::SleepFor(absl::Seconds(idle_seconds));
    stop = true;
    observer.join();
  }
  const int64_t rss_before = server.ResidentBytes();

  if (mode == "answers") {
    // The abuser's own gallery: samples whose provenance is at its limits.
    v1::CreateGalleryRequest fat;
    fat.set_name("fat");
    if (absl::StatusOr<v1::Gallery> made = lab->CreateGallery(fat); !made.ok()) {
      std::fprintf(stderr, "CreateGallery: %s\n", made.status().ToString().c_str());
      return 1;
    }
    auto stub = v1::ShapeId::NewStub(
        grpc::CreateChannel(server.address(), grpc::InsecureChannelCredentials()));
    grpc::ClientContext context;
    context.AddMetadata("authorization", absl::StrCat("Bearer ", kLabKey));
    v1::TrainResponse trained;
    auto writer = stub->Train(&context, &trained);
    v1::TrainRequest request;
    request.mutable_header()->set_gallery("fat");
    writer->Write(request);
    const std::string xyz(reinterpret_cast<const char*>(query.data()), query.size() * 12);
    for (int i = 0; i < answer_samples; ++i) {
      request.Clear();
      request.mutable_sample()->set_label(absl::StrCat("kind", i % 4));
      FatProvenance(static_cast<uint64_t>(i), request.mutable_sample());
      writer->Write(request);
      request.Clear();
      request.mutable_points()->set_xyz(xyz);
      writer->Write(request);
    }
    writer->WritesDone();
    if (grpc::Status s = writer->Finish(); !s.ok()) {
      std::fprintf(stderr, "Train (fat provenance): %s\n", s.error_message().c_str());
      return 1;
    }
  }
  if (mode == "learn") {
    // The abuser's gallery, trained now: the abuse phase is its head's fit alone.
    std::unique_ptr<Client> abuser = Connect(server.address(), kAbuserKey, absl::Minutes(10));
    v1::CreateGalleryRequest big;
    big.set_name("big");
    big.mutable_augmentation()->set_views(16);
    if (absl::StatusOr<v1::Gallery> made = abuser->CreateGallery(big); !made.ok()) {
      std::fprintf(stderr, "CreateGallery: %s\n", made.status().ToString().c_str());
      return 1;
    }
    for (int first = 0; first < learn_samples; first += 500) {
      std::vector<PointCloud> batch;
      std::vector<TrainSample> train;
      for (int i = first; i < std::min(learn_samples, first + 500); ++i) {
        batch.push_back(testing_clouds::ShapeCloud(i % 4, static_cast<uint32_t>(5000 + i), 512));
      }
      for (size_t i = 0; i < batch.size(); ++i) {
        train.push_back({absl::StrCat("kind", (first + i) % 4), 0, &batch[i]});
      }
      if (absl::StatusOr<v1::TrainResponse> t = abuser->Train("big", train); !t.ok()) {
        std::fprintf(stderr, "Train (big): %s\n", t.status().ToString().c_str());
        return 1;
      }
    }
  }
  // The lab's own heavy describe, idle: what its wait under the abuse is compared with.
  const PointCloud lab_heavy = bench::SurfaceCloud(1'000'000, 11);
  Series lab_heavy_idle;
  for (int i = 0; i < 2; ++i) {
    const absl::Time start = absl::Now();
    lab_heavy_idle.Add(start, lab->Describe(lab_heavy).status());
  }
  const int64_t rss_idle = server.ResidentBytes();

  std::atomic<bool> stop{false};
  std::atomic<int> described{0};
  std::atomic<int64_t> rss_seen{0};
  std::vector<std::thread> abusers;
  std::unique_ptr<bench::Flooder> flooder;
  const PointCloud huge =
      mode == "describe" || mode == "huge_scenes" ? bench::SurfaceCloud(points, 7) : PointCloud();
  const absl::Time abuse_start = absl::Now();
  if (mode == "describe" || mode == "huge_scenes") {
    for (int i = 0; i < heavy; ++i) {
      abusers.emplace_back([&] {
        std::unique_ptr<Client> abuser =
            Connect(server.address(), kAbuserKey, absl::Minutes(10), streams ? 1'000'000 : 0);
        do {
          const absl::Time start = absl::Now();
          if (mode == "describe") {
            abuse.heavy.Add(start, abuser->Describe(huge).status());
          } else {
            abuse.heavy.Add(start,
                            abuser->RecognizeScene("lab", huge, Client::SceneOptions()).status());
          }
          described.fetch_add(1);
        } while (!stop.load());
      });
    }
  } else if (mode != "learn") {
    auto request = std::make_shared<v1::ClassifyCloudRequest>();
    auto scene = std::make_shared<v1::RecognizeSceneCloudRequest>();
    if (mode == "scenes") {
      scene->mutable_header()->set_gallery("lab");
      scene->mutable_header()->mutable_segmentation()->set_max_planes(0);
      scene->mutable_header()->mutable_segmentation()->set_min_cluster_points(10);
      scene->mutable_header()->mutable_segmentation()->set_cluster_tolerance(0.05f);
      scene->mutable_points()->set_xyz(SpeckFrame(5'000));
    } else {
      request->mutable_header()->set_gallery(mode == "answers" ? "fat" : "lab");
      if (mode == "answers")
        request->mutable_header()->set_k(static_cast<uint32_t>(answer_samples));
      request->mutable_points()->set_xyz(
          std::string(reinterpret_cast<const char*>(query.data()), query.size() * 12));
    }
    flooder = std::make_unique<bench::Flooder>(
        server.address(),
        [](grpc::ClientContext& context) {
          context.AddMetadata("authorization", absl::StrCat("Bearer ", kReaderKey));
          context.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(60));
        },
        [request, scene, scenes = mode == "scenes"](v1::ShapeId::Stub& stub,
                                                    grpc::ClientContext* context,
                                                    std::function<void(grpc::Status)> done) {
          if (scenes) {
            auto response = std::make_shared<v1::RecognizeSceneResponse>();
            stub.async()->RecognizeSceneCloud(context, scene.get(), response.get(),
                                              [response, done](grpc::Status s) { done(s); });
          } else {
            auto response = std::make_shared<v1::ClassifyResponse>();
            stub.async()->ClassifyCloud(context, request.get(), response.get(),
                                        [response, done](grpc::Status s) { done(s); });
          }
        },
        in_flight);
    flooder->Start();
  }
  std::thread sampler([&] {
    while (!stop.load()) {
      rss_seen = std::max<int64_t>(rss_seen.load(), server.ResidentBytes());
      absl::SleepFor(absl::Milliseconds(50));
    }
  });
  std::thread observer([&] { Observe(*lab, *main_probe, *port_probe, query, stop, abuse); });
  Series lab_heavy_abuse;
  std::thread lab_heavy_thread([&] {
    std::unique_ptr<Client> own = Connect(server.address(), kLabKey, absl::Minutes(10));
    while (!stop.load()) {
      const absl::Time start = absl::Now();
      lab_heavy_abuse.Add(start, own->Describe(lab_heavy).status());
    }
  });
  // At least `seconds`, and until every abuser stream has finished one call (learn: until
  // the head is published, at most 10 minutes).
  const auto fitted = [&] {
    absl::StatusOr<v1::Gallery> big = lab->GetGallery("big");
    return big.ok() && big->has_head() && big->head().fitted_version() == big->version();
  };
  absl::Duration head_after = absl::InfiniteDuration();
  while (absl::Now() - abuse_start < absl::Seconds(seconds) ||
         (mode == "describe" || mode == "huge_scenes" ? described.load() < heavy
          : mode == "learn" ? !fitted() && absl::Now() - abuse_start < absl::Minutes(10)
                            : false)) {
    if (mode == "learn" && head_after == absl::InfiniteDuration() && fitted()) {
      head_after = absl::Now() - abuse_start;
    }
    absl::SleepFor(absl::Milliseconds(100));
  }
  if (mode == "learn" && head_after == absl::InfiniteDuration() && fitted()) {
    head_after = absl::Now() - abuse_start;
  }
  stop = true;
  observer.join();
  for (std::thread& thread : abusers) thread.join();
  if (flooder != nullptr) flooder->Stop();
  sampler.join();
  lab_heavy_thread.join();
  const double abuse_seconds = absl::ToDoubleSeconds(absl::Now() - abuse_start);
  std::string flood_summary = "";
  if (flooder != nullptr) {
    const bench::FloodCounts counts = flooder->counts();
    flood_summary =
        absl::StrCat("; the reader's flood (", in_flight, " open): ", counts.ok, " answered, ",
                     counts.refused, " refused RESOURCE_EXHAUSTED, ", counts.other, " other",
                     counts.other > 0 ? " (" : "", counts.first_other, counts.other > 0 ? ")" : "");
  }
  uint64_t budget = 0, held_peak = 0;
  if (absl::StatusOr<v1::ServerStats> stats = lab->GetServerStats(); stats.ok()) {
    budget = stats->memory_budget_bytes();
    held_peak = stats->memory_held_peak_bytes();
  }
  const int64_t rss_peak = std::max<int64_t>(server.PeakResidentBytes(), rss_seen.load());

  if (mode == "learn") {
    std::printf(
        "\nabuse: the server fitting the head of %d clouds x 17 vectors: published %s "
        "after the phase began (%.1f s observed)\n",
        learn_samples, absl::FormatDuration(head_after).c_str(), abuse_seconds);
  } else if (flooder == nullptr) {
    std::printf("\nabuse: %d stream(s) of %zu-point %s for %.1f s; %zu done, failures: %s\n", heavy,
                points, mode == "describe" ? "Describe (default spec)" : "RecognizeScene",
                abuse_seconds, abuse.heavy.ms.size(), abuse.heavy.Failures().c_str());
  } else {
    std::printf("\nabuse: %s for %.1f s%s\n", mode.c_str(), abuse_seconds, flood_summary.c_str());
  }
  std::printf("\n%-28s %9s %9s %10s %10s %10s %9s  %s\n", "ms", "idle p50", "idle p99", "abuse p50",
              "abuse p99", "abuse max", "p99 ratio", "failures under abuse");
  PrintRow("lab ClassifyCloud (1,024)", idle.classify, abuse.classify);
  PrintRow("health, main port", idle.health_main, abuse.health_main);
  PrintRow("health, --health_listen", idle.health_port, abuse.health_port);
  PrintRow("lab Describe (1,000,000)", lab_heavy_idle, lab_heavy_abuse);
  std::printf("\ncalls: lab %zu idle, %zu under abuse; probes %zu / %zu under abuse\n",
              idle.classify.ms.size(), abuse.classify.ms.size(), abuse.health_main.ms.size(),
              abuse.health_port.ms.size());
  std::printf(
      "server memory: resident %.0f MiB empty (after the idle phase), %.0f MiB before the "
      "abuse, peak %.0f MiB (+%.0f MiB); budget %s, most held at once %.0f MiB\n",
      rss_before / 1048576.0, rss_idle / 1048576.0, rss_peak / 1048576.0,
      (rss_peak - rss_before) / 1048576.0,
      no_budget_flags || budget == 0 ? "none" : absl::StrCat(budget >> 20, " MiB").c_str(),
      held_peak / 1048576.0);
  std::printf(
      "{\"bench\":\"fair_server\",\"points\":%zu,\"heavy\":%d,\"classify_idle_p99_ms\":%.3f,"
      "\"classify_abuse_p50_ms\":%.3f,\"classify_abuse_p99_ms\":%.3f,"
      "\"classify_abuse_max_ms\":%.3f,\"classify_abuse_calls\":%zu,\"classify_failures\":%d,"
      "\"health_main_abuse_p99_ms\":%.3f,\"health_port_abuse_p99_ms\":%.3f,"
      "\"health_failures\":%d,\"rss_before_mib\":%.0f,\"rss_peak_mib\":%.0f,"
      "\"budget_mib\":%llu,\"abuse\":\"%s\",\"lab_describe_idle_p50_ms\":%.1f,"
      "\"lab_describe_abuse_max_ms\":%.1f,\"rss_within_budget\":%s}\n",
      points, heavy, Percentile(idle.classify.ms, 0.99), Percentile(abuse.classify.ms, 0.5),
      Percentile(abuse.classify.ms, 0.99), Percentile(abuse.classify.ms, 1.0),
      abuse.classify.ms.size(), abuse.classify.FailureCount(),
      Percentile(abuse.health_main.ms, 0.99), Percentile(abuse.health_port.ms, 0.99),
      abuse.health_main.FailureCount() + abuse.health_port.FailureCount(), rss_before / 1048576.0,
      rss_peak / 1048576.0, static_cast<unsigned long long>(budget >> 20), mode.c_str(),
      Percentile(lab_heavy_idle.ms, 0.5), Percentile(lab_heavy_abuse.ms, 1.0),
      budget > 0 && static_cast<double>(rss_peak) <=
                        1.1 * static_cast<double>(budget) + static_cast<double>(rss_before)
          ? "true"
          : "false");
  server.Terminate(absl::Seconds(30));
  std::filesystem::remove_all(dir);
  return 0;
}

}  // namespace
}  // namespace shapeid

int main(int argc, char** argv) { return shapeid::Main(argc, argv); }
