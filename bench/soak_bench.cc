// Soak test (issue 10): the real shapeid-server binary, started as a child process on a
// loopback port with a fresh data directory (the SQLite store, fsync'd as in production), under
// a long mixed load from many clients. Each client has its own channel and TCP connection and,
// in a closed loop, trains into a gallery of its own, removes its oldest samples once the
// gallery passes --gallery_samples (so the server's data stays bounded and its memory should
// be flat), classifies and describes (one-message and streamed calls), reads, lists and exports
// its gallery, and now and then deletes a scratch gallery and recreates it (created and trained,
// or imported from its last export). Every answer is checked against what the client knows
// its galleries hold; every non-OK status or failed check is an error.
//
//   soak_bench                                   the issue's run: 32 clients, 600 s
//   soak_bench --seconds 6 --clients 8 --window_seconds 1 --skip_memory_check   (CI smoke)
//
// Per window (--window_seconds) it records requests and latency by kind, errors, and the
// server's resident memory (VmRSS of the child) and CPU; it writes the windows as JSON lines
// (--out), draws them as an SVG (--svg), and prints a summary. PASS: no error, RSS growth from
// the end of the warm-up to the end under 5 %, and exit 0 after SIGTERM. Exit 0 pass, 1 fail,
// 2 usage error. Figures: docs/reliability.md.
//
// Raw stubs rather than shapeid::Client: the client library retries UNAVAILABLE (which would
// hide errors) and shares one TCP connection among all its channels (gRPC's global subchannel
// pool), while 32 robots would open 32 connections.

#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <deque>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <mutex>
#include <random>
#include <set>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "CLI/CLI.hpp"
#include "absl/status/status.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/strings/str_join.h"
#include "absl/time/time.h"
#include "bench/bench_clouds.h"
#include "client/client.h"
#include "grpcpp/grpcpp.h"
#include "server/testing/child_server.h"
#include "shapeid/v1/shapeid.grpc.pb.h"

extern char** environ;

