#include "client/cli/eval_command.h"

#include <unistd.h>

#include <fstream>
#include <map>
#include <memory>
#include <utility>

#include "absl/strings/str_cat.h"
#include "absl/time/clock.h"
#include "client/cli/describe_command.h"
#include "core/random.h"

namespace shapeid {
namespace {

// Deletes a temporary gallery on every way out of an evaluation round.
class TemporaryGallery {
 public:
  TemporaryGallery(Client& client, std::string name) : client_(client), name_(std::move(name)) {}
  ~TemporaryGallery() {
    if (created_) (void)client_.DeleteGallery(name_);  // best effort: nothing else to do
  }
  TemporaryGallery(const TemporaryGallery&) = delete;
  TemporaryGallery& operator=(const TemporaryGallery&) = delete;

  absl::StatusOr<v1::Gallery> Create(v1::CreateGalleryRequest request) {
    request.set_name(name_);
    absl::StatusOr<v1::Gallery> gallery = client_.CreateGallery(request);
    created_ = gallery.ok();
    return gallery;
  }
  const std::string& name() const { return name_; }

 private:
  Client& client_;
  const std::string name_;
  bool created_ = false;
};

// Unique enough across concurrent evals on one server: pid and microseconds.
std::string TemporaryGalleryName(int round) {
  return absl::StrCat("eval-", ::getpid(), "-", absl::ToUnixMicros(absl::Now()), "-", round);
}

struct RoundFiles {
  std::vector<LabelledFile> train;  // empty in "gallery" mode
  std::vector<LabelledFile> test;
};

}  // namespace

std::vector<int> StratifiedFolds(const std::vector<LabelledFile>& files, int folds, uint64_t seed) {
  std::map<std::string, std::vector<size_t>> by_label;
  for (size_t i = 0; i < files.size(); ++i) by_label[files[i].label].push_back(i);
  std::vector<int> fold(files.size(), 0);
  SplitMix64 rng(seed);
  int next = 0;  // continue dealing across labels so small classes do not all start at fold 0
  for (auto& [label, members] : by_label) {
    for (size_t i = members.size(); i > 1; --i) {
      const size_t j = static_cast<size_t>(rng.Next() % i);
      std::swap(members[i - 1], members[j]);
    }
    for (size_t index : members) {
      fold[index] = next;
      next = (next + 1) % folds;
    }
  }
  return fold;
}

int RunEval(const EvalOptions& options, const CliContext& context) {
  EvalRun run;
  run.dataset = options.dataset;
  run.seed = options.seed;
  std::vector<RoundFiles> rounds;
  const auto usage = [&](const absl::Status& status) {
    PrintError(context.err, "eval", status);
    return kExitUsage;
  };

  const bool split_layout = HasTrainTestSplit(options.dataset);
  if (!options.gallery.empty()) {
    run.mode = "gallery";
    absl::StatusOr<std::vector<LabelledFile>> test =
        LabelledFiles(options.dataset, split_layout ? Split::kTest : Split::kAll);
    if (!test.ok()) return usage(test.status());
    rounds.push_back({{}, std::move(test).value()});
  } else if (options.folds == 0 && split_layout) {
    run.mode = "holdout";
    absl::StatusOr<std::vector<LabelledFile>> train = LabelledFiles(options.dataset, Split::kTrain);
    if (!train.ok()) return usage(train.status());
    absl::StatusOr<std::vector<LabelledFile>> test = LabelledFiles(options.dataset, Split::kTest);
    if (!test.ok()) return usage(test.status());
    rounds.push_back({std::move(train).value(), std::move(test).value()});
  } else {
    run.mode = "kfold";
    const int folds = options.folds == 0 ? 5 : options.folds;
    if (folds < 2) {
      return usage(absl::InvalidArgumentError("--folds must be at least 2"));
    }
    absl::StatusOr<std::vector<LabelledFile>> files = LabelledFiles(options.dataset, Split::kAll);
    if (!files.ok()) return usage(files.status());
    if (files->size() < static_cast<size_t>(folds)) {
      return usage(absl::InvalidArgumentError(absl::StrCat(
          options.dataset, ": ", files->size(), " files cannot make ", folds, " folds")));
    }
    run.folds = folds;
    const std::vector<int> fold = StratifiedFolds(*files, folds, options.seed);
    rounds.resize(static_cast<size_t>(folds));
    for (size_t i = 0; i < files->size(); ++i) {
      for (int f = 0; f < folds; ++f) {
        (f == fold[i] ? rounds[f].test : rounds[f].train).push_back((*files)[i]);
      }
    }
  }
  absl::StatusOr<v1::CreateGalleryRequest> request = CreateGalleryRequestFor(options.create);
  if (!request.ok()) return usage(request.status());

  std::unique_ptr<Client> client = ConnectOrReport(context);
  if (client == nullptr) return kExitUsage;
  const auto refused = [&](absl::string_view what, const absl::Status& status) {
    PrintError(context.err, what, status, context.client.target);
    return ExitCodeForStatus(status);
  };

  for (size_t r = 0; r < rounds.size(); ++r) {
    const std::string phase =
        rounds.size() > 1 ? absl::StrCat("fold ", r + 1, "/", rounds.size(), " ") : "";
    TemporaryGallery temporary(*client, TemporaryGalleryName(static_cast<int>(r)));
    std::string gallery = options.gallery;
    if (gallery.empty()) {
      absl::StatusOr<v1::Gallery> created = temporary.Create(*request);
      if (!created.ok()) return refused("eval: create a temporary gallery", created.status());
      gallery = temporary.name();
      run.descriptor_spec = created->descriptor_spec();
      run.k = options.create.k != 0 ? options.create.k : created->knn().k();

      TrainOutcome trained;
      {
        Progress progress(context.err, context.progress, phase + "train", rounds[r].train.size());
        trained =
            TrainFiles(*client, gallery, rounds[r].train, options.batch, progress, context.err);
      }
      if (!trained.stopped.ok()) return refused("eval: train", trained.stopped);
      run.train_samples += trained.trained;
      run.train_seconds += trained.seconds;
      for (const FailedInput& f : trained.failed) run.failed_files.push_back(f.path);
      if (trained.trained == 0) {
        return refused("eval", absl::FailedPreconditionError(
                                   "no training file could be used; nothing to evaluate"));
      }
    } else {
      absl::StatusOr<v1::Gallery> existing = client->GetGallery(gallery);
      if (!existing.ok()) return refused(absl::StrCat("eval ", gallery), existing.status());
      run.descriptor_spec = existing->descriptor_spec();
      run.k = options.create.k != 0 ? options.create.k : existing->knn().k();
    }

    const std::vector<LabelledFile>& test = rounds[r].test;
    std::vector<std::string> paths;
    paths.reserve(test.size());
    for (const LabelledFile& f : test) paths.push_back(f.path);
    ClassifyOutcome classified;
    {
      Progress progress(context.err, context.progress, phase + "test", paths.size());
      classified = ClassifyFiles(
          *client, gallery, options.create.k, paths, options.batch, progress,
          [&](size_t i, const v1::ClassifyResponse& response, double seconds) {
            EvalPrediction p;
            p.file = test[i].path;
            p.truth = test[i].label;
            p.predicted = response.unknown() ? "unknown" : response.label();
            p.confidence = response.confidence();
            p.seconds = seconds;
            p.fold = static_cast<int>(r);
            run.predictions.push_back(std::move(p));
          },
          [&](size_t i, const absl::Status& status) {
            WriteAll(context.err, FileErrorLine(test[i].path, status));
          });
    }
    if (!classified.stopped.ok()) return refused("eval: classify", classified.stopped);
    run.test_seconds += classified.seconds;
    for (const FailedInput& f : classified.failed) run.failed_files.push_back(f.path);
  }

  const EvalMetrics metrics = ComputeEvalMetrics(run);
  std::string text;
  switch (context.format) {
    case OutputFormat::kJson:
      text = FormatEvalJson(run, metrics, options.with_predictions);
      break;
    case OutputFormat::kCsv:
      text = FormatEvalCsv(metrics);
      break;
    case OutputFormat::kTable:
      text = FormatEvalTable(run, metrics);
      break;
  }
  bool written = WriteAll(context.out, text);
  written &= std::fflush(context.out) == 0;
  if (!options.report_html.empty()) {
    std::ofstream report(options.report_html, std::ios::binary | std::ios::trunc);
    report << RenderEvalHtml(run, metrics);
    report.close();
    if (!report) {
      WriteAll(context.err,
               absl::StrCat("shapeid: eval: cannot write the report ", options.report_html, "\n"));
      return kExitSomeInputsFailed;
    }
    if (context.progress != ProgressMode::kOff) {
      WriteAll(context.err, absl::StrCat("report written to ", options.report_html, "\n"));
    }
  }
  if (!written) {
    WriteAll(context.err, "shapeid: cannot write the output\n");
    return kExitSomeInputsFailed;
  }
  return run.failed_files.empty() ? kExitOk : kExitSomeInputsFailed;
}

}  // namespace shapeid
