#include "client/cli/eval_local.h"

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <functional>
#include <mutex>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "client/cli/describe_command.h"
#include "client/cli/input_files.h"
#include "core/gallery/gallery.h"
#include "core/gallery/gallery_head.h"
#include "core/gallery/gallery_options.h"
#include "core/gallery/gallery_snapshot.h"
#include "core/io/point_cloud_reader.h"
#include "core/knn/knn_options.h"
#include "core/views/augment.h"

namespace shapeid {
namespace {

using Clock = std::chrono::steady_clock;

double SecondsSince(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

// Runs work(i) for every i in [0, n) on `jobs` threads, and emit(i, result) in index order,
// one call at a time: each result waits until those before it are out. That is what keeps
// the gallery's sample order, the predictions and the error lines independent of timing.
template <typename Result>
void OrderedParallelFor(size_t n, int jobs, const std::function<Result(size_t)>& work,
                        const std::function<void(size_t, Result&)>& emit) {
  std::vector<std::optional<Result>> slots(n);
  std::mutex mu;
  size_t next = 0;
  ParallelFor(n, jobs, [&](size_t i) {
    Result result = work(i);
    std::lock_guard<std::mutex> lock(mu);
    slots[i] = std::move(result);
    for (; next < n && slots[next].has_value(); ++next) {
      emit(next, *slots[next]);
      slots[next].reset();  // frees a descriptor or answer as soon as it is used
    }
  });
}

// What a server makes of the same flags (server/wire/proto_convert.cc GalleryOptionsFromProto):
// an empty spec is the default descriptor, k = 0 is 1, empty weighting and scaling are the
// defaults. Weighting and scaling were checked by CreateGalleryRequestFor already.
absl::StatusOr<GalleryOptions> LocalGalleryOptions(const GalleryCreateOptions& create) {
  GalleryOptions options;
  if (!create.spec.empty()) options.descriptor_spec = create.spec;
  options.knn.k = create.k == 0 ? 1 : static_cast<int>(std::min<uint32_t>(create.k, 1 << 20));
  if (!create.weighting.empty()) {
    absl::StatusOr<VoteWeighting> weighting = ParseVoteWeighting(create.weighting);
    if (!weighting.ok()) return weighting.status();
    options.knn.weighting = *weighting;
  }
  if (!create.scaling.empty()) {
    absl::StatusOr<FeatureScaling> scaling = ParseFeatureScaling(create.scaling);
    if (!scaling.ok()) return scaling.status();
    options.knn.scaling = *scaling;
  }
  options.reject_distance = create.reject_distance;
  options.augment.views = static_cast<int>(std::min<uint32_t>(create.augment_views, 1 << 20));
  options.augment.sensor.random_pose = create.augment_random_pose;
  if (!create.augment_mix.empty()) {
    const std::optional<ViewMix> mix = ValueNamed(kViewMixNames, create.augment_mix);
    if (!mix) {
      return absl::InvalidArgumentError(absl::StrCat("--augment-mix \"", create.augment_mix,
                                                     "\": use ", NameList(kViewMixNames)));
    }
    options.augment.mix = *mix;
  }
  return options;
}

// One training file's descriptor, or why the file cannot be used.
struct Described {
  absl::Status status;
  std::vector<float> features;
};

// One test file's answer, or why it failed; `seconds` is describe + search.
struct Classified {
  absl::Status status;
  GalleryClassification answer;
  double seconds = 0;
};

class LocalEvalBackend final : public EvalBackend {
 public:
  LocalEvalBackend(const EvalOptions& options, const CliContext& context,
                   std::shared_ptr<Gallery> empty)
      : options_(options), context_(context), empty_(std::move(empty)) {}

  std::string target() const override { return ""; }

  // Describes in parallel, then builds the round's gallery from the descriptors in file
  // order: Gallery::Restore adds them to the index exactly as a server's Train commits do,
  // without a second description of each cloud or a copy of the index per batch.
  EvalStep Train(int /*round*/, const std::vector<LabeledFile>& train, Progress& progress,
                 EvalRun& run) override {
    const Clock::time_point start = Clock::now();
    gallery_.reset();
    sample_files_.clear();
    const std::shared_ptr<const GallerySnapshot> empty = empty_->Snapshot();
    const CloudLimits limits = empty_->limits().cloud_limits();
    StoredGallery stored = empty->ToStored();
    OrderedParallelFor<Described>(
        train.size(), options_.batch.jobs,
        [&](size_t i) {
          Described d;
          // A server refuses such a sample (e.g. a folder named "unknown") the same way.
          d.status = ValidateLabel(train[i].label);
          if (!d.status.ok()) return d;
          absl::StatusOr<ReadResult> read = ReadInputCloud(train[i].path, options_.batch.read);
          if (!read.ok()) {
            d.status = read.status();
            return d;
          }
          // What TrainBatch stores: the descriptor and its augmented views' (if any).
          absl::StatusOr<std::vector<float>> features =
              empty->DescribeForTraining(read->cloud, limits);
          if (!features.ok()) {
            d.status = features.status();
            return d;
          }
          d.features = *std::move(features);
          return d;
        },
        [&](size_t i, Described& d) {
          if (!d.status.ok()) {
            Fail(train[i].path, d.status, progress, run);
            return;
          }
          // The ids a new gallery gives its first id-0 samples, in training order; a server's
          // gallery may give the same files other ids.
          sample_files_.push_back(train[i].path);
          stored.samples.push_back(
              {kFirstAssignedId + stored.samples.size(), train[i].label, std::move(d.features)});
          progress.Advance(1, 0);
        });
    absl::StatusOr<std::shared_ptr<Gallery>> gallery =
        Gallery::Restore(stored, empty_->limits(), /*store=*/nullptr);
    if (!gallery.ok()) return {"eval: train", gallery.status()};
    gallery_ = *std::move(gallery);
    if (options_.create.learn == "mlp") {
      // What a server's gallery does once trained (gallery_head.h), on this thread.
      absl::StatusOr<GalleryHead> head = FitGalleryHead(*gallery_->Snapshot(), HeadOptions{});
      run.learn = "mlp";
      if (head.ok()) {
        run.fit_seconds += absl::ToDoubleSeconds(head->fit_time);
        run.head_holdout_rows += static_cast<uint64_t>(head->holdout_rows);
        run.head_holdout_right += static_cast<uint64_t>(head->holdout_right);
        const absl::Status set =
            gallery_->SetHead(std::make_shared<const GalleryHead>(*std::move(head)));
        if (!set.ok()) return {"eval: learn", set};
      } else if (head.status().code() != absl::StatusCode::kFailedPrecondition) {
        return {"eval: learn", head.status()};
      }  // too small a gallery to fit: the kNN vote answers, as on a server
    }
    run.descriptor_spec = stored.options.descriptor_spec;
    run.k =
        options_.create.k != 0 ? options_.create.k : static_cast<uint32_t>(stored.options.knn.k);
    run.train_samples += stored.samples.size();
    run.train_seconds += SecondsSince(start);
    return {};
  }

  EvalStep Test(int round, const std::vector<LabeledFile>& test, Progress& progress,
                EvalRun& run) override {
    const Clock::time_point start = Clock::now();
    const std::shared_ptr<const GallerySnapshot> snapshot = gallery_->Snapshot();
    const CloudLimits limits = gallery_->limits().cloud_limits();
    const int k = static_cast<int>(std::min<uint32_t>(options_.create.k, 1 << 20));
    OrderedParallelFor<Classified>(
        test.size(), options_.batch.jobs,
        [&](size_t i) {
          Classified c;
          absl::StatusOr<ReadResult> read = ReadInputCloud(test[i].path, options_.batch.read);
          if (!read.ok()) {
            c.status = read.status();
            return c;
          }
          const Clock::time_point call = Clock::now();
          absl::StatusOr<GalleryClassification> answer = snapshot->Classify(read->cloud, limits, k);
          c.seconds = SecondsSince(call);
          if (answer.ok()) {
            c.answer = *std::move(answer);
          } else {
            c.status = answer.status();
          }
          return c;
        },
        [&](size_t i, Classified& c) {
          if (!c.status.ok()) {
            Fail(test[i].path, c.status, progress, run);
            return;
          }
          EvalPrediction p;
          p.file = test[i].path;
          p.truth = test[i].label;
          p.predicted = c.answer.unknown ? std::string(kUnknownLabel) : c.answer.label;
          p.confidence = c.answer.confidence;
          p.seconds = c.seconds;
          p.fold = round;
          for (const Neighbor& n : c.answer.knn.neighbors) {
            const uint64_t index = n.id - kFirstAssignedId;
            p.neighbors.push_back({n.id, n.label, n.distance, static_cast<uint32_t>(n.view),
                                   index < sample_files_.size() ? sample_files_[index] : ""});
          }
          run.predictions.push_back(std::move(p));
          progress.Advance(1, 0);
        });
    run.test_seconds += SecondsSince(start);
    return {};
  }

  void IdentifyServer(EvalRun& /*run*/) override {}  // no server

 private:
  // One failed file: a line on stderr, counted, and the evaluation goes on.
  void Fail(const std::string& path, const absl::Status& status, Progress& progress, EvalRun& run) {
    const std::string line = FileErrorLine(path, status);
    progress.Interrupt([&] { WriteAll(context_.err, line); });
    progress.Advance(1, 1);
    run.failed_files.push_back(path);
  }

  const EvalOptions& options_;
  const CliContext& context_;
  // Never trained: its snapshot describes the training clouds and gives every round's
  // gallery its canonical options and versions.
  const std::shared_ptr<Gallery> empty_;
  std::shared_ptr<Gallery> gallery_;  // the round's
  // The round's training file of sample id kFirstAssignedId + i.
  std::vector<std::string> sample_files_;
};

}  // namespace

absl::StatusOr<std::unique_ptr<EvalBackend>> NewLocalEvalBackend(const EvalOptions& options,
                                                                 const CliContext& context) {
  absl::StatusOr<GalleryOptions> gallery_options = LocalGalleryOptions(options.create);
  if (!gallery_options.ok()) return gallery_options.status();
  // Searches as a server with its default flags does: approximate on large galleries.
  GalleryLimits limits;
  limits.approximate.min_vectors = ApproximateOptions::kServedMinVectors;
  absl::StatusOr<std::shared_ptr<Gallery>> empty =
      Gallery::Create("eval-local", *gallery_options, limits, /*store=*/nullptr);
  if (!empty.ok()) return empty.status();
  return std::unique_ptr<EvalBackend>(
      std::make_unique<LocalEvalBackend>(options, context, *std::move(empty)));
}

}  // namespace shapeid
