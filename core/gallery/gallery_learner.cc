#include "core/gallery/gallery_learner.h"

#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <map>
#include <utility>
#include <vector>

#include "core/gallery/gallery.h"
#include "core/gallery/gallery_registry.h"
#include "core/gallery/gallery_snapshot.h"

namespace shapeid {
namespace {

// Whether `snapshot` should get a (new) head: enough samples of two labels or more, and no
// head fitted on this very version.
bool WantsHead(const GallerySnapshot& snapshot, const HeadOptions& options) {
  if (!snapshot.incompatible().empty()) return false;
  if (snapshot.num_samples() < options.min_samples || snapshot.index().num_labels() < 2) {
    return false;
  }
  const std::shared_ptr<const GalleryHead>& head = snapshot.head();
  return head == nullptr || head->fitted_version != snapshot.version();
}

// The working memory of a fit: a copy of every vector, the network with its AdamW state,
// and a mini-batch's activations, with room to spare.
int64_t FitBytes(const GallerySnapshot& snapshot, const HeadOptions& options) {
  const int64_t parameters = MlpClassifier::ParametersFor(snapshot.dimension(), options.mlp.hidden,
                                                          snapshot.index().num_labels());
  const int64_t rows = FitVectors(snapshot, options);
  return rows * (snapshot.dimension() + 1) * 4 + 4 * 4 * parameters + (int64_t{1} << 20);
}

}  // namespace

GalleryLearner::GalleryLearner(GalleryLearnerOptions options, GalleryRegistry* registry)
    : options_(std::move(options)), registry_(registry) {
  thread_ = std::thread([this] { Run(); });
}

GalleryLearner::~GalleryLearner() { Stop(); }

void GalleryLearner::Stop() {
  {
    std::lock_guard<std::mutex> lock(mu_);
    stop_ = true;
  }
  wake_.notify_all();
  if (thread_.joinable()) thread_.join();
}

void GalleryLearner::Nudge() {
  {
    std::lock_guard<std::mutex> lock(mu_);
    nudged_ = true;
  }
  wake_.notify_all();
}

std::string GalleryLearner::fitting() const {
  std::lock_guard<std::mutex> lock(mu_);
  return fitting_;
}

void GalleryLearner::Run() {
  if (options_.low_priority) {
    // Per thread on Linux: only this thread yields to requests.
    (void)setpriority(PRIO_PROCESS, static_cast<id_t>(syscall(SYS_gettid)), 19);
  }
  // A gallery whose fit failed at a version is not tried again at that version before
  // `retry` (a refused memory reservation may succeed later; a bad gallery will not).
  struct Attempt {
    uint64_t version = 0;
    absl::Time after;
  };
  std::map<std::string, Attempt> failed;
  const absl::Duration retry = absl::Seconds(30);
  while (true) {
    {
      std::unique_lock<std::mutex> lock(mu_);
      wake_.wait_for(lock, absl::ToChronoMilliseconds(options_.poll),
                     [this] { return stop_.load() || nudged_; });
      nudged_ = false;
      if (stop_) return;
    }
    const absl::Time now = absl::Now();
    std::shared_ptr<Gallery> gallery;
    for (const std::shared_ptr<Gallery>& candidate : registry_->All()) {
      const std::shared_ptr<const GallerySnapshot> snapshot = candidate->Snapshot();
      if (now - snapshot->updated() < options_.settle) continue;
      if (!WantsHead(*snapshot, options_.head)) continue;
      const auto tried = failed.find(candidate->name());
      if (tried != failed.end() && tried->second.version == snapshot->version() &&
          now < tried->second.after) {
        continue;
      }
      gallery = candidate;
      break;
    }
    if (gallery == nullptr) continue;
    const uint64_t version = gallery->Snapshot()->version();
    const int64_t before = fits_;
    Fit(gallery);
    if (fits_ == before) {
      failed[gallery->name()] = {version, absl::Now() + retry};
    } else {
      failed.erase(gallery->name());
    }
    Nudge();  // look again at once: another gallery may be waiting
  }
}

void GalleryLearner::Fit(const std::shared_ptr<Gallery>& gallery) {
  const std::shared_ptr<const GallerySnapshot> snapshot = gallery->Snapshot();
  std::shared_ptr<void> memory;
  if (options_.reserve) {
    absl::StatusOr<std::shared_ptr<void>> reserved =
        options_.reserve(FitBytes(*snapshot, options_.head));
    if (!reserved.ok()) {
      ++failures_;
      return;
    }
    memory = *std::move(reserved);
  }
  {
    std::lock_guard<std::mutex> lock(mu_);
    fitting_ = gallery->name();
  }
  int64_t batches = 0;
  const FitProgress progress = [&](double) -> absl::Status {
    if (stop_) return absl::CancelledError("the learner is stopping");
    // Now and then: a gallery deleted (or replaced) meanwhile is not worth finishing.
    if (++batches % 64 == 0) {
      absl::StatusOr<std::shared_ptr<Gallery>> current = registry_->Get(gallery->name());
      if (!current.ok() || *current != gallery) return absl::CancelledError("gallery deleted");
    }
    return absl::OkStatus();
  };
  absl::StatusOr<GalleryHead> head = FitGalleryHead(*snapshot, options_.head, progress);
  {
    std::lock_guard<std::mutex> lock(mu_);
    fitting_.clear();
  }
  if (!head.ok()) {
    if (head.status().code() != absl::StatusCode::kCancelled) ++failures_;
    return;
  }
  // Published even when the store cannot keep it (the next restart then fits it again).
  auto published = std::make_shared<const GalleryHead>(*std::move(head));
  (void)gallery->SetHead(published, Gallery::KeepHead::kInStore);
  ++fits_;
  if (options_.on_fitted) options_.on_fitted(gallery->name(), *published);
}

}  // namespace shapeid
