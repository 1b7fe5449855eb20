// Service speed (issue 3, "Speed"): Classify latency and throughput through a real gRPC server
// on a loopback TCP port, against a 4,000-sample gallery of one spec (--spec; default the
// server's default, dfsd), and the same work in-process for the RPC overhead ratio.
//
//   service_bench                 full run (~30 s): single-client latency, in-process latency,
//                                 1 / 4 / 16 concurrent clients (shared channel and one
//                                 channel per client), a table and one JSON line
//   service_bench --quick         a ~2 s smoke for CI
//   service_bench --log_level=info --log_format=json
//                                 the same with the server's log line per RPC (issue 12),
//                                 written to --log_file instead of stderr; the default,
//                                 error, logs no RPC lines, as before issue 12. Metrics are
//                                 recorded either way (operations_bench has their cost).
//
// Server and load generator share this process and the machine's cores, as in the issue
// ("the load generator runs on the same 2-core machine"). Clouds are ModelNet10 (1,024
// points each) when ../shared/data/modelnet10 exists, else synthetic 1,024-point clouds; the
// output says which. Figures and their reading: docs/performance.md.
//
// Not Google Benchmark: latency percentiles and multi-client throughput over fixed durations
// fit it poorly, so this is a plain program with its own timing.

#include <fcntl.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <memory>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "CLI/CLI.hpp"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/strings/str_join.h"
#include "absl/time/time.h"
#include "bench/bench_clouds.h"
#include "core/gallery/gallery.h"
#include "core/gallery/gallery_registry.h"
#include "core/io/point_cloud_reader.h"
#include "core/views/perturb.h"
#include "grpcpp/grpcpp.h"
#include "server/ops/process_stats.h"
#include "server/server.h"
#include "shapeid/v1/shapeid.grpc.pb.h"

namespace shapeid {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

constexpr char kGalleryName[] = "bench";

// ----------------------------------------------------------------------------- data

struct Sample {
  std::string label;
  PointCloud cloud;
};

struct Data {
  std::vector<Sample> train;  // exactly gallery_size
  std::vector<Sample> test;   // queries, cycled through
  std::string source;         // what the clouds are, for the output
};

std::vector<fs::path> SortedEntries(const fs::path& dir) {
  std::vector<fs::path> entries;
  std::error_code ec;
  for (const auto& entry : fs::directory_iterator(dir, ec)) entries.push_back(entry.path());
  std::sort(entries.begin(), entries.end());
  return entries;
}

// Every <class>/<split>/*.pcd, classes and files in sorted order. Empty on any read error.
std::vector<Sample> ReadSplit(const fs::path& root, const std::string& split, size_t limit) {
  std::vector<Sample> out;
  for (const fs::path& class_dir : SortedEntries(root)) {
    if (!fs::is_directory(class_dir)) continue;
    for (const fs::path& file : SortedEntries(class_dir / split)) {
      if (out.size() >= limit) return out;
      if (file.extension() != ".pcd") continue;
      auto read = ReadPointCloud(file.string());
      if (!read.ok()) {
        std::fprintf(stderr, "cannot read %s: %s\n", file.c_str(),
                     read.status().ToString().c_str());
        return {};
      }
      out.push_back({class_dir.filename().string(), std::move(read->cloud)});
    }
  }
  return out;
}

// Repeats `samples` cyclically up to `n` (ModelNet10 has 3,991 training clouds).
void FillTo(std::vector<Sample>& samples, size_t n) {
  const size_t have = samples.size();
  for (size_t i = 0; samples.size() < n; ++i) samples.push_back(samples[i % have]);
  samples.resize(n);
}

Data LoadData(const std::string& root, size_t gallery_size, size_t num_clouds) {
  Data data;
  if (fs::is_directory(root)) {
    data.train = ReadSplit(root, "train", gallery_size);
    data.test = ReadSplit(root, "test", num_clouds);
  }
  if (!data.train.empty() && !data.test.empty()) {
    const size_t read = data.train.size();
    FillTo(data.train, gallery_size);
    data.source = absl::StrCat(
        "ModelNet10 (", read, " train clouds",
        read < gallery_size ? absl::StrCat(", first ", gallery_size - read, " repeated") : "", "; ",
        data.test.size(), " test clouds; ", data.test[0].cloud.size(), " points each)");
    return data;
  }
  data.train.clear();
  data.test.clear();
  const char* kLabels[] = {"a", "b", "c", "d", "e", "f", "g", "h", "i", "j"};
  for (size_t i = 0; i < gallery_size; ++i) {
    data.train.push_back({kLabels[i % 10], bench::SurfaceCloud(1024, 1000 + i)});
  }
  for (size_t i = 0; i < num_clouds; ++i) {
    data.test.push_back({kLabels[i % 10], bench::SurfaceCloud(1024, 900000 + i)});
  }
  data.source = absl::StrCat("SYNTHETIC 1,024-point clouds (no ModelNet10 at ", root, ")");
  return data;
}

std::string Bytes(const PointCloud& cloud) {
  std::string bytes(cloud.size() * 12, '\0');
  std::memcpy(bytes.data(), cloud.data(), bytes.size());
  return bytes;
}

// ----------------------------------------------------------------------------- statistics

struct Stats {
  int64_t count = 0;
  double p50_us = 0, p90_us = 0, p99_us = 0, mean_us = 0;
};

Stats Summarize(std::vector<int64_t> ns) {
  Stats s;
  s.count = static_cast<int64_t>(ns.size());
  if (ns.empty()) return s;
  std::sort(ns.begin(), ns.end());
  auto at = [&](double q) {
    const size_t i = std::min(ns.size() - 1, static_cast<size_t>(q * (ns.size() - 1) + 0.5));
    return ns[i] / 1e3;
  };
  s.p50_us = at(0.50);
  s.p90_us = at(0.90);
  s.p99_us = at(0.99);
  double sum = 0;
  for (int64_t v : ns) sum += static_cast<double>(v);
  s.mean_us = sum / ns.size() / 1e3;
  return s;
}

double ThreadCpuSeconds() {
  timespec t{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) + 1e-9 * static_cast<double>(t.tv_nsec);
}

double ProcessCpuSeconds() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  auto sec = [](const timeval& t) { return t.tv_sec + t.tv_usec / 1e6; };
  return sec(usage.ru_utime) + sec(usage.ru_stime);
}

