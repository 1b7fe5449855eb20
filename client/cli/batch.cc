#include "client/cli/batch.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <filesystem>
#include <mutex>
#include <optional>
#include <random>
#include <utility>

#include "absl/strings/str_cat.h"
#include "client/cli/describe_command.h"
#include "client/cli/input_files.h"
#include "core/io/point_cloud_reader.h"

namespace shapeid {
namespace {

using Clock = std::chrono::steady_clock;

double SecondsSince(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

// A trained file's source: its absolute path, so that it names the file from any directory
// (standard input has none).
std::string SourceOf(const std::string& path) {
  if (path == "-") return "";
  std::error_code error;
  const std::filesystem::path absolute = std::filesystem::absolute(path, error);
  return error ? path : absolute.lexically_normal().string();
}

// Shared state of one batch: the first batch-stopping error, and failures in arrival order.
class BatchState {
 public:
  BatchState(Progress& progress, std::FILE* err) : progress_(progress), err_(err) {}

  bool stopped() const { return stopped_.load(std::memory_order_relaxed); }

  // Records a batch-stopping error (the first one wins) and tells the workers to stop.
  void Stop(const absl::Status& status) {
    std::lock_guard<std::mutex> lock(mu_);
    if (stop_status_.ok()) stop_status_ = status;
    stopped_.store(true, std::memory_order_relaxed);
  }

  // Records and prints one failed file.
  void Fail(const std::string& path, const absl::Status& status) {
    {
      std::lock_guard<std::mutex> lock(mu_);
      failed_.push_back({path, status});
    }
    const std::string line = FileErrorLine(path, status);
    progress_.Interrupt([&] { WriteAll(err_, line); });
  }

  absl::Status stop_status() {
    std::lock_guard<std::mutex> lock(mu_);
    return stop_status_;
  }
  std::vector<FailedInput> TakeFailed() {
    std::lock_guard<std::mutex> lock(mu_);
    std::vector<FailedInput> failed = std::move(failed_);
    // Parallel workers finish out of order; sorted output is reproducible.
    std::sort(failed.begin(), failed.end(),
              [](const FailedInput& a, const FailedInput& b) { return a.path < b.path; });
    return failed;
  }

 private:
  Progress& progress_;
  std::FILE* const err_;
  std::atomic<bool> stopped_{false};
  std::mutex mu_;
  absl::Status stop_status_;
  std::vector<FailedInput> failed_;
};

// A client-chosen sample id: random, in [1, 2^62). With an id on every sample the client
// library may repeat a Train stream that a replica dropped (on another replica) without ever
// adding a sample twice; letting the server assign ids would make the stream unrepeatable.
// Two random ids collide with probability about n^2 / 2^63: never, in practice, and then the
// stream fails ALREADY_EXISTS rather than mix two samples.
uint64_t RandomSampleId() {
  static std::mutex mu;
  static std::mt19937_64 engine(std::random_device{}());
  std::lock_guard<std::mutex> lock(mu);
  return (engine() >> 2) | 1;
}

}  // namespace

TrainOutcome TrainFiles(Client& client, const std::string& gallery,
                        const std::vector<LabeledFile>& files, const BatchOptions& options,
                        Progress& progress, std::FILE* err) {
  const Clock::time_point start = Clock::now();
  const size_t batch_size = std::max<size_t>(options.train_batch, 1);
  const size_t batches = (files.size() + batch_size - 1) / batch_size;
  BatchState state(progress, err);
  std::atomic<uint64_t> trained{0};
  std::atomic<uint64_t> gallery_count{0};
  std::mutex trained_mu;
  std::vector<std::pair<size_t, uint64_t>> trained_ids;  // (index into `files`, sample id)
  const auto record = [&](size_t file, uint64_t id) {
    std::lock_guard<std::mutex> lock(trained_mu);
    trained_ids.emplace_back(file, id);
  };

  const auto send = [&](const std::vector<TrainSample>& samples) {
    Client::TrainOptions train;
    train.sensor_frame = options.sensor_frame;
    absl::StatusOr<v1::TrainResponse> response = client.Train(gallery, samples, train);
    if (response.ok()) {
      trained += static_cast<uint64_t>(response->sample_ids_size());
      // Streams commit in any order; the largest count seen is the latest.
      uint64_t seen = gallery_count.load();
      while (seen < response->gallery_sample_count() &&
             !gallery_count.compare_exchange_weak(seen, response->gallery_sample_count())) {
      }
    }
    return response.status();
  };

  ParallelFor(
      batches, options.jobs,
      [&](size_t b) {
        const size_t begin = b * batch_size;
        const size_t end = std::min(files.size(), begin + batch_size);
        std::vector<PointCloud> clouds;
        std::vector<size_t> owners;  // index into `files` of each cloud
        clouds.reserve(end - begin);
        size_t read_failures = 0;
        for (size_t i = begin; i < end; ++i) {
          absl::StatusOr<ReadResult> read = ReadInputCloud(files[i].path, options.read);
          if (!read.ok()) {
            state.Fail(files[i].path, read.status());
            ++read_failures;
            continue;
          }
          clouds.push_back(std::move(read->cloud));
          owners.push_back(i);
        }
        std::vector<TrainSample> samples;
        for (size_t j = 0; j < clouds.size(); ++j) {
          samples.push_back({files[owners[j]].label, RandomSampleId(), &clouds[j],
                             SourceOf(files[owners[j]].path), options.metadata});
        }
        size_t failures = read_failures;
        if (!samples.empty()) {
          const absl::Status status = send(samples);
          if (status.ok()) {
            for (size_t j = 0; j < samples.size(); ++j) record(owners[j], samples[j].sample_id);
          } else if (StopsBatch(status)) {
            state.Stop(status);
          } else if (!status.ok() && samples.size() == 1) {
            state.Fail(files[owners[0]].path, status);
            ++failures;
          } else if (!status.ok()) {
            // One bad cloud refuses the whole stream; find it by sending one per stream.
            for (size_t j = 0; j < samples.size() && !state.stopped(); ++j) {
              const absl::Status single = send({samples[j]});
              if (single.ok()) {
                record(owners[j], samples[j].sample_id);
                continue;
              }
              if (StopsBatch(single)) {
                state.Stop(single);
              } else {
                state.Fail(files[owners[j]].path, single);
                ++failures;
              }
            }
          }
        }
        progress.Advance(end - begin, failures);
      },
      [&] { return state.stopped(); });

  TrainOutcome outcome;
  std::sort(trained_ids.begin(), trained_ids.end());
  for (const auto& [file, id] : trained_ids) {
    outcome.files.push_back({files[file].path, files[file].label, id});
  }
  outcome.trained = trained.load();
  outcome.gallery_sample_count = gallery_count.load();
  outcome.failed = state.TakeFailed();
  outcome.stopped = state.stop_status();
  outcome.seconds = SecondsSince(start);
  return outcome;
}

ClassifyOutcome ClassifyFiles(
    Client& client, const std::string& gallery, const Client::ClassifyOptions& call,
    const std::vector<std::string>& paths, const BatchOptions& options, Progress& progress,
    const std::function<void(size_t, const v1::ClassifyResponse&, double)>& on_result,
    const std::function<void(size_t, const absl::Status&)>& on_failure) {
  const Clock::time_point start = Clock::now();
  BatchState state(progress, nullptr);
  std::vector<FailedInput> failed;

  // Results wait in `slots` until every earlier file is out, so output follows input order.
  struct Slot {
    bool done = false;
    absl::Status status;
    v1::ClassifyResponse response;
    double seconds = 0;
  };
  std::vector<Slot> slots(paths.size());
  std::mutex emit_mu;
  size_t next_out = 0;
  size_t classified = 0;

  ParallelFor(
      paths.size(), options.jobs,
      [&](size_t i) {
        Slot slot;
        absl::StatusOr<ReadResult> read = ReadInputCloud(paths[i], options.read);
        if (read.ok()) {
          const Clock::time_point call_start = Clock::now();
          absl::StatusOr<v1::ClassifyResponse> response =
              client.Classify(gallery, read->cloud, call);
          slot.seconds = SecondsSince(call_start);
          if (response.ok()) {
            slot.response = std::move(response).value();
          } else if (StopsBatch(response.status())) {
            state.Stop(response.status());
            return;  // not emitted: the batch ends here
          } else {
            slot.status = response.status();
          }
        } else {
          slot.status = read.status();
        }
        slot.done = true;
        std::lock_guard<std::mutex> lock(emit_mu);
        slots[i] = std::move(slot);
        while (next_out < slots.size() && slots[next_out].done) {
          Slot& ready = slots[next_out];
          if (ready.status.ok()) {
            ++classified;
            progress.Interrupt([&] { on_result(next_out, ready.response, ready.seconds); });
            progress.Advance(1, 0);
          } else {
            failed.push_back({paths[next_out], ready.status});
            progress.Interrupt([&] { on_failure(next_out, ready.status); });
            progress.Advance(1, 1);
          }
          ready = Slot();  // release the response
          ready.done = true;
          ++next_out;
        }
      },
      [&] { return state.stopped(); });

  ClassifyOutcome outcome;
  outcome.classified = classified;
  outcome.failed = std::move(failed);
  outcome.stopped = state.stop_status();
  outcome.seconds = SecondsSince(start);
  return outcome;
}

}  // namespace shapeid
