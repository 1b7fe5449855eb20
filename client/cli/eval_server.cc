#include "client/cli/eval_server.h"

#include <unistd.h>

#include <string>
#include <utility>
#include <vector>

#include "absl/strings/str_cat.h"
#include "absl/time/clock.h"
#include "client/cli/batch.h"
#include "client/cli/describe_command.h"

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

class ServerEvalBackend final : public EvalBackend {
 public:
  ServerEvalBackend(const EvalOptions& options, v1::CreateGalleryRequest request,
                    const CliContext& context, std::unique_ptr<Client> client)
      : options_(options),
        request_(std::move(request)),
        context_(context),
        client_(std::move(client)) {}

  std::string target() const override { return context_.client.target; }

  EvalStep Train(int round, const std::vector<LabeledFile>& train, Progress& progress,
                 EvalRun& run) override {
    temporary_.reset();  // the previous round's gallery goes first
    const uint32_t k = options_.create.k;
    if (!options_.gallery.empty()) {
      gallery_ = options_.gallery;
      absl::StatusOr<v1::Gallery> existing = client_->GetGallery(gallery_);
      if (!existing.ok()) return {absl::StrCat("eval ", gallery_), existing.status()};
      run.descriptor_spec = existing->descriptor_spec();
      run.k = k != 0 ? k : existing->knn().k();
      run.gallery = gallery_;
      run.train_samples = existing->sample_count();
      return {};
    }
    temporary_ = std::make_unique<TemporaryGallery>(*client_, TemporaryGalleryName(round));
    absl::StatusOr<v1::Gallery> created = temporary_->Create(request_);
    if (!created.ok()) return {"eval: create a temporary gallery", created.status()};
    gallery_ = temporary_->name();
    run.descriptor_spec = created->descriptor_spec();
    run.k = k != 0 ? k : created->knn().k();

    const TrainOutcome trained =
        TrainFiles(*client_, gallery_, train, options_.batch, progress, context_.err);
    if (!trained.stopped.ok()) return {"eval: train", trained.stopped};
    run.train_samples += trained.trained;
    run.train_seconds += trained.seconds;
    for (const FailedInput& f : trained.failed) run.failed_files.push_back(f.path);
    return {};
  }

  EvalStep Test(int round, const std::vector<LabeledFile>& test, Progress& progress,
                EvalRun& run) override {
    std::vector<std::string> paths;
    paths.reserve(test.size());
    for (const LabeledFile& f : test) paths.push_back(f.path);
    Client::ClassifyOptions call;
    call.k = options_.create.k;
    const ClassifyOutcome classified = ClassifyFiles(
        *client_, gallery_, call, paths, options_.batch, progress,
        [&](size_t i, const v1::ClassifyResponse& response, double seconds) {
          EvalPrediction p;
          p.file = test[i].path;
          p.truth = test[i].label;
          p.predicted = response.unknown() ? "unknown" : response.label();
          p.confidence = response.confidence();
          p.seconds = seconds;
          p.fold = round;
          for (const v1::Neighbor& n : response.neighbors()) {
            p.neighbors.push_back({n.sample_id(), n.label(), n.distance(), n.view(), n.source()});
          }
          run.predictions.push_back(std::move(p));
        },
        [&](size_t i, const absl::Status& status) {
          WriteAll(context_.err, FileErrorLine(test[i].path, status));
        });
    if (!classified.stopped.ok()) return {"eval: classify", classified.stopped};
    run.test_seconds += classified.seconds;
    for (const FailedInput& f : classified.failed) run.failed_files.push_back(f.path);
    return {};
  }

  void IdentifyServer(EvalRun& run) override {
    absl::StatusOr<v1::ServerStats> stats = client_->GetServerStats();
    if (stats.ok()) run.server_version = stats->version();
  }

 private:
  const EvalOptions& options_;
  const v1::CreateGalleryRequest request_;
  const CliContext& context_;
  // Declared before temporary_, which deletes its gallery through it when destroyed.
  const std::unique_ptr<Client> client_;
  std::unique_ptr<TemporaryGallery> temporary_;
  std::string gallery_;  // the round's gallery
};

}  // namespace

std::unique_ptr<EvalBackend> NewServerEvalBackend(const EvalOptions& options,
                                                  v1::CreateGalleryRequest request,
                                                  const CliContext& context) {
  std::unique_ptr<Client> client = ConnectOrReport(context);
  if (client == nullptr) return nullptr;
  return std::make_unique<ServerEvalBackend>(options, std::move(request), context,
                                             std::move(client));
}

}  // namespace shapeid