std::string LoadAverage() {
  std::ifstream in("/proc/loadavg");
  std::string a, b, c;
  in >> a >> b >> c;
  return absl::StrCat(a, " ", b, " ", c);
}

// ----------------------------------------------------------------------------- the log

// The server logs to fd 2. While it runs with RPC lines on, fd 2 points at a file instead
// (a terminal would make the figures the terminal's), and Stop puts stderr back. The bench's
// own messages to stderr in that time land in the file too.
class LogCapture {
 public:
  LogCapture() = default;
  LogCapture(const LogCapture&) = delete;
  LogCapture& operator=(const LogCapture&) = delete;
  ~LogCapture() { Stop(); }  // an early return must not leave stderr in the file

  // False, with a message on stderr, if the file cannot be opened.
  bool Start(const std::string& path) {
    const int fd = open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
    if (fd < 0) {
      std::fprintf(stderr, "cannot open %s: %s\n", path.c_str(), std::strerror(errno));
      return false;
    }
    std::fflush(stderr);
    saved_stderr_ = dup(STDERR_FILENO);
    dup2(fd, STDERR_FILENO);
    close(fd);
    path_ = path;
    return true;
  }
  bool active() const { return saved_stderr_ >= 0; }

  // Marks the start and the end of the measured RPC phases, for lines/s.
  void Mark() {
    if (!active()) return;
    marks_.push_back({Clock::now(), Size()});
  }

  void Stop() {
    if (!active()) return;
    std::fflush(stderr);
    bytes_ = Size();
    dup2(saved_stderr_, STDERR_FILENO);
    close(saved_stderr_);
    saved_stderr_ = -1;
  }

  struct Summary {
    int64_t bytes = 0, lines = 0;
    int64_t window_lines = 0;  // between the first and the last Mark
    double window_seconds = 0;
  };
  // After Stop: reads the file back to count lines.
  Summary Summarize() const {
    Summary s;
    s.bytes = bytes_;
    std::ifstream in(path_, std::ios::binary);
    std::vector<char> buffer(1 << 20);
    int64_t offset = 0;
    const int64_t window_begin = marks_.size() >= 2 ? marks_.front().bytes : 0;
    const int64_t window_end = marks_.size() >= 2 ? marks_.back().bytes : 0;
    while (in.read(buffer.data(), static_cast<std::streamsize>(buffer.size())) || in.gcount() > 0) {
      const int64_t n = in.gcount();
      for (int64_t i = 0; i < n; ++i) {
        if (buffer[i] != '\n') continue;
        ++s.lines;
        if (offset + i >= window_begin && offset + i < window_end) ++s.window_lines;
      }
      offset += n;
    }
    if (marks_.size() >= 2) {
      s.window_seconds =
          std::chrono::duration<double>(marks_.back().time - marks_.front().time).count();
    }
    return s;
  }

 private:
  struct Checkpoint {
    Clock::time_point time;
    int64_t bytes;
  };
  int64_t Size() const {
    struct stat st {};
    return fstat(STDERR_FILENO, &st) == 0 ? static_cast<int64_t>(st.st_size) : 0;
  }

  int saved_stderr_ = -1;
  std::string path_;
  int64_t bytes_ = 0;
  std::vector<Checkpoint> marks_;
};

// ----------------------------------------------------------------------------- client

// The two messages of one Classify stream and the one ClassifyCloud message, built once per
// query cloud so the load generator spends its (shared) CPU on the RPC, not on copying points.
struct Query {
  v1::ClassifyRequest header;
  v1::ClassifyRequest points;
  v1::ClassifyCloudRequest one_message;
};