namespace shapeid {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

double SecondsSince(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

// ----------------------------------------------------------------------------- the server


std::string TailOfFile(const std::string& path, size_t max_bytes) {
  std::ifstream in(path);
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  return text.size() > max_bytes ? text.substr(text.size() - max_bytes) : text;
}

double LoadAverage1() {
  std::ifstream in("/proc/loadavg");
  double one = 0;
  in >> one;
  return one;
}

std::string LoadAverages() {
  std::ifstream in("/proc/loadavg");
  std::string a, b, c;
  in >> a >> b >> c;
  return absl::StrCat(a, " ", b, " ", c);
}

// ----------------------------------------------------------------------------- clouds

struct Pool {
  std::vector<std::string> xyz;      // train clouds as PointChunk bytes
  std::vector<std::string> labels;   // label of each: a cloud always trains under one label
  std::vector<std::string> queries;  // query clouds (never trained), PointChunk bytes
  std::string source;
};

std::string Bytes(const PointCloud& cloud) {
  return std::string(reinterpret_cast<const char*>(cloud.data()), cloud.size() * 12);
}

// `per_class` train clouds and `per_class / 2` test clouds of every ModelNet10 class, or
// synthetic clouds under 10 labels where the data is absent.
Pool LoadPool(const fs::path& root, size_t per_class) {
  Pool pool;
  std::error_code error;
  std::vector<fs::path> classes;
  for (const auto& entry : fs::directory_iterator(root, error)) {
    if (entry.is_directory()) classes.push_back(entry.path());
  }
  std::sort(classes.begin(), classes.end());
  for (const fs::path& cls : classes) {
    for (const char* split : {"train", "test"}) {
      std::vector<fs::path> files;
      for (const auto& entry : fs::directory_iterator(cls / split, error)) {
        files.push_back(entry.path());
      }
      std::sort(files.begin(), files.end());
      const size_t want = std::string(split) == "train" ? per_class : per_class / 2;
      for (size_t i = 0; i < files.size() && i < want; ++i) {
        auto read = ReadPointCloud(files[i].string());
        if (!read.ok()) continue;
        if (std::string(split) == "train") {
          pool.xyz.push_back(Bytes(read->cloud));
          pool.labels.push_back(cls.filename().string());
        } else {
          pool.queries.push_back(Bytes(read->cloud));
        }
      }
    }
  }
  if (!pool.xyz.empty() && !pool.queries.empty()) {
    pool.source = absl::StrCat("ModelNet10 (", pool.xyz.size(), " train and ", pool.queries.size(),
                               " test clouds, ", classes.size(), " classes, 1,024 points each)");
    return pool;
  }
  pool = Pool();
  for (size_t i = 0; i < 10 * per_class; ++i) {
    pool.xyz.push_back(Bytes(bench::SurfaceCloud(1024, 1000 + static_cast<uint32_t>(i))));
    pool.labels.push_back(absl::StrCat("shape-", i % 10));
  }
  for (size_t i = 0; i < 5 * per_class; ++i) {
    pool.queries.push_back(Bytes(bench::SurfaceCloud(1024, 900000 + static_cast<uint32_t>(i))));
  }
  pool.source = absl::StrCat("SYNTHETIC 1,024-point clouds under 10 labels (no ModelNet10 at ",
                             root.string(), ")");
  return pool;
}

// ----------------------------------------------------------------------------- recording

enum Kind {
  kTrain,
  kClassifyCloud,
  kClassifyStream,
  kDescribeCloud,
  kDescribeStream,
  kCreateGallery,
  kGetGallery,
  kListGalleries,
  kRemoveSamples,
  kDeleteGallery,
  kExportGallery,
  kImportGallery,
  kNumKinds
};

constexpr const char* kKindNames[kNumKinds] = {
    "train",           "classify_cloud", "classify_stream", "describe_cloud",
    "describe_stream", "create_gallery", "get_gallery",     "list_galleries",
    "remove_samples",  "delete_gallery", "export_gallery",  "import_gallery"};

// What the clients did since the last window: latencies (ns) of successful requests by kind
// and the number of errors.
struct Tally {
  std::vector<int64_t> ns[kNumKinds];
  int64_t errors = 0;
};

// Every client's Tally, swapped out by the sampler at each window's end.
class Recorder {
 public:
  explicit Recorder(int clients) : slots_(static_cast<size_t>(clients)) {}

  void Record(int client, Kind kind, int64_t ns, bool ok) {
    Slot& slot = slots_[static_cast<size_t>(client)];
    std::lock_guard<std::mutex> lock(slot.mu);
    if (ok) {
      slot.tally.ns[kind].push_back(ns);
    } else {
      ++slot.tally.errors;
    }
  }

  Tally Take() {
    Tally all;
    for (Slot& slot : slots_) {
      Tally taken;
      {
        std::lock_guard<std::mutex> lock(slot.mu);
        std::swap(taken, slot.tally);
      }
      for (int k = 0; k < kNumKinds; ++k) {
        all.ns[k].insert(all.ns[k].end(), taken.ns[k].begin(), taken.ns[k].end());
      }
      all.errors += taken.errors;
    }
    return all;
  }

 private:
  struct Slot {
    std::mutex mu;
    Tally tally;
  };
  std::vector<Slot> slots_;
};

// The first errors in full, and how many there were.
class ErrorLog {
 public:
  void Add(double at_s, int client, Kind kind, const absl::Status& status) {
    std::lock_guard<std::mutex> lock(mu_);
    ++count_;
    if (first_.size() < 10) {
      first_.push_back(absl::StrFormat("%8.2f s  client %2d  %-15s %s", at_s, client,
                                       kKindNames[kind], status.ToString()));
    }
  }
  int64_t count() const {
    std::lock_guard<std::mutex> lock(mu_);
    return count_;
  }
  std::vector<std::string> first() const {
    std::lock_guard<std::mutex> lock(mu_);
    return first_;
  }

 private:
  mutable std::mutex mu_;
  int64_t count_ = 0;
  std::vector<std::string> first_;
};

// p-th quantile (nearest rank) of `ns`, in milliseconds; sorts `ns`.
double QuantileMs(std::vector<int64_t>& ns, double q) {
  if (ns.empty()) return 0;
  std::sort(ns.begin(), ns.end());
  const size_t i = std::min(ns.size() - 1, static_cast<size_t>(q * (ns.size() - 1) + 0.5));
  return static_cast<double>(ns[i]) / 1e6;
}

// ----------------------------------------------------------------------------- one client

absl::Status Check(bool ok, const std::string& what) {
  return ok ? absl::OkStatus() : absl::InternalError(absl::StrCat("check failed: ", what));
}

struct Held {
  uint64_t id;
  std::string label;
  size_t cloud;  // index in Pool::xyz; SIZE_MAX if unknown (after a resync)
};

// Streamed calls send 1,024-point clouds in chunks of 256 points.
constexpr size_t kChunkBytes = 256 * 12;

struct ClientSettings {
  size_t gallery_samples = 64;  // trim back to 3/4 of this once a Train passes it
  absl::Duration deadline = absl::Seconds(30);
};

// One simulated robot: a channel, a gallery "soak-NN" and a scratch gallery "soak-NN-scratch"
// that only it changes, so it knows exactly what each answer must say.
class SoakClient {
 public:
  SoakClient(int index, const std::string& address, const Pool& pool, ClientSettings settings)
      : pool_(pool),
        settings_(settings),
        rng_(7919u * static_cast<uint32_t>(index) + 1),
        name_(absl::StrFormat("soak-%02d", index)),
        scratch_(absl::StrCat(name_, "-scratch")),
        next_id_(1) {
    grpc::ChannelArguments args;
    args.SetMaxReceiveMessageSize(64 << 20);
    args.SetInt(GRPC_ARG_USE_LOCAL_SUBCHANNEL_POOL, 1);  // a TCP connection of its own
    channel_ = grpc::CreateCustomChannel(address, grpc::InsecureChannelCredentials(), args);
    stub_ = v1::ShapeId::NewStub(channel_);
  }

  // The galleries and their first samples. Not timed.
  absl::Status SetUp() {
    channel_->WaitForConnected(std::chrono::system_clock::now() + std::chrono::seconds(10));
    if (absl::Status s = CreateGallery(name_, 3); !s.ok()) return s;
    if (absl::Status s = CreateGallery(scratch_, 1); !s.ok()) return s;
    scratch_exists_ = true;
    while (held_.size() < settings_.gallery_samples / 2) {
      if (absl::Status s = Train(false, 4); !s.ok()) return s;
    }
    return Train(true, 2);
  }

  // The next request: what a previous step requires, else a weighted draw.
  Kind Next() {
    if (!pending_.empty()) {
      const Kind kind = pending_.front();
      pending_.pop_front();
      return kind;
    }
    // Percent of the free draws; RemoveSamples, CreateGallery, ImportGallery (and a scratch
    // Train) follow from Train and DeleteGallery.
    static constexpr std::pair<Kind, int> kWeights[] = {
        {kClassifyCloud, 32}, {kClassifyStream, 14}, {kDescribeCloud, 12},
        {kDescribeStream, 6}, {kTrain, 18},          {kGetGallery, 8},
        {kListGalleries, 4},  {kExportGallery, 3},   {kDeleteGallery, 3}};
    int draw = std::uniform_int_distribution<int>(0, 99)(rng_);
    for (const auto& [kind, weight] : kWeights) {
      if (draw < weight) return kind;
      draw -= weight;
    }
    return kClassifyCloud;
  }

  absl::Status Run(Kind kind) {
    switch (kind) {
      case kTrain:
        if (train_scratch_next_) {
          train_scratch_next_ = false;
          return Train(true, 2);
        }
        return Train(false, 1 + std::uniform_int_distribution<int>(0, 3)(rng_));
      case kClassifyCloud:
        return Classify(false);
      case kClassifyStream:
        return Classify(true);
      case kDescribeCloud:
        return Describe(false);
      case kDescribeStream:
        return Describe(true);
      case kCreateGallery:
        return CreateGallery(scratch_, 1);
      case kGetGallery:
        return GetGallery();
      case kListGalleries:
        return ListGalleries();
      case kRemoveSamples:
        return RemoveSamples();
      case kDeleteGallery:
        return DeleteScratch();
      case kExportGallery:
        return Export();
      case kImportGallery:
        return ImportScratch();
      case kNumKinds:
        break;
    }
    return absl::InternalError("no such request kind");
  }

  // After an error: what the server holds now (a failed call changes nothing, but a deadline
  // may pass after the server committed), read back from an export and GetGallery.
  absl::Status Resync() {
    pending_.clear();
    train_scratch_next_ = false;
    std::vector<v1::GalleryExportChunk> chunks;
    if (absl::Status s = ReadExport(&chunks); !s.ok()) return s;
    held_.clear();
    for (const v1::GalleryExportChunk& chunk : chunks) {
      if (!chunk.has_samples()) continue;
      for (int i = 0; i < chunk.samples().sample_ids_size(); ++i) {
        held_.push_back({chunk.samples().sample_ids(i), chunk.samples().labels(i), SIZE_MAX});
        next_id_ = std::max(next_id_, chunk.samples().sample_ids(i) + 1);
      }
    }
    grpc::ClientContext context;
    SetDeadline(context);
    v1::GetGalleryRequest request;
    request.set_name(scratch_);
    v1::Gallery gallery;
    const grpc::Status status = stub_->GetGallery(&context, request, &gallery);
    scratch_exists_ = status.ok();
    scratch_count_ = status.ok() ? gallery.sample_count() : 0;
    if (!status.ok() && status.error_code() != grpc::StatusCode::NOT_FOUND) {
      return FromGrpcStatus(status);
    }
    if (!scratch_exists_) pending_.push_back(kCreateGallery);
    return absl::OkStatus();
  }

 private:
  void SetDeadline(grpc::ClientContext& context) const {
    context.set_deadline(absl::ToChronoTime(absl::Now() + settings_.deadline));
  }

  size_t RandomCloud() {
    return std::uniform_int_distribution<size_t>(0, pool_.xyz.size() - 1)(rng_);
  }

  absl::Status CreateGallery(const std::string& name, uint32_t k) {
    grpc::ClientContext context;
    SetDeadline(context);
    v1::CreateGalleryRequest request;
    request.set_name(name);
    request.mutable_knn()->set_k(k);
    v1::Gallery gallery;
    const grpc::Status status = stub_->CreateGallery(&context, request, &gallery);
    if (!status.ok()) return FromGrpcStatus(status);
    if (name == scratch_) {
      scratch_exists_ = true;
      scratch_count_ = 0;
      train_scratch_next_ = true;
      pending_.push_back(kTrain);
    } else {
      spec_ = gallery.descriptor_spec();
      dimension_ = gallery.dimension();
    }
    return Check(gallery.name() == name && gallery.sample_count() == 0 && gallery.knn().k() == k &&
                     gallery.dimension() > 0,
                 absl::StrCat("CreateGallery answer for ", name));
  }

  // One stream of `n` samples (client-chosen ids), each cloud in one or two chunks.
  absl::Status Train(bool scratch, int n) {
    grpc::ClientContext context;
    SetDeadline(context);
    v1::TrainResponse response;
    auto writer = stub_->Train(&context, &response);
    v1::TrainRequest request;
    request.mutable_header()->set_gallery(scratch ? scratch_ : name_);
    bool open = writer->Write(request);
    std::vector<Held> added;
    for (int i = 0; i < n && open; ++i) {
      const size_t cloud = RandomCloud();
      const std::string& xyz = pool_.xyz[cloud];
      added.push_back({next_id_++, pool_.labels[cloud], cloud});
      request.Clear();
      request.mutable_sample()->set_label(added.back().label);
      request.mutable_sample()->set_sample_id(added.back().id);
      request.mutable_sample()->set_expected_points(xyz.size() / 12);
      open = writer->Write(request);
      const size_t half = xyz.size() / 24 * 12;  // two chunks, split on a point boundary
      for (const std::string& part : {xyz.substr(0, half), xyz.substr(half)}) {
        request.Clear();
        request.mutable_points()->set_xyz(part);
        open = open && writer->Write(request);
      }
    }
    writer->WritesDone();
    const grpc::Status status = writer->Finish();
    if (!status.ok()) return FromGrpcStatus(status);
    const uint64_t before = scratch ? scratch_count_ : held_.size();
    bool ids_ok = response.sample_ids_size() == n;
    for (int i = 0; ids_ok && i < n; ++i) ids_ok = response.sample_ids(i) == added[i].id;
    if (scratch) {
      scratch_count_ += static_cast<uint64_t>(n);
    } else {
      held_.insert(held_.end(), added.begin(), added.end());
      if (held_.size() > settings_.gallery_samples) pending_.push_back(kRemoveSamples);
    }
    return Check(ids_ok && response.gallery_sample_count() == before + static_cast<uint64_t>(n),
                 absl::StrCat("Train answer: ", response.sample_ids_size(), " ids, gallery of ",
                              response.gallery_sample_count(), " samples; expected ", n, " ids, ",
                              before + n));
  }

  // The oldest samples, down to 3/4 of the bound; every fourth time also every sample of the
  // oldest one's label (the union), as long as a quarter of the bound remains.
  absl::Status RemoveSamples() {
    const size_t target = settings_.gallery_samples * 3 / 4;
    if (held_.size() <= target) return absl::OkStatus();
    v1::RemoveSamplesRequest request;
    request.set_gallery(name_);
    std::set<uint64_t> removed;
    for (size_t i = 0; i < held_.size() - target; ++i) {
      request.add_sample_ids(held_[i].id);
      removed.insert(held_[i].id);
    }
    if (++removals_ % 4 == 0) {
      const std::string& label = held_.front().label;
      size_t with_label = removed.size();
      for (const Held& h : held_) with_label += h.label == label && !removed.count(h.id);
      if (held_.size() - with_label >= settings_.gallery_samples / 4) {
        request.add_labels(label);
        for (const Held& h : held_) {
          if (h.label == label) removed.insert(h.id);
        }
      }
    }
    grpc::ClientContext context;
    SetDeadline(context);
    v1::RemoveSamplesResponse response;
    const grpc::Status status = stub_->RemoveSamples(&context, request, &response);
    if (!status.ok()) return FromGrpcStatus(status);
    std::deque<Held> kept;
    for (Held& h : held_) {
      if (!removed.count(h.id)) kept.push_back(std::move(h));
    }
    held_ = std::move(kept);
    return Check(
        response.removed() == removed.size() && response.remaining() == held_.size(),
        absl::StrCat("RemoveSamples answer: removed ", response.removed(), ", remaining ",
                     response.remaining(), "; expected ", removed.size(), ", ", held_.size()));
  }

  // Half the time the cloud of a sample held now (k = 1: it must find itself, or a copy: a
  // cloud always trains under one label), half the time an unseen one (the gallery's k = 3).
  // Either way the label and every neighbour must be among the samples held now.
  absl::Status Classify(bool stream) {
    const Held* self = nullptr;
    if (std::uniform_int_distribution<int>(0, 1)(rng_) == 1 && !held_.empty()) {
      self = &held_[std::uniform_int_distribution<size_t>(0, held_.size() - 1)(rng_)];
      if (self->cloud >= pool_.xyz.size()) self = nullptr;  // unknown since a resync
    }
    const std::string& xyz = self != nullptr ? pool_.xyz[self->cloud]
                                             : pool_.queries[std::uniform_int_distribution<size_t>(
                                                   0, pool_.queries.size() - 1)(rng_)];
    v1::ClassifyHeader header;
    header.set_gallery(name_);
    header.set_expected_points(xyz.size() / 12);
    if (self != nullptr) header.set_k(1);
    v1::ClassifyResponse response;
    grpc::ClientContext context;
    SetDeadline(context);
    grpc::Status status;
    if (stream) {
      auto writer = stub_->Classify(&context, &response);
      v1::ClassifyRequest request;
      *request.mutable_header() = header;
      bool open = writer->Write(request);
      for (size_t first = 0; open && first < xyz.size(); first += kChunkBytes) {
        request.Clear();
        request.mutable_points()->set_xyz(xyz.substr(first, kChunkBytes));
        open = writer->Write(request);
      }
      writer->WritesDone();
      status = writer->Finish();
    } else {
      v1::ClassifyCloudRequest request;
      *request.mutable_header() = header;
      request.mutable_points()->set_xyz(xyz);
      status = stub_->ClassifyCloud(&context, request, &response);
    }
    if (!status.ok()) return FromGrpcStatus(status);
    std::map<uint64_t, const std::string*> held_labels;
    for (const Held& h : held_) held_labels[h.id] = &h.label;
    const size_t k = self != nullptr ? 1 : 3;
    bool neighbours_ok = response.neighbors_size() == static_cast<int>(std::min(k, held_.size()));
    for (const v1::Neighbor& n : response.neighbors()) {
      auto it = held_labels.find(n.sample_id());
      neighbours_ok = neighbours_ok && it != held_labels.end() && *it->second == n.label();
    }
    const bool label_ok =
        self != nullptr ? response.label() == self->label
                        : std::any_of(held_.begin(), held_.end(),
                                      [&](const Held& h) { return h.label == response.label(); });
    const bool ok = neighbours_ok && label_ok && !response.unknown() && response.confidence() > 0 &&
                    response.confidence() <= 1 && response.num_points() == xyz.size() / 12;
    return Check(
        ok, absl::StrCat(stream ? "Classify" : "ClassifyCloud", " answer: label '",
                         response.label(), "'",
                         self != nullptr ? absl::StrCat(" for a held '", self->label, "' cloud")
                                         : " for an unseen cloud",
                         ", ", response.neighbors_size(),
                         " neighbours (all held: ", neighbours_ok ? "yes" : "no", ", nearest at ",
                         response.neighbors_size() > 0 ? response.neighbors(0).distance() : -1.0,
                         "), confidence ", response.confidence()));
  }

  // The descriptor of a pool cloud, by the gallery's spec; the same cloud must always give
  // the same values.
  absl::Status Describe(bool stream) {
    const size_t cloud = RandomCloud();
    const std::string& xyz = pool_.xyz[cloud];
    v1::DescribeHeader header;
    header.set_gallery(name_);
    header.set_expected_points(xyz.size() / 12);
    v1::DescribeResponse response;
    grpc::ClientContext context;
    SetDeadline(context);
    grpc::Status status;
    if (stream) {
      auto writer = stub_->Describe(&context, &response);
      v1::DescribeRequest request;
      *request.mutable_header() = header;
      bool open = writer->Write(request);
      for (size_t first = 0; open && first < xyz.size(); first += kChunkBytes) {
        request.Clear();
        request.mutable_points()->set_xyz(xyz.substr(first, kChunkBytes));
        open = writer->Write(request);
      }
      writer->WritesDone();
      status = writer->Finish();
    } else {
      v1::DescribeCloudRequest request;
      *request.mutable_header() = header;
      request.mutable_points()->set_xyz(xyz);
      status = stub_->DescribeCloud(&context, request, &response);
    }
    if (!status.ok()) return FromGrpcStatus(status);
    std::vector<float> values(response.values().begin(), response.values().end());
    auto [seen, first_time] = descriptors_.emplace(cloud, values);
    return Check(response.descriptor_spec() == spec_ && values.size() == dimension_ &&
                     response.num_points() == xyz.size() / 12 &&
                     (first_time || seen->second == values),
                 absl::StrCat("Describe answer: spec '", response.descriptor_spec(), "', ",
                              values.size(), " values, ", response.num_points(), " points",
                              first_time || seen->second == values
                                  ? ""
                                  : "; values differ from the same cloud's earlier ones"));
  }

  absl::Status CheckGallery(const v1::Gallery& gallery) const {
    std::map<std::string, uint64_t> counts;
    for (const Held& h : held_) ++counts[h.label];
    bool counts_ok = gallery.label_counts_size() == static_cast<int>(counts.size());
    for (const v1::LabelCount& c : gallery.label_counts()) {
      counts_ok = counts_ok && counts[c.label()] == c.count();
    }
    return Check(gallery.name() == name_ && gallery.sample_count() == held_.size() &&
                     gallery.vector_count() == held_.size() && gallery.dimension() == dimension_ &&
                     counts_ok,
                 absl::StrCat("gallery ", gallery.name(), ": ", gallery.sample_count(),
                              " samples (expected ", held_.size(), "), label counts ",
                              counts_ok ? "right" : "wrong"));
  }

  absl::Status GetGallery() {
    grpc::ClientContext context;
    SetDeadline(context);
    v1::GetGalleryRequest request;
    request.set_name(name_);
    v1::Gallery gallery;
    const grpc::Status status = stub_->GetGallery(&context, request, &gallery);
    if (!status.ok()) return FromGrpcStatus(status);
    return CheckGallery(gallery);
  }

  absl::Status ListGalleries() {
    grpc::ClientContext context;
    SetDeadline(context);
    v1::ListGalleriesResponse response;
    const grpc::Status status =
        stub_->ListGalleries(&context, v1::ListGalleriesRequest(), &response);
    if (!status.ok()) return FromGrpcStatus(status);
    bool sorted = true;
    const v1::Gallery* own = nullptr;
    for (int i = 0; i < response.galleries_size(); ++i) {
      if (i > 0) sorted = sorted && response.galleries(i - 1).name() < response.galleries(i).name();
      if (response.galleries(i).name() == name_) own = &response.galleries(i);
    }
    if (!sorted || own == nullptr) {
      return Check(false, absl::StrCat("ListGalleries: ", response.galleries_size(),
                                       " galleries, sorted: ", sorted ? "yes" : "no", ", ", name_,
                                       own ? " listed" : " missing"));
    }
    return CheckGallery(*own);
  }

  absl::Status ReadExport(std::vector<v1::GalleryExportChunk>* chunks) {
    grpc::ClientContext context;
    SetDeadline(context);
    v1::ExportGalleryRequest request;
    request.set_name(name_);
    auto reader = stub_->ExportGallery(&context, request);
    v1::GalleryExportChunk chunk;
    while (reader->Read(&chunk)) chunks->push_back(chunk);
    return FromGrpcStatus(reader->Finish());
  }

  // The whole gallery: header, samples in training order, trailer; kept for ImportScratch.
  absl::Status Export() {
    std::vector<v1::GalleryExportChunk> chunks;
    if (absl::Status s = ReadExport(&chunks); !s.ok()) return s;
    std::vector<uint64_t> ids;
    for (const v1::GalleryExportChunk& chunk : chunks) {
      if (chunk.has_samples()) {
        ids.insert(ids.end(), chunk.samples().sample_ids().begin(),
                   chunk.samples().sample_ids().end());
      }
    }
    bool ids_ok = ids.size() == held_.size();
    for (size_t i = 0; ids_ok && i < ids.size(); ++i) ids_ok = ids[i] == held_[i].id;
    const bool framed = chunks.size() >= 2 && chunks.front().has_header() &&
                        chunks.back().has_trailer() &&
                        chunks.front().header().sample_count() == held_.size() &&
                        chunks.back().trailer().sample_count() == held_.size();
    if (framed && ids_ok) last_export_ = std::move(chunks);
    return Check(framed && ids_ok,
                 absl::StrCat("ExportGallery: ", ids.size(), " samples (expected ", held_.size(),
                              "), in order: ", ids_ok ? "yes" : "no"));
  }

  // Deletes the scratch gallery; a CreateGallery (then a Train) or, when there is an export
  // to import, every other time an ImportGallery recreates it.
  absl::Status DeleteScratch() {
    if (!scratch_exists_) {
      pending_.push_back(kCreateGallery);
      return absl::OkStatus();
    }
    grpc::ClientContext context;
    SetDeadline(context);
    v1::DeleteGalleryRequest request;
    request.set_name(scratch_);
    v1::DeleteGalleryResponse response;
    const grpc::Status status = stub_->DeleteGallery(&context, request, &response);
    if (!status.ok()) return FromGrpcStatus(status);
    scratch_exists_ = false;
    const bool import = !last_export_.empty() && ++recreations_ % 2 == 0;
    pending_.push_back(import ? kImportGallery : kCreateGallery);
    return Check(response.samples_deleted() == scratch_count_,
                 absl::StrCat("DeleteGallery: ", response.samples_deleted(),
                              " samples deleted, expected ", scratch_count_));
  }

  absl::Status ImportScratch() {
    grpc::ClientContext context;
    SetDeadline(context);
    v1::Gallery gallery;
    auto writer = stub_->ImportGallery(&context, &gallery);
    bool open = true;
    for (size_t i = 0; open && i < last_export_.size(); ++i) {
      v1::ImportGalleryRequest request;
      if (i == 0) request.set_name(scratch_);
      *request.mutable_chunk() = last_export_[i];
      open = writer->Write(request);
    }
    writer->WritesDone();
    const grpc::Status status = writer->Finish();
    if (!status.ok()) return FromGrpcStatus(status);
    const uint64_t expected = last_export_.front().header().sample_count();
    scratch_exists_ = true;
    scratch_count_ = gallery.sample_count();
    return Check(gallery.name() == scratch_ && gallery.sample_count() == expected,
                 absl::StrCat("ImportGallery: ", gallery.name(), " with ", gallery.sample_count(),
                              " samples, expected ", scratch_, " with ", expected));
  }

  const Pool& pool_;
  const ClientSettings settings_;
  std::mt19937 rng_;
  const std::string name_, scratch_;
  std::shared_ptr<grpc::Channel> channel_;
  std::unique_ptr<v1::ShapeId::Stub> stub_;

  std::string spec_;       // the gallery's canonical spec
  size_t dimension_ = 0;   // and descriptor length
  std::deque<Held> held_;  // the gallery's samples, oldest first
  uint64_t next_id_;
  bool scratch_exists_ = false;
  uint64_t scratch_count_ = 0;
  bool train_scratch_next_ = false;
  std::deque<Kind> pending_;
  int removals_ = 0;
  int recreations_ = 0;
  std::vector<v1::GalleryExportChunk> last_export_;
  std::map<size_t, std::vector<float>> descriptors_;  // pool cloud -> first answer
};

// ----------------------------------------------------------------------------- windows

struct Window {
  double t0 = 0, t1 = 0;  // seconds since the load started
  int64_t requests = 0;
  int64_t errors = 0;
  double p50_ms = 0, p99_ms = 0;
  int64_t kind_n[kNumKinds] = {};
  double kind_p50_ms[kNumKinds] = {}, kind_p99_ms[kNumKinds] = {};
  int64_t rss_kib = 0;      // server VmRSS at the window's end
  double server_cores = 0;  // server CPU seconds per second over the window
  double load1 = 0;         // 1-minute load average at the window's end
};

std::string WindowJson(int index, const Window& w) {
  std::vector<std::string> kinds;
  for (int k = 0; k < kNumKinds; ++k) {
    kinds.push_back(absl::StrFormat(R"("%s":{"n":%d,"p50_ms":%.3f,"p99_ms":%.3f})", kKindNames[k],
                                    w.kind_n[k], w.kind_p50_ms[k], w.kind_p99_ms[k]));
  }
  const double span = w.t1 - w.t0;
  return absl::StrFormat(
      R"({"window":%d,"t_start_s":%.2f,"t_end_s":%.2f,"requests":%d,"per_second":%.1f,)"
      R"("errors":%d,"p50_ms":%.3f,"p99_ms":%.3f,"rss_kib":%d,"server_cores":%.2f,)"
      R"("loadavg_1m":%.2f,"kinds":{%s}})",
      index, w.t0, w.t1, w.requests, span > 0 ? w.requests / span : 0.0, w.errors, w.p50_ms,
      w.p99_ms, w.rss_kib, w.server_cores, w.load1, absl::StrJoin(kinds, ","));
}

// ----------------------------------------------------------------------------- the plot

double NiceStep(double range, int ticks) {
  const double raw = range / ticks;
  const double power = std::pow(10.0, std::floor(std::log10(raw)));
  const double f = raw / power;
  return (f <= 1 ? 1 : f <= 2 ? 2 : f <= 5 ? 5 : 10) * power;
}

std::string Escape(const std::string& text) {
  std::string out;
  for (char c : text) {
    if (c == '<') {
      out += "&lt;";
    } else if (c == '>') {
      out += "&gt;";
    } else if (c == '&') {
      out += "&amp;";
    } else {
      out += c;
    }
  }
  return out;
}

// One panel: a frame, x ticks over [0, x_max], y ticks, labels. `y_of` maps a value to pixels.
struct Panel {
  double left, top, width, height, x_max;
  double X(double t) const { return left + width * t / x_max; }
};

void XAxis(std::string& svg, const Panel& p) {
  const double step = NiceStep(p.x_max, 8);
  for (double t = 0; t <= p.x_max + 1e-9; t += step) {
    absl::StrAppendFormat(&svg,
                          R"(<line x1="%.1f" y1="%.1f" x2="%.1f" y2="%.1f" stroke="#ddd"/>)"
                          R"(<text x="%.1f" y="%.1f" text-anchor="middle">%g</text>)"
                          "\n",
                          p.X(t), p.top, p.X(t), p.top + p.height, p.X(t), p.top + p.height + 16,
                          t);
  }
  absl::StrAppendFormat(&svg,
                        R"(<text x="%.1f" y="%.1f" text-anchor="middle">%s</text>)"
                        "\n",
                        p.left + p.width / 2, p.top + p.height + 36,
                        "time since the load started (s)");
}

void YLabel(std::string& svg, const Panel& p, const std::string& label) {
  const double cy = p.top + p.height / 2;
  absl::StrAppendFormat(&svg,
                        R"(<text x="%.1f" y="%.1f" text-anchor="middle" )"
                        R"svg(transform="rotate(-90 %.1f %.1f)">%s</text>)svg"
                        "\n",
                        p.left - 58, cy, p.left - 58, cy, Escape(label));
}

void Frame(std::string& svg, const Panel& p, const std::string& title) {
  absl::StrAppendFormat(&svg,
                        R"(<rect x="%.1f" y="%.1f" width="%.1f" height="%.1f" fill="none" )"
                        R"(stroke="#333"/>)"
                        "\n"
                        R"(<text x="%.1f" y="%.1f" font-weight="bold">%s</text>)"
                        "\n",
                        p.left, p.top, p.width, p.height, p.left, p.top - 8, Escape(title));
}

void WarmupLine(std::string& svg, const Panel& p, double warmup_end) {
  absl::StrAppendFormat(&svg,
                        R"(<line x1="%.1f" y1="%.1f" x2="%.1f" y2="%.1f" stroke="#888" )"
                        R"(stroke-dasharray="4 3"/>)"
                        R"(<text x="%.1f" y="%.1f" fill="#666">end of warm-up</text>)"
                        "\n",
                        p.X(warmup_end), p.top, p.X(warmup_end), p.top + p.height,
                        p.X(warmup_end) + 4, p.top + 14);
}

template <typename YOf>
void Polyline(std::string& svg, const Panel& p, const std::vector<Window>& windows,
              const char* colour, const YOf& y_of, const std::string& first_point = "") {
  std::string points = first_point;
  for (const Window& w : windows) {
    if (w.requests == 0 && w.rss_kib == 0) continue;
    const double y = y_of(w);
    if (!std::isfinite(y)) continue;
    absl::StrAppendFormat(&points, "%.1f,%.1f ", p.X(w.t1), y);
  }
  absl::StrAppendFormat(&svg,
                        R"(<polyline points="%s" fill="none" stroke="%s" stroke-width="1.8"/>)"
                        "\n",
                        points, colour);
}

void Legend(std::string& svg, const Panel& p, int row, const char* colour,
            const std::string& text) {
  const double x = p.left + p.width - 190, y = p.top + 18 + 18 * row;
  absl::StrAppendFormat(&svg, R"(<rect x="%.1f" y="%.1f" width="180" height="18" fill="white"/>)",
                        x - 4, y - 13);
  absl::StrAppendFormat(&svg,
                        R"(<line x1="%.1f" y1="%.1f" x2="%.1f" y2="%.1f" stroke="%s" )"
                        R"(stroke-width="2.5"/><text x="%.1f" y="%.1f">%s</text>)"
                        "\n",
                        x, y - 4, x + 24, y - 4, colour, x + 30, y, Escape(text));
}

// Two panels over time: p50 and p99 latency of all requests per window (log scale), and the
// server's resident memory with the pass band (+max_growth % over the value after warm-up).
std::string Plot(const std::vector<Window>& windows, double warmup_end, int64_t rss_start_kib,
                 int64_t rss_warm_kib, double max_growth_percent, const std::string& title,
                 const std::string& subtitle) {
  const double width = 960, height = 700;
  const double x_max = windows.empty() ? 1 : windows.back().t1;
  std::string svg = absl::StrFormat(
      R"(<svg xmlns="http://www.w3.org/2000/svg" width="%.0f" height="%.0f" )"
      R"(viewBox="0 0 %.0f %.0f" font-family="sans-serif" font-size="12">)"
      "\n"
      R"(<rect width="100%%" height="100%%" fill="white"/>)"
      "\n"
      R"(<text x="%.0f" y="26" text-anchor="middle" font-size="16" font-weight="bold">%s</text>)"
      "\n"
      R"(<text x="%.0f" y="46" text-anchor="middle" fill="#444">%s</text>)"
      "\n",
      width, height, width, height, width / 2, Escape(title), width / 2, Escape(subtitle));

  // Latency, log scale over whole decades.
  const Panel lat{90, 90, width - 130, 230, x_max};
  double lo = 1e300, hi = 0;
  for (const Window& w : windows) {
    if (w.requests == 0) continue;
    lo = std::min(lo, w.p50_ms);
    hi = std::max(hi, w.p99_ms);
  }
  if (hi <= 0) lo = 0.1, hi = 1;
  const double d_lo = std::floor(std::log10(std::max(lo, 1e-3)));
  const double d_hi = std::max(d_lo + 1, std::ceil(std::log10(hi)));
  auto lat_y = [&](double ms) {
    return lat.top + lat.height * (1 - (std::log10(ms) - d_lo) / (d_hi - d_lo));
  };
  Frame(svg, lat, "Latency of all requests per window");
  for (double d = d_lo; d <= d_hi + 1e-9; d += 1) {
    for (int m : {1, 2, 5}) {
      const double v = m * std::pow(10.0, d);
      if (std::log10(v) > d_hi + 1e-9) break;
      absl::StrAppendFormat(&svg, R"(<line x1="%.1f" y1="%.1f" x2="%.1f" y2="%.1f" stroke="%s"/>)",
                            lat.left, lat_y(v), lat.left + lat.width, lat_y(v),
                            m == 1 ? "#ccc" : "#eee");
      absl::StrAppendFormat(&svg,
                            R"(<text x="%.1f" y="%.1f" text-anchor="end">%g</text>)"
                            "\n",
                            lat.left - 6, lat_y(v) + 4, v);
    }
  }
  XAxis(svg, lat);
  YLabel(svg, lat, "latency (ms, log scale)");
  WarmupLine(svg, lat, warmup_end);
  Polyline(svg, lat, windows, "#d62728",
           [&](const Window& w) { return w.requests ? lat_y(w.p99_ms) : NAN; });
  Polyline(svg, lat, windows, "#1f77b4",
           [&](const Window& w) { return w.requests ? lat_y(w.p50_ms) : NAN; });
  Legend(svg, lat, 0, "#d62728", "p99");
  Legend(svg, lat, 1, "#1f77b4", "p50");

  // Resident memory, linear from 0.
  const Panel mem{90, 410, width - 130, 230, x_max};
  double rss_max = static_cast<double>(rss_warm_kib) * (1 + max_growth_percent / 100);
  for (const Window& w : windows) rss_max = std::max(rss_max, static_cast<double>(w.rss_kib));
  rss_max /= 1024;
  const double step = NiceStep(std::max(rss_max, 1.0), 5);
  const double top_mib = std::ceil(rss_max * 1.1 / step) * step;
  auto mem_y = [&](double mib) { return mem.top + mem.height * (1 - mib / top_mib); };
  Frame(svg, mem, "Resident memory of shapeid-server (VmRSS) at each window's end");
  for (double v = 0; v <= top_mib + 1e-9; v += step) {
    absl::StrAppendFormat(&svg,
                          R"(<line x1="%.1f" y1="%.1f" x2="%.1f" y2="%.1f" stroke="#ddd"/>)"
                          R"(<text x="%.1f" y="%.1f" text-anchor="end">%g</text>)"
                          "\n",
                          mem.left, mem_y(v), mem.left + mem.width, mem_y(v), mem.left - 6,
                          mem_y(v) + 4, v);
  }
  if (rss_warm_kib > 0) {
    const double base = rss_warm_kib / 1024.0;
    const double limit = base * (1 + max_growth_percent / 100);
    absl::StrAppendFormat(&svg,
                          R"(<rect x="%.1f" y="%.1f" width="%.1f" height="%.1f" )"
                          R"(fill="#2ca02c" fill-opacity="0.12"/>)"
                          R"(<text x="%.1f" y="%.1f" fill="#2a7a2a">pass band: up to +%g %% )"
                          R"(over %.1f MiB (after warm-up)</text>)"
                          "\n",
                          mem.X(warmup_end), mem_y(limit), mem.X(x_max) - mem.X(warmup_end),
                          std::max(1.0, mem_y(base) - mem_y(limit)), mem.X(warmup_end) + 4,
                          mem_y(limit) - 4, max_growth_percent, base);
  }
  XAxis(svg, mem);
  YLabel(svg, mem, "server RSS (MiB)");
  WarmupLine(svg, mem, warmup_end);
  Polyline(
      svg, mem, windows, "#2ca02c",
      [&](const Window& w) { return w.rss_kib ? mem_y(w.rss_kib / 1024.0) : NAN; },
      rss_start_kib > 0 ? absl::StrFormat("%.1f,%.1f ", mem.X(0), mem_y(rss_start_kib / 1024.0))
                        : "");
  svg += "</svg>\n";
  return svg;
}

// ----------------------------------------------------------------------------- main

std::string CpuModel() {
  std::ifstream in("/proc/cpuinfo");
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind("model name", 0) == 0 && line.find(':') != std::string::npos) {
      return line.substr(line.find(':') + 2);
    }
  }
  return "unknown";
}