std::vector<Query> BuildQueries(const std::vector<Sample>& test) {
  std::vector<Query> queries(test.size());
  for (size_t i = 0; i < test.size(); ++i) {
    queries[i].header.mutable_header()->set_gallery(kGalleryName);
    queries[i].header.mutable_header()->set_expected_points(test[i].cloud.size());
    queries[i].points.mutable_points()->set_xyz(Bytes(test[i].cloud));
    *queries[i].one_message.mutable_header() = queries[i].header.header();
    *queries[i].one_message.mutable_points() = queries[i].points.points();
  }
  return queries;
}

// How the client sends a cloud.
//  unary:     one ClassifyCloud message (what shapeid::Client does for clouds up to its
//             chunk_points, 16,384 by default)
//  plain:     a Classify stream: Write(header), Write(points), WritesDone, Finish
//  coalesced: a Classify stream with initial metadata corked, header buffered,
//             WriteLast(points): the whole request leaves in one flush (shapeid::Client's
//             way for larger clouds)
enum class WriteMode { kUnary, kPlain, kCoalesced };

grpc::Status ClassifyOnce(v1::ShapeId::Stub& stub, const Query& query, WriteMode mode,
                          v1::ClassifyResponse* response) {
  grpc::ClientContext context;
  if (mode == WriteMode::kUnary) return stub.ClassifyCloud(&context, query.one_message, response);
  if (mode == WriteMode::kCoalesced) context.set_initial_metadata_corked(true);
  auto writer = stub.Classify(&context, response);
  if (mode == WriteMode::kPlain) {
    if (writer->Write(query.header)) writer->Write(query.points);
    writer->WritesDone();
  } else {
    if (writer->Write(query.header, grpc::WriteOptions().set_buffer_hint())) {
      writer->WriteLast(query.points, grpc::WriteOptions());
    } else {
      writer->WritesDone();
    }
  }
  return writer->Finish();
}

std::shared_ptr<grpc::Channel> MakeChannel(const std::string& address, bool own_connection) {
  grpc::ChannelArguments args;
  args.SetMaxReceiveMessageSize(16 << 20);
  // Channels with equal arguments share one TCP connection through gRPC's global subchannel
  // pool; a local pool gives each channel its own connection.
  if (own_connection) args.SetInt(GRPC_ARG_USE_LOCAL_SUBCHANNEL_POOL, 1);
  auto channel = grpc::CreateCustomChannel(address, grpc::InsecureChannelCredentials(), args);
  channel->WaitForConnected(std::chrono::system_clock::now() + std::chrono::seconds(10));
  return channel;
}

// ----------------------------------------------------------------------------- phases

struct Breakdown {  // server-side, from ClassifyResponse
  double describe_us = 0, search_us = 0;
};

struct LatencyResult {
  Stats stats;
  Breakdown server;
  int64_t errors = 0;
  int64_t label_mismatches = 0;  // against the in-process answers
};

LatencyResult SingleClient(v1::ShapeId::Stub& stub, const std::vector<Query>& queries,
                           const std::vector<std::string>& expected, int warmup, int requests,
                           WriteMode mode) {
  LatencyResult r;
  v1::ClassifyResponse response;
  for (int i = 0; i < warmup; ++i) ClassifyOnce(stub, queries[i % queries.size()], mode, &response);
  std::vector<int64_t> ns;
  ns.reserve(requests);
  double describe = 0, search = 0;
  for (int i = 0; i < requests; ++i) {
    const size_t q = i % queries.size();
    response.Clear();
    const auto t0 = Clock::now();
    const grpc::Status status = ClassifyOnce(stub, queries[q], mode, &response);
    const auto t1 = Clock::now();
    if (!status.ok()) {
      if (++r.errors == 1) std::fprintf(stderr, "Classify: %s\n", status.error_message().c_str());
      continue;
    }
    ns.push_back(std::chrono::duration_cast<std::chrono::nanoseconds>(t1 - t0).count());
    if (response.label() != expected[q]) ++r.label_mismatches;
    describe += response.describe_time().seconds() * 1e6 + response.describe_time().nanos() / 1e3;
    search += response.search_time().seconds() * 1e6 + response.search_time().nanos() / 1e3;
  }
  r.stats = Summarize(std::move(ns));
  if (r.stats.count > 0) {
    r.server.describe_us = describe / r.stats.count;
    r.server.search_us = search / r.stats.count;
  }
  return r;
}

struct InProcessResult {
  Stats stats;
  double describe_us = 0, search_us = 0;
  double throughput_2t = 0;  // classifications/s with two threads
  std::vector<std::string> labels;
  // Over the distinct queries: searches that went approximate, answers that differ from an
  // exact search's, and correct answers of each kind (the cost of approximation).
  int approximate_searches = 0, differ_from_exact = 0, correct = 0, correct_exact = 0;
};

InProcessResult InProcess(const Gallery& gallery, const std::vector<Sample>& test, int warmup,
                          int requests, double seconds) {
  InProcessResult r;
  const CloudLimits limits = gallery.limits().cloud_limits();
  for (const Sample& s : test) {
    auto answer = gallery.Snapshot()->Classify(s.cloud, limits);
    auto exact = gallery.Snapshot()->Classify(s.cloud, limits, 0, SearchMode::kExact);
    r.labels.push_back(answer.ok() ? answer->label : "<error>");
    const std::string exact_label = exact.ok() ? exact->label : "<error>";
    if (answer.ok() && answer->knn.approximate) ++r.approximate_searches;
    if (r.labels.back() != exact_label) ++r.differ_from_exact;
    if (r.labels.back() == s.label) ++r.correct;
    if (exact_label == s.label) ++r.correct_exact;
  }
  for (int i = 0; i < warmup; ++i)
    (void)gallery.Snapshot()->Classify(test[i % test.size()].cloud, limits);
  std::vector<int64_t> ns;
  ns.reserve(requests);
  double describe = 0, search = 0;
  for (int i = 0; i < requests; ++i) {
    const auto t0 = Clock::now();
    auto answer = gallery.Snapshot()->Classify(test[i % test.size()].cloud, limits);
    const auto t1 = Clock::now();
    ns.push_back(std::chrono::duration_cast<std::chrono::nanoseconds>(t1 - t0).count());
    describe += absl::ToDoubleMicroseconds(answer->describe_time);
    search += absl::ToDoubleMicroseconds(answer->search_time);
  }
  r.stats = Summarize(std::move(ns));
  r.describe_us = describe / requests;
  r.search_us = search / requests;

  // Two threads (the machine's cores): the ceiling any server could reach here.
  std::atomic<int64_t> done{0};
  const auto start = Clock::now();
  const auto deadline = start + std::chrono::duration<double>(seconds);
  std::vector<std::thread> threads;
  for (int t = 0; t < 2; ++t) {
    threads.emplace_back([&, t] {
      int64_t n = 0;
      for (size_t i = t; Clock::now() < deadline; ++i, ++n) {
        (void)gallery.Snapshot()->Classify(test[i % test.size()].cloud, limits);
      }
      done += n;
    });
  }
  for (auto& th : threads) th.join();
  r.throughput_2t = done / std::chrono::duration<double>(Clock::now() - start).count();
  return r;
}

struct LoadResult {
  int clients = 0;
  bool channel_per_client = false;
  double per_second = 0;
  Stats stats;
  double cpu_us_per_call = 0;  // whole process (server + clients) CPU time per classification
  // The load generator's threads alone (CLOCK_THREAD_CPUTIME_ID); the rest of the process
  // is the server, plus gRPC's few background threads.
  double client_cpu_us_per_call = 0;
  int64_t errors = 0;
};

LoadResult Load(const std::string& address, const std::vector<Query>& queries, int clients,
                bool channel_per_client, double seconds, WriteMode mode) {
  LoadResult r;
  r.clients = clients;
  r.channel_per_client = channel_per_client;
  std::vector<std::shared_ptr<grpc::Channel>> channels;
  std::vector<std::unique_ptr<v1::ShapeId::Stub>> stubs;
  auto shared = channel_per_client ? nullptr : MakeChannel(address, false);
  for (int c = 0; c < clients; ++c) {
    channels.push_back(channel_per_client ? MakeChannel(address, true) : shared);
    stubs.push_back(v1::ShapeId::NewStub(channels.back()));
  }
  // A short warm-up on every stub (connections, server threads).
  {
    std::vector<std::thread> warm;
    for (int c = 0; c < clients; ++c) {
      warm.emplace_back([&, c] {
        v1::ClassifyResponse response;
        for (int i = 0; i < 20; ++i)
          ClassifyOnce(*stubs[c], queries[(c + i) % queries.size()], mode, &response);
      });
    }
    for (auto& th : warm) th.join();
  }

  std::vector<std::vector<int64_t>> ns(clients);
  std::vector<double> thread_cpu(clients, 0.0);
  std::atomic<int64_t> errors{0};
  std::atomic<bool> go{false};
  std::vector<std::thread> threads;
  Clock::time_point deadline;
  for (int c = 0; c < clients; ++c) {
    threads.emplace_back([&, c] {
      while (!go.load(std::memory_order_acquire)) std::this_thread::yield();
      v1::ClassifyResponse response;
      ns[c].reserve(1 << 16);
      const double cpu_start = ThreadCpuSeconds();
      for (size_t i = c * 7919; Clock::now() < deadline; ++i) {
        response.Clear();
        const auto t0 = Clock::now();
        const grpc::Status status =
            ClassifyOnce(*stubs[c], queries[i % queries.size()], mode, &response);
        const auto t1 = Clock::now();
        if (!status.ok()) {
          ++errors;
          continue;
        }
        ns[c].push_back(std::chrono::duration_cast<std::chrono::nanoseconds>(t1 - t0).count());
      }
      thread_cpu[c] = ThreadCpuSeconds() - cpu_start;
    });
  }
  const double cpu0 = ProcessCpuSeconds();
  const auto start = Clock::now();
  deadline =
      start + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(seconds));
  go.store(true, std::memory_order_release);
  for (auto& th : threads) th.join();
  const double elapsed = std::chrono::duration<double>(Clock::now() - start).count();
  const double cpu = ProcessCpuSeconds() - cpu0;

  std::vector<int64_t> all;
  for (auto& v : ns) all.insert(all.end(), v.begin(), v.end());
  r.stats = Summarize(std::move(all));
  r.per_second = r.stats.count / elapsed;
  r.cpu_us_per_call = r.stats.count > 0 ? cpu / r.stats.count * 1e6 : 0;
  double client_cpu = 0;
  for (double t : thread_cpu) client_cpu += t;
  r.client_cpu_us_per_call = r.stats.count > 0 ? client_cpu / r.stats.count * 1e6 : 0;
  r.errors = errors;
  return r;
}