int Run(int argc, char** argv) {
  CLI::App app{"soak_bench: a long mixed load on a real shapeid-server, watching memory"};
  int clients = 32;
  double seconds = 600;
  double window_seconds = 10;
  double warmup_seconds = 60;
  double max_growth = 5;
  bool skip_memory_check = false;
  ClientSettings settings;
  double deadline_seconds = 30;
  size_t per_class = 8;
  std::string out = "soak_bench.jsonl";
  std::string svg_path = "soak_bench.svg";
  std::string server_path = SHAPEID_SERVER_PATH;
  std::string data_dir = fs::path(SHAPEID_SOURCE_DIR) / ".." / "shared" / "data" / "modelnet10";
  std::string scratch_parent = fs::temp_directory_path().string();
  app.add_option("--clients", clients, "client threads, each with its own channel")
      ->capture_default_str();
  app.add_option("--seconds", seconds, "duration of the load")->capture_default_str();
  app.add_option("--window_seconds", window_seconds, "sampling window")->capture_default_str();
  app.add_option("--warmup_seconds", warmup_seconds,
                 "warm-up before the memory reference (at most a fifth of --seconds)")
      ->capture_default_str();
  app.add_option("--max_rss_growth_percent", max_growth,
                 "largest RSS growth from the end of the warm-up to the end that passes")
      ->capture_default_str();
  app.add_flag("--skip_memory_check", skip_memory_check,
               "do not fail on RSS growth (for runs too short to reach a steady state)");
  app.add_option("--gallery_samples", settings.gallery_samples,
                 "bound of each client's gallery (trimmed to 3/4 of it once passed)")
      ->capture_default_str();
  app.add_option("--deadline_seconds", deadline_seconds, "deadline of every call")
      ->capture_default_str();
  app.add_option("--per_class", per_class,
                 "train clouds per class (test clouds: half as many) in the clouds the clients "
                 "draw from")
      ->capture_default_str();
  app.add_option("--out", out, "JSON-lines file of the windows (empty: none)")
      ->capture_default_str();
  app.add_option("--svg", svg_path, "SVG plot of latency and RSS over time (empty: none)")
      ->capture_default_str();
  app.add_option("--server", server_path, "the shapeid-server binary")->capture_default_str();
  app.add_option("--data", data_dir, "ModelNet10 folder (synthetic clouds where absent)")
      ->capture_default_str();
  app.add_option("--tmp", scratch_parent, "where the server's temporary data directory goes")
      ->capture_default_str();
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 2;
  }
  if (clients < 1 || clients > 1000 || !(seconds > 0) || !(window_seconds > 0) ||
      warmup_seconds < 0 || settings.gallery_samples < 8 || !(deadline_seconds > 0) ||
      per_class < 2) {
    std::fprintf(stderr,
                 "soak_bench: --clients 1..1000, --seconds, --window_seconds and "
                 "--deadline_seconds > 0, --warmup_seconds >= 0, --gallery_samples >= 8, "
                 "--per_class >= 2\n");
    return 2;
  }
  settings.deadline = absl::Seconds(deadline_seconds);
  const double warmup = std::min(warmup_seconds, seconds / 5);

  const Pool pool = LoadPool(data_dir, per_class);
  std::string tmp = absl::StrCat(scratch_parent, "/shapeid_soak_XXXXXX");
  if (mkdtemp(tmp.data()) == nullptr) {
    std::fprintf(stderr, "soak_bench: cannot make a directory under %s\n", scratch_parent.c_str());
    return 1;
  }
  const std::string stderr_path = tmp + "/server.stderr";
  const std::string load_before = LoadAverages();
  std::printf("machine: %u hardware threads, %s; load average before: %s\n",
              std::thread::hardware_concurrency(), CpuModel().c_str(), load_before.c_str());
  std::printf("clouds: %s\n", pool.source.c_str());
  ChildServer server;
  if (absl::Status s = server.Start(
          server_path,
          {"--listen=127.0.0.1:0", "--data_dir=" + tmp + "/data", "--shutdown_grace_seconds=10"},
          stderr_path);
      !s.ok()) {
    std::fprintf(stderr, "soak_bench: %s\n%s", std::string(s.message()).c_str(),
                 TailOfFile(stderr_path, 2000).c_str());
    return 1;
  }
  {
    ClientOptions options;
    options.target = server.address();
    options.max_attempts = 1;
    options.deadline = absl::Seconds(2);
    absl::Status health = absl::UnavailableError("not asked");
    auto health_client = Client::Connect(options);
    const auto until = Clock::now() + std::chrono::seconds(30);
    while (health_client.ok() && !(health = (*health_client)->CheckHealth()).ok() &&
           Clock::now() < until) {
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
    if (!health.ok()) {
      std::fprintf(stderr, "soak_bench: the server is not SERVING: %s\n",
                   health.ToString().c_str());
      return 1;
    }
  }
  std::printf("server: %s, pid %d, %s, data directory %s/data (SQLite), health SERVING\n",
              server_path.c_str(), static_cast<int>(server.pid()), server.address().c_str(),
              tmp.c_str());
  std::printf(
      "load: %d clients x %.0f s, windows of %g s, warm-up %g s, galleries of at "
      "most %zu samples, deadline %.0f s per call\n",
      clients, seconds, window_seconds, warmup, settings.gallery_samples, deadline_seconds);
  std::fflush(stdout);

  // Set-up (galleries, first samples) in parallel, then the timed load.
  Recorder recorder(clients);
  ErrorLog errors;
  std::vector<std::unique_ptr<SoakClient>> soakers;
  for (int c = 0; c < clients; ++c) {
    soakers.push_back(std::make_unique<SoakClient>(c, server.address(), pool, settings));
  }
  std::atomic<int> ready{0};
  std::atomic<bool> go{false}, stop{false};
  Clock::time_point start, end;
  std::vector<std::thread> threads;
  for (int c = 0; c < clients; ++c) {
    threads.emplace_back([&, c] {
      SoakClient& client = *soakers[static_cast<size_t>(c)];
      if (absl::Status s = client.SetUp(); !s.ok()) {
        errors.Add(0, c, kCreateGallery, s);
        recorder.Record(c, kCreateGallery, 0, false);
        (void)client.Resync();
      }
      ++ready;
      while (!go.load(std::memory_order_acquire)) {
        std::this_thread::sleep_for(std::chrono::milliseconds(1));
      }
      while (!stop.load(std::memory_order_relaxed) && Clock::now() < end) {
        const Kind kind = client.Next();
        const auto t0 = Clock::now();
        const absl::Status s = client.Run(kind);
        const int64_t ns =
            std::chrono::duration_cast<std::chrono::nanoseconds>(Clock::now() - t0).count();
        recorder.Record(c, kind, ns, s.ok());
        if (!s.ok()) {
          errors.Add(SecondsSince(start), c, kind, s);
          if (!client.Resync().ok()) std::this_thread::sleep_for(std::chrono::milliseconds(100));
        }
      }
    });
  }
  while (ready.load() < clients) std::this_thread::sleep_for(std::chrono::milliseconds(5));
  const int64_t setup_errors = errors.count();
  recorder.Take();  // set-up calls are not part of the windows
  start = Clock::now();
  end = start + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(seconds));
  go.store(true, std::memory_order_release);

  std::vector<Window> windows;
  std::vector<int64_t> all_ns;
  int64_t kind_total[kNumKinds] = {};
  std::vector<int64_t> kind_all[kNumKinds];
  double cpu_before = absl::ToDoubleSeconds(server.CpuTime());
  const int64_t rss_start = (server.ResidentBytes() / 1024);  // galleries set up, no load yet
  int server_died = -1;
  std::printf("\n%8s %9s %8s %7s %9s %9s %9s %6s %6s\n", "t (s)", "requests", "req/s", "errors",
              "p50 ms", "p99 ms", "RSS MiB", "cores", "load");
  for (int index = 0; !stop.load(); ++index) {
    Window w;
    w.t0 = index * window_seconds;
    w.t1 = std::min(seconds, (index + 1) * window_seconds);
    std::this_thread::sleep_until(
        start + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(w.t1)));
    Tally tally = recorder.Take();
    std::vector<int64_t> window_ns;
    for (int k = 0; k < kNumKinds; ++k) {
      w.kind_n[k] = static_cast<int64_t>(tally.ns[k].size());
      kind_total[k] += w.kind_n[k];
      w.kind_p50_ms[k] = QuantileMs(tally.ns[k], 0.50);
      w.kind_p99_ms[k] = QuantileMs(tally.ns[k], 0.99);
      window_ns.insert(window_ns.end(), tally.ns[k].begin(), tally.ns[k].end());
      kind_all[k].insert(kind_all[k].end(), tally.ns[k].begin(), tally.ns[k].end());
    }
    w.requests = static_cast<int64_t>(window_ns.size());
    w.errors = tally.errors;
    w.p50_ms = QuantileMs(window_ns, 0.50);
    w.p99_ms = QuantileMs(window_ns, 0.99);
    all_ns.insert(all_ns.end(), window_ns.begin(), window_ns.end());
    w.rss_kib = (server.ResidentBytes() / 1024);
    const double cpu = absl::ToDoubleSeconds(server.CpuTime());
    w.server_cores = (cpu - cpu_before) / (w.t1 - w.t0);
    cpu_before = cpu;
    w.load1 = LoadAverage1();
    windows.push_back(w);
    std::printf("%8.0f %9lld %8.0f %7lld %9.2f %9.2f %9.1f %6.2f %6.2f\n", w.t1,
                static_cast<long long>(w.requests), w.requests / (w.t1 - w.t0),
                static_cast<long long>(w.errors), w.p50_ms, w.p99_ms, w.rss_kib / 1024.0,
                w.server_cores, w.load1);
    std::fflush(stdout);
    if ((server_died = server.Poll()) >= 0) {
      std::printf("the server exited (status %d) during the load\n", server_died);
      stop = true;
    }
    if (w.t1 >= seconds) stop = true;
  }
  for (std::thread& t : threads) t.join();
  // Calls in flight at the end: counted in the totals, not in any window.
  Tally drained = recorder.Take();
  int64_t drained_n = 0;
  for (int k = 0; k < kNumKinds; ++k) {
    drained_n += static_cast<int64_t>(drained.ns[k].size());
    kind_total[k] += static_cast<int64_t>(drained.ns[k].size());
    kind_all[k].insert(kind_all[k].end(), drained.ns[k].begin(), drained.ns[k].end());
    all_ns.insert(all_ns.end(), drained.ns[k].begin(), drained.ns[k].end());
  }
  const double elapsed = SecondsSince(start);
  const std::string load_after = LoadAverages();

  // The server must still answer health checks, then stop cleanly on SIGTERM.
  absl::Status health_after = absl::UnavailableError("the server exited");
  if (server_died < 0) {
    ClientOptions options;
    options.target = server.address();
    options.max_attempts = 1;
    options.deadline = absl::Seconds(5);
    auto health_client = Client::Connect(options);
    health_after = health_client.ok() ? (*health_client)->CheckHealth() : health_client.status();
  }
  soakers.clear();  // close the clients' channels before the server stops
  const int exit_status = server.Terminate(absl::Seconds(30));

  // ------------------------------------------------------------------ report
  int64_t rss_warm = 0, rss_end = 0, rss_peak = 0;
  double warmup_end = 0;
  for (const Window& w : windows) {
    if (rss_warm == 0 && w.t1 >= warmup - 1e-9 && w.rss_kib > 0) {
      rss_warm = w.rss_kib;
      warmup_end = w.t1;
    }
    if (rss_warm > 0) rss_peak = std::max(rss_peak, w.rss_kib);
  }
  if (!windows.empty()) rss_end = windows.back().rss_kib;
  const double growth = rss_warm > 0 ? 100.0 * (rss_end - rss_warm) / rss_warm : 0;
  const int64_t total = static_cast<int64_t>(all_ns.size());
  const int64_t error_count = errors.count();
  double mean_load = 0, mean_cores = 0;
  for (const Window& w : windows) {
    mean_load += w.load1 / static_cast<double>(windows.size());
    mean_cores += w.server_cores / static_cast<double>(windows.size());
  }
  const double p50 = QuantileMs(all_ns, 0.50), p99 = QuantileMs(all_ns, 0.99);

  std::printf("\nBy kind over the run:\n  %-16s %9s %8s %9s %9s\n", "", "requests", "req/s",
              "p50 ms", "p99 ms");
  for (int k = 0; k < kNumKinds; ++k) {
    std::printf("  %-16s %9lld %8.1f %9.2f %9.2f\n", kKindNames[k],
                static_cast<long long>(kind_total[k]), kind_total[k] / elapsed,
                QuantileMs(kind_all[k], 0.50), QuantileMs(kind_all[k], 0.99));
  }
  std::printf("\nSummary\n");
  std::printf("  requests          %lld in %.1f s (%lld in flight at the end counted), %.1f /s\n",
              static_cast<long long>(total), elapsed, static_cast<long long>(drained_n),
              total / elapsed);
  std::printf("  errors            %lld (%lld during set-up)\n",
              static_cast<long long>(error_count), static_cast<long long>(setup_errors));
  for (const std::string& e : errors.first()) std::printf("    %s\n", e.c_str());
  if (error_count > static_cast<int64_t>(errors.first().size())) {
    std::printf("    ... and %lld more\n",
                static_cast<long long>(error_count - static_cast<int64_t>(errors.first().size())));
  }
  std::printf("  latency           p50 %.2f ms, p99 %.2f ms (all requests)\n", p50, p99);
  std::printf("  server RSS        %.1f MiB at the start of the load (galleries set up)\n",
              rss_start / 1024.0);
  std::printf(
      "  server RSS        %.1f MiB after warm-up (at %.0f s), %.1f MiB at the end, "
      "peak %.1f MiB after warm-up; growth %+.2f %%\n",
      rss_warm / 1024.0, warmup_end, rss_end / 1024.0, rss_peak / 1024.0, growth);
  std::printf("  server CPU        %.2f cores on average\n", mean_cores);
  std::printf("  load average      before %s; mean 1-min during %.2f; after %s\n",
              load_before.c_str(), mean_load, load_after.c_str());
  std::printf("  health at the end %s\n",
              health_after.ok() ? "SERVING" : health_after.ToString().c_str());
  std::printf("  SIGTERM           exit status %d%s\n", exit_status,
              exit_status == -1 ? " (still running after 30 s; killed)" : "");

  const bool memory_ok = rss_warm > 0 && growth < max_growth;
  bool pass = error_count == 0 && server_died < 0 && health_after.ok() && exit_status == 0;
  if (skip_memory_check) {
    std::printf(
        "  memory check      DISABLED (--skip_memory_check): growth reported, not judged\n");
  } else {
    std::printf("  memory check      growth %+.2f %% %s %.1f %%\n", growth,
                memory_ok ? "<" : ">=", max_growth);
    pass = pass && memory_ok;
  }

  const std::string subtitle = absl::StrFormat(
      "%d clients, %.0f s, %lld requests (%.0f /s), %lld errors; p50 %.2f ms, p99 %.2f ms; "
      "RSS %.1f -> %.1f MiB (%+.2f %%); load %.2f on %u threads",
      clients, seconds, static_cast<long long>(total), total / elapsed,
      static_cast<long long>(error_count), p50, p99, rss_warm / 1024.0, rss_end / 1024.0, growth,
      mean_load, std::thread::hardware_concurrency());
  bool written = true;
  if (!out.empty()) {
    std::ofstream file(out);
    for (size_t i = 0; i < windows.size(); ++i) {
      file << WindowJson(static_cast<int>(i), windows[i]) << "\n";
    }
    written = written && file.good();
    std::printf("  windows           %s\n", out.c_str());
  }
  if (!svg_path.empty()) {
    std::ofstream file(svg_path);
    file << Plot(windows, warmup_end, rss_start, rss_warm, max_growth, "shapeid-server soak test",
                 subtitle);
    written = written && file.good();
    std::printf("  plot              %s\n", svg_path.c_str());
  }
  if (!written) {
    std::printf("  could not write %s / %s\n", out.c_str(), svg_path.c_str());
    pass = false;
  }
  if (!pass) std::printf("server stderr (tail):\n%s\n", TailOfFile(stderr_path, 3000).c_str());
  std::printf(
      "JSON {\"bench\":\"soak\",\"clients\":%d,\"seconds\":%.1f,\"requests\":%lld,"
      "\"per_second\":%.1f,\"errors\":%lld,\"p50_ms\":%.3f,\"p99_ms\":%.3f,"
      "\"rss_start_kib\":%lld,\"rss_warm_kib\":%lld,\"rss_end_kib\":%lld,\"rss_peak_kib\":%lld,"
      "\"rss_growth_percent\":%.3f,\"memory_checked\":%s,\"server_exit\":%d,"
      "\"loadavg_before\":\"%s\",\"loadavg_mean_1m\":%.2f,\"loadavg_after\":\"%s\","
      "\"pass\":%s}\n",
      clients, elapsed, static_cast<long long>(total), total / elapsed,
      static_cast<long long>(error_count), p50, p99, static_cast<long long>(rss_start),
      static_cast<long long>(rss_warm), static_cast<long long>(rss_end),
      static_cast<long long>(rss_peak), growth, skip_memory_check ? "false" : "true", exit_status,
      load_before.c_str(), mean_load, load_after.c_str(), pass ? "true" : "false");
  std::printf("%s\n", pass ? "PASS" : "FAIL");
  std::error_code ignored;
  fs::remove_all(tmp, ignored);
  return pass ? 0 : 1;
}

}  // namespace
}  // namespace shapeid

int main(int argc, char** argv) { return shapeid::Run(argc, argv); }