double BestAt(const std::vector<LoadResult>& loads, int clients) {
  double best = 0;
  for (const LoadResult& l : loads) {
    if (l.clients == clients) best = std::max(best, l.per_second);
  }
  return best;
}

// ----------------------------------------------------------------------------- setup

bool CreateAndTrain(v1::ShapeId::Stub& stub, const std::string& spec, int augment_views,
                    const std::vector<Sample>& train, int streams) {
  {
    grpc::ClientContext context;
    v1::CreateGalleryRequest request;
    request.set_name(kGalleryName);     // k = 1
    request.set_descriptor_spec(spec);  // empty: the server's default
    if (augment_views > 0) {
      request.mutable_augmentation()->set_views(static_cast<uint32_t>(augment_views));
    }
    v1::Gallery gallery;
    const grpc::Status status = stub.CreateGallery(&context, request, &gallery);
    if (!status.ok()) {
      std::fprintf(stderr, "CreateGallery: %s\n", status.error_message().c_str());
      return false;
    }
    std::printf("gallery: %s, dimension %u\n", gallery.descriptor_spec().c_str(),
                gallery.dimension());
  }
  const size_t per_stream = (train.size() + streams - 1) / streams;
  for (size_t first = 0; first < train.size(); first += per_stream) {
    grpc::ClientContext context;
    v1::TrainResponse response;
    auto writer = stub.Train(&context, &response);
    v1::TrainRequest header;
    header.mutable_header()->set_gallery(kGalleryName);
    bool open = writer->Write(header);
    for (size_t i = first; open && i < std::min(train.size(), first + per_stream); ++i) {
      v1::TrainRequest sample;
      sample.mutable_sample()->set_label(train[i].label);
      open = writer->Write(sample);
      v1::TrainRequest points;
      points.mutable_points()->set_xyz(Bytes(train[i].cloud));
      open = open && writer->Write(points);
    }
    writer->WritesDone();
    const grpc::Status status = writer->Finish();
    if (!status.ok()) {
      std::fprintf(stderr, "Train: %s\n", status.error_message().c_str());
      return false;
    }
    if (first + per_stream >= train.size() && response.gallery_sample_count() != train.size()) {
      std::fprintf(stderr, "Train: gallery holds %llu samples, expected %zu\n",
                   static_cast<unsigned long long>(response.gallery_sample_count()), train.size());
      return false;
    }
  }
  return true;
}

std::string StatsJson(const Stats& s) {
  return absl::StrFormat(R"({"n":%d,"p50_us":%.1f,"p90_us":%.1f,"p99_us":%.1f,"mean_us":%.1f})",
                         s.count, s.p50_us, s.p90_us, s.p99_us, s.mean_us);
}

int Run(int argc, char** argv) {
  CLI::App app{"Classify latency and throughput through a loopback gRPC server vs in-process"};
  std::string data_dir = fs::path(SHAPEID_SOURCE_DIR) / ".." / "shared" / "data" / "modelnet10";
  bool quick = false;
  double seconds = 3.0;
  size_t gallery_size = 4000;
  int augment_views = 0;
  size_t num_clouds = 908;
  int requests = 2000;
  int warmup = 200;
  int train_streams = 4;
  std::vector<int> clients = {1, 4, 16};
  std::string channels_mode = "both";
  std::string write_mode_name = "unary";
  size_t points = 0;
  std::string log_level_name = "error";
  std::string log_format_name = "text";
  std::string log_file = "/tmp/service_bench_rpc.log";
  app.add_option("--data", data_dir, "ModelNet10 folder with <class>/{train,test}/*.pcd")
      ->capture_default_str();
  app.add_flag("--quick", quick, "tiny numbers for a CI smoke (~2 s)");
  std::string spec;
  app.add_option("--spec", spec, "descriptor spec of the gallery (default: the server's default)");
  app.add_option("--augment_views", augment_views,
                 "synthetic sensor views per trained cloud (view augmentation; 0: off)")
      ->capture_default_str()
      ->check(CLI::Range(0, 64));
  app.add_option("--seconds", seconds, "duration of each concurrent-load run")
      ->capture_default_str();
  app.add_option("--gallery_size", gallery_size, "samples in the gallery")->capture_default_str();
  app.add_option("--clouds", num_clouds, "distinct query clouds (cycled)")->capture_default_str();
  app.add_option("--requests", requests, "single-client classifications measured")
      ->capture_default_str();
  app.add_option("--warmup", warmup, "single-client classifications before measuring")
      ->capture_default_str();
  app.add_option("--train_streams", train_streams, "Train streams the gallery is filled over")
      ->capture_default_str();
  app.add_option("--clients", clients, "concurrent client counts")->capture_default_str();
  app.add_option("--channels", channels_mode, "shared | per-client | both")->capture_default_str();
  app.add_option("--write_mode", write_mode_name, "unary | plain | coalesced (see ClassifyOnce)")
      ->capture_default_str()
      ->check(CLI::IsMember({"unary", "plain", "coalesced"}));
  app.add_option("--points", points,
                 "query clouds of this many points, synthetic (0: the ModelNet10 test clouds, "
                 "1,024 points)")
      ->capture_default_str();
  bool query_views = false;
  int64_t approximate_min_vectors = ApproximateOptions::kServedMinVectors;
  int approximate_probes = 0;
  app.add_flag("--query_views", query_views,
               "query with single-side sensor views of the test clouds (300-500 points, 1 % "
               "noise, any pose), as a robot would");
  app.add_option("--approximate_min_vectors", approximate_min_vectors,
                 "the server's --approximate_min_vectors: searches go approximate (IVF) from this "
                 "many stored vectors (0: always exact)")
      ->capture_default_str()
      ->check(CLI::NonNegativeNumber);
  app.add_option("--approximate_probes", approximate_probes,
                 "the server's --approximate_probes: cells a query reads (0: the default, 32)")
      ->capture_default_str()
      ->check(CLI::NonNegativeNumber);
  app.add_option("--log_level", log_level_name,
                 "the server's --log_level: error logs no RPC lines (the figures before issue "
                 "12); info logs one per call, to --log_file")
      ->capture_default_str()
      ->check(CLI::IsMember({"debug", "info", "warning", "error"}));
  app.add_option("--log_format", log_format_name, "the server's --log_format: text | json")
      ->capture_default_str()
      ->check(CLI::IsMember({"text", "json"}));
  app.add_option("--log_file", log_file,
                 "where stderr goes while the server runs, when --log_level is below error")
      ->capture_default_str();
  CLI11_PARSE(app, argc, argv);
  if (quick) {
    seconds = 0.2;
    gallery_size = std::min<size_t>(gallery_size, 200);
    num_clouds = std::min<size_t>(num_clouds, 16);
    requests = 100;
    warmup = 10;
    clients = {1, 4};
  }
  const WriteMode mode = write_mode_name == "coalesced" ? WriteMode::kCoalesced
                         : write_mode_name == "plain"   ? WriteMode::kPlain
                                                        : WriteMode::kUnary;
  if (gallery_size == 0 || num_clouds == 0 || requests <= 0 || train_streams <= 0) {
    std::fprintf(stderr, "sizes must be positive\n");
    return 2;
  }

  const std::string load_before = LoadAverage();
  std::printf("load average before: %s (%u hardware threads)\n", load_before.c_str(),
              std::thread::hardware_concurrency());
  Data data = LoadData(data_dir, gallery_size, num_clouds);
  if (points > 0) {
    // Bigger (or smaller) queries against the same gallery: synthetic surfaces of `points`
    // points, a few distinct ones cycled. Far from every stored sample, they make the search
    // the slowest it can be (early abandonment drops little); --query_views is the fair one.
    data.test.clear();
    for (size_t i = 0; i < std::min<size_t>(num_clouds, 16); ++i) {
      data.test.push_back(
          {"query", bench::SurfaceCloud(points, 900000 + static_cast<uint32_t>(i))});
    }
    absl::StrAppend(&data.source, "; queries: ", data.test.size(), " synthetic clouds of ", points,
                    " points");
  }
  if (query_views) {
    // What a robot sends: one side of a test object (SensorView: 300-500 points, 1 % noise,
    // any pose). The search's cost does depend on the query: early abandonment drops a stored
    // vector sooner the nearer the query's neighbors are.
    size_t view_points = 0;
    for (size_t i = 0; i < data.test.size(); ++i) {
      absl::StatusOr<PointCloud> view = SensorView(data.test[i].cloud, SensorViewOptions(), i + 1);
      if (!view.ok()) {
        std::fprintf(stderr, "%s\n", view.status().ToString().c_str());
        return 1;
      }
      view_points += view->size();
      data.test[i].cloud = std::move(*view);
    }
    absl::StrAppend(&data.source, "; queries: single-side sensor views of them, ",
                    view_points / std::max<size_t>(1, data.test.size()), " points on average");
  }
  std::printf("clouds: %s\n", data.source.c_str());

  ServerOptions options;
  options.listen = "127.0.0.1:0";
  options.gallery_limits.approximate.min_vectors = approximate_min_vectors;
  options.gallery_limits.approximate.probes = approximate_probes;
  options.log.level = *ParseLogLevel(log_level_name);  // both checked by CLI11
  options.log.format = *ParseLogFormat(log_format_name);
  std::printf("server log: level %s, format %s%s\n", log_level_name.c_str(),
              log_format_name.c_str(),
              options.log.level < LogLevel::kError ? absl::StrCat(", to ", log_file).c_str() : "");
  LogCapture capture;
  if (options.log.level < LogLevel::kError && !capture.Start(log_file)) return 1;
  auto started = ShapeIdServer::Start(options);
  if (!started.ok()) {
    capture.Stop();
    std::fprintf(stderr, "%s\n", started.status().ToString().c_str());
    return 1;
  }
  std::unique_ptr<ShapeIdServer> server = std::move(started).value();
  auto channel = MakeChannel(server->address(), false);
  auto stub = v1::ShapeId::NewStub(channel);
  const auto train_start = Clock::now();
  if (!CreateAndTrain(*stub, spec, augment_views, data.train, train_streams)) return 1;
  std::printf("trained %zu samples over %d Train streams on %s in %.2f s\n", data.train.size(),
              train_streams, server->address().c_str(),
              std::chrono::duration<double>(Clock::now() - train_start).count());

  // The in-process twin: an identical gallery (same spec, same samples in the same order).
  // Its growth in resident memory is what a trained sample costs (allocator slack included).
  const absl::StatusOr<ProcessStats> before_twin = ReadProcessStats();
  GalleryRegistry registry(options.gallery_limits);
  GalleryOptions gallery_options;
  if (!spec.empty()) gallery_options.descriptor_spec = spec;
  gallery_options.augment.views = augment_views;
  auto gallery = registry.Create(kGalleryName, gallery_options);
  if (!gallery.ok()) {
    std::fprintf(stderr, "%s\n", gallery.status().ToString().c_str());
    return 1;
  }
  {
    std::vector<LabeledCloud> samples;
    samples.reserve(data.train.size());
    for (const Sample& s : data.train) samples.push_back({0, s.label, s.cloud});
    auto trained = (*gallery)->Train(samples);
    if (!trained.ok()) {
      std::fprintf(stderr, "%s\n", trained.status().ToString().c_str());
      return 1;
    }
  }
  const absl::StatusOr<ProcessStats> after_twin = ReadProcessStats();
  if (before_twin.ok() && after_twin.ok() && !data.train.empty()) {
    std::printf(
        "memory: %.0f bytes of resident memory per trained sample (%d stored views each; "
        "the in-process gallery's growth over %zu samples)\n",
        static_cast<double>(after_twin->resident_bytes - before_twin->resident_bytes) /
            static_cast<double>(data.train.size()),
        augment_views, data.train.size());
  }

  const std::vector<Query> queries = BuildQueries(data.test);
  const InProcessResult local = InProcess(**gallery, data.test, warmup, requests, seconds);
  capture.Mark();
  const LatencyResult rpc = SingleClient(*stub, queries, local.labels, warmup, requests, mode);

  std::vector<LoadResult> loads;
  for (int c : clients) {
    if (channels_mode != "per-client")
      loads.push_back(Load(server->address(), queries, c, false, seconds, mode));
    if (channels_mode != "shared" && c > 1)
      loads.push_back(Load(server->address(), queries, c, true, seconds, mode));
  }
  capture.Mark();
  const std::string load_after = LoadAverage();
  server->Shutdown(absl::Seconds(1));
  server.reset();
  capture.Stop();
  const LogCapture::Summary log = capture.Summarize();

  // ------------------------------------------------------------------ report
  const double ratio = local.stats.p50_us > 0 ? rpc.stats.p50_us / local.stats.p50_us : 0;
  std::printf(
      "\nSingle client, sequential, %lld classifications (after %d warm-up), write mode %s\n",
      static_cast<long long>(rpc.stats.count), warmup, write_mode_name.c_str());
  std::printf("  %-12s %9s %9s %9s %9s\n", "", "p50 us", "p90 us", "p99 us", "mean us");
  std::printf("  %-12s %9.1f %9.1f %9.1f %9.1f\n", "RPC", rpc.stats.p50_us, rpc.stats.p90_us,
              rpc.stats.p99_us, rpc.stats.mean_us);
  std::printf("  %-12s %9.1f %9.1f %9.1f %9.1f\n", "in-process", local.stats.p50_us,
              local.stats.p90_us, local.stats.p99_us, local.stats.mean_us);
  std::printf("  RPC overhead: x%.2f at p50 (+%.1f us); mean +%.1f us\n", ratio,
              rpc.stats.p50_us - local.stats.p50_us, rpc.stats.mean_us - local.stats.mean_us);
  std::printf("  server-side describe %.1f us + search %.1f us (in-process: %.1f + %.1f)\n",
              rpc.server.describe_us, rpc.server.search_us, local.describe_us, local.search_us);
  const bool modelnet_size = points == 0 || points == 1024;
  std::printf("  target p50 < 1000 us (1,024-point clouds): %s\n", !modelnet_size ? "not this size"
                                                                   : rpc.stats.p50_us < 1000
                                                                       ? "MET"
                                                                       : "MISSED");
  std::printf(
      "  searches approximate: %d of %zu distinct queries; answers differing from an exact "
      "search: %d; correct %d (exact search: %d)\n",
      local.approximate_searches, data.test.size(), local.differ_from_exact, local.correct,
      local.correct_exact);
  if (rpc.errors > 0 || rpc.label_mismatches > 0) {
    std::printf("  WARNING: %lld errors, %lld answers differ from in-process\n",
                static_cast<long long>(rpc.errors), static_cast<long long>(rpc.label_mismatches));
  }
  std::printf("\nConcurrent clients, %.1f s each (in-process, 2 threads: %.0f /s)\n", seconds,
              local.throughput_2t);
  std::printf("  %7s  %-11s %9s %9s %9s %12s %12s %6s\n", "clients", "channels", "calls/s",
              "p50 us", "p99 us", "cpu us/call", "server cpu", "errors");
  for (const LoadResult& l : loads) {
    std::printf("  %7d  %-11s %9.0f %9.1f %9.1f %12.1f %12.1f %6lld\n", l.clients,
                l.channel_per_client ? "per-client" : "shared", l.per_second, l.stats.p50_us,
                l.stats.p99_us, l.cpu_us_per_call, l.cpu_us_per_call - l.client_cpu_us_per_call,
                static_cast<long long>(l.errors));
  }
  std::printf(
      "  (cpu us/call: the whole process; server cpu: less the load generator's threads)\n");
  // The best 16-client configuration (or the largest client count measured).
  const int top = *std::max_element(clients.begin(), clients.end());
  const LoadResult* best = nullptr;
  for (const LoadResult& l : loads) {
    if (l.clients == top && (best == nullptr || l.per_second > best->per_second)) best = &l;
  }
  if (std::find(clients.begin(), clients.end(), 16) != clients.end()) {
    std::printf("  best at 16 clients: %.0f /s; target >= 3000 /s (1,024-point clouds): %s\n",
                BestAt(loads, 16),
                !modelnet_size              ? "not this size"
                : BestAt(loads, 16) >= 3000 ? "MET"
                                            : "MISSED");
  }
  if (options.log.level < LogLevel::kError) {
    const double rate = log.window_seconds > 0 ? log.window_lines / log.window_seconds : 0;
    std::printf(
        "\nServer log (%s, %s): %lld bytes, %lld lines (%.0f bytes/line) in %s; "
        "%.0f lines/s, %.0f KB/s over the RPC phases (%.1f s)\n",
        log_level_name.c_str(), log_format_name.c_str(), static_cast<long long>(log.bytes),
        static_cast<long long>(log.lines),
        log.lines > 0 ? static_cast<double>(log.bytes) / log.lines : 0.0, log_file.c_str(), rate,
        log.window_lines > 0 ? rate * log.bytes / log.lines / 1e3 : 0.0, log.window_seconds);
  }
  std::printf("load average after: %s\n", load_after.c_str());

  std::vector<std::string> load_json;
  for (const LoadResult& l : loads) {
    load_json.push_back(absl::StrFormat(
        R"({"clients":%d,"channels":"%s","per_second":%.1f,"p50_us":%.1f,"p99_us":%.1f,"cpu_us_per_call":%.1f,"server_cpu_us_per_call":%.1f,"errors":%d})",
        l.clients, l.channel_per_client ? "per-client" : "shared", l.per_second, l.stats.p50_us,
        l.stats.p99_us, l.cpu_us_per_call, l.cpu_us_per_call - l.client_cpu_us_per_call, l.errors));
  }
  std::fputs(absl::StrFormat(
                 "JSON {\"bench\":\"service\",\"data\":\"%s\",\"points\":%zu,\"gallery_size\":%zu,"
                 "\"write_mode\":\"%s\",\"log_level\":\"%s\",\"log_format\":\"%s\","
                 "\"log_bytes\":%d,\"log_lines\":%d,\"log_lines_per_second\":%.0f,"
                 "\"rpc\":%s,\"in_process\":%s,\"overhead_ratio_p50\":%.2f,"
                 "\"overhead_us_p50\":%.1f,\"server_describe_us\":%.1f,\"server_search_us\":%.1f,"
                 "\"in_process_2t_per_second\":%.1f,\"load\":[%s],\"best_top\":%.1f,"
                 "\"loadavg_before\":\"%s\",\"loadavg_after\":\"%s\"}\n",
                 data.source.rfind("SYNTHETIC", 0) == 0 ? "synthetic" : "modelnet10",
                 points == 0 ? data.test[0].cloud.size() : points, gallery_size, write_mode_name,
                 log_level_name, log_format_name, log.bytes, log.lines,
                 log.window_seconds > 0 ? log.window_lines / log.window_seconds : 0.0,
                 StatsJson(rpc.stats), StatsJson(local.stats), ratio,
                 rpc.stats.p50_us - local.stats.p50_us, rpc.server.describe_us,
                 rpc.server.search_us, local.throughput_2t, absl::StrJoin(load_json, ","),
                 best ? best->per_second : 0.0, load_before, load_after)
                 .c_str(),
             stdout);
  return rpc.errors > 0 ? 1 : 0;
}

}  // namespace
}  // namespace shapeid

int main(int argc, char** argv) { return shapeid::Run(argc, argv); }
