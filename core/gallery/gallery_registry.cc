#include "core/gallery/gallery_registry.h"

#include <optional>
#include <utility>

#include "absl/strings/str_cat.h"
#include "core/gallery/gallery_head.h"
#include "core/status_macros.h"

namespace shapeid {

namespace {

// NotFound, or InvalidArgument for a name no gallery can have (as the API documents), so that
// a typo like "../x" or a 200-character name says what is wrong with it.
absl::Status NoSuchGallery(absl::string_view name) {
  if (absl::Status valid = ValidateGalleryName(name); !valid.ok()) return valid;
  return absl::NotFoundError(absl::StrCat("no gallery named '", name, "'"));
}

// Rebuilds each gallery as the store reads it, a sample at a time, each sample's provenance
// moved in: nothing stored is held twice.
class RestoringLoader final : public GalleryLoader {
 public:
  RestoringLoader(const GalleryLimits& limits, std::shared_ptr<GalleryStore> store,
                  CatchUpFunction catch_up)
      : limits_(limits), store_(std::move(store)), catch_up_(std::move(catch_up)) {}

  absl::Status Begin(const GalleryMetadata& gallery) override {
    restorer_.reset();  // a gallery begun and not ended is dropped
    SHAPEID_ASSIGN_OR_RETURN(Gallery::Restorer restorer, Gallery::Restorer::Begin(gallery));
    restorer_.emplace(std::move(restorer));
    return absl::OkStatus();
  }
  absl::Status Add(StoredSample& sample) override {
    if (!restorer_.has_value())
      return absl::InternalError("a stored sample came before its gallery");
    return restorer_->Add(std::move(sample));
  }
  absl::Status End() override {
    if (!restorer_.has_value())
      return absl::InternalError("a stored gallery ended before it began");
    absl::StatusOr<std::shared_ptr<Gallery>> gallery =
        std::move(*restorer_).Finish(limits_, store_, Gallery::ApproximateBuild::kLater, catch_up_);
    restorer_.reset();
    if (!gallery.ok()) return gallery.status();
    loaded_.push_back(*std::move(gallery));
    return absl::OkStatus();
  }

  // The head the store kept, for the gallery just loaded: used only if it was fitted on
  // exactly these samples (else a crash came between a change and the head's refit, and the
  // learner fits it again). A head that does not parse is left out the same way.
  absl::Status Head(absl::string_view bytes) override {
    if (loaded_.empty()) return absl::InternalError("a stored head came before its gallery");
    const std::shared_ptr<Gallery>& gallery = loaded_.back();
    absl::StatusOr<GalleryHead> head = GalleryHead::Parse(bytes);
    if (!head.ok()) return absl::OkStatus();
    const std::shared_ptr<const GallerySnapshot> snapshot = gallery->Snapshot();
    if (head->samples_fingerprint != SamplesFingerprint(*snapshot)) return absl::OkStatus();
    head->fitted_version = snapshot->version();  // versions restart in some stores
    return gallery->SetHead(std::make_shared<const GalleryHead>(*std::move(head)));
  }

  std::vector<std::shared_ptr<Gallery>>& loaded() { return loaded_; }

 private:
  const GalleryLimits limits_;
  const std::shared_ptr<GalleryStore> store_;
  const CatchUpFunction catch_up_;
  std::optional<Gallery::Restorer> restorer_;
  std::vector<std::shared_ptr<Gallery>> loaded_;
};

}  // namespace

GalleryRegistry::GalleryRegistry(GalleryLimits limits, std::shared_ptr<GalleryStore> store,
                                 CatchUpFunction catch_up)
    : limits_(limits),
      store_(store != nullptr ? std::move(store) : std::make_shared<NullGalleryStore>()),
      catch_up_(std::move(catch_up)) {}

GalleryRegistry::~GalleryRegistry() {
  stop_ = true;
  WaitForApproximateIndexes();
}

void GalleryRegistry::WaitForApproximateIndexes() {
  if (approximate_builder_.joinable()) approximate_builder_.join();
}

absl::Status GalleryRegistry::LoadFromStore() {
  RestoringLoader loader(limits_, store_, catch_up_);
  SHAPEID_RETURN_IF_ERROR(store_->Load(loader));
  std::vector<std::shared_ptr<Gallery>> loaded = std::move(loader.loaded());
  std::lock_guard<std::mutex> lock(mu_);
  if (galleries_.size() + loaded.size() > limits_.max_galleries) {
    return absl::ResourceExhaustedError(
        absl::StrCat("the store holds ", loaded.size(), " galleries and ", galleries_.size(),
                     " are registered, more than max_galleries = ", limits_.max_galleries));
  }
  for (const auto& gallery : loaded) {
    if (galleries_.count(gallery->name()) != 0) {
      return absl::AlreadyExistsError(
          absl::StrCat("stored gallery '", gallery->name(), "' is already registered"));
    }
  }
  for (const auto& gallery : loaded) galleries_.emplace(gallery->name(), gallery);
  // One gallery after another, so that the build's working copy (an index copy plus its
  // lists) is there for one gallery at a time. A gallery deleted meanwhile is skipped by
  // UpdateApproximateIndex; a cancelled or failed build leaves it exact, as it was, until
  // its next commit brings the index in step.
  WaitForApproximateIndexes();
  approximate_builder_ = std::thread([this, galleries = std::move(loaded)] {
    for (const auto& gallery : galleries) {
      if (stop_) return;
      (void)gallery->UpdateApproximateIndex(&stop_);
    }
  });
  return absl::OkStatus();
}

absl::StatusOr<std::shared_ptr<Gallery>> GalleryRegistry::Create(absl::string_view name,
                                                                 const GalleryOptions& options) {
  // Validation and descriptor construction need no lock.
  SHAPEID_ASSIGN_OR_RETURN(
      std::shared_ptr<Gallery> gallery,
      Gallery::Create(std::string(name), options, limits_, store_, absl::Now(), catch_up_));
  return Add(gallery, gallery->Snapshot()->ToStored(), "create", "");
}

absl::StatusOr<std::shared_ptr<Gallery>> GalleryRegistry::Import(StoredGallery stored) {
  stored.incarnation = NewGalleryIncarnation();  // a new gallery, wherever it was exported
  if (static_cast<int64_t>(stored.samples.size()) > limits_.max_samples_per_gallery) {
    return absl::ResourceExhaustedError(absl::StrCat(
        "cannot import gallery '", stored.name, "': it holds ", stored.samples.size(),
        " samples, more than max_samples_per_gallery = ", limits_.max_samples_per_gallery));
  }
  // Validation and the index build need no lock.
  SHAPEID_ASSIGN_OR_RETURN(
      std::shared_ptr<Gallery> gallery,
      Gallery::Restore(stored, limits_, store_, Gallery::ApproximateBuild::kNow, catch_up_));
  const std::shared_ptr<const GallerySnapshot> snapshot = gallery->Snapshot();
  if (!snapshot->incompatible().empty()) {
    return absl::FailedPreconditionError(absl::StrCat("cannot import: ", snapshot->incompatible()));
  }
  return Add(gallery, stored, "import", "; import under another name or delete it");
}

absl::StatusOr<std::shared_ptr<Gallery>> GalleryRegistry::Add(std::shared_ptr<Gallery> gallery,
                                                              const StoredGallery& stored,
                                                              absl::string_view verb,
                                                              absl::string_view exists_hint) {
  const std::string& name = stored.name;
  {
    std::lock_guard<std::mutex> lock(mu_);
    if (galleries_.count(name) != 0 || pending_.count(name) != 0) {
      return absl::AlreadyExistsError(
          absl::StrCat("gallery '", name, "' already exists", exists_hint));
    }
    const size_t count = galleries_.size() + pending_.size();
    if (count >= limits_.max_galleries) {
      return absl::ResourceExhaustedError(
          absl::StrCat("cannot ", verb, " gallery '", name, "': ", count,
                       " galleries exist, the limit (max_galleries) is ", limits_.max_galleries));
    }
    pending_.insert(name);
  }
  // The store write (fsyncs; about 0.6 s for a 100,000-sample import) runs without the
  // registry lock, so Get, and with it every Classify, never waits for it. The name stays
  // reserved meanwhile, so the store still sees one create or delete per name at a time.
  const absl::Status saved = store_->SaveGallery(stored);
  std::lock_guard<std::mutex> lock(mu_);
  pending_.erase(name);
  SHAPEID_RETURN_IF_ERROR(saved);
  galleries_.emplace(name, std::move(gallery));
  return galleries_.at(name);
}

absl::StatusOr<std::shared_ptr<Gallery>> GalleryRegistry::Get(absl::string_view name) const {
  std::lock_guard<std::mutex> lock(mu_);
  auto it = galleries_.find(name);
  if (it == galleries_.end()) return NoSuchGallery(name);
  return it->second;
}

std::vector<std::string> GalleryRegistry::List() const {
  std::lock_guard<std::mutex> lock(mu_);
  std::vector<std::string> names;
  names.reserve(galleries_.size());
  for (const auto& [name, gallery] : galleries_) names.push_back(name);
  return names;
}

std::vector<std::shared_ptr<Gallery>> GalleryRegistry::All() const {
  std::lock_guard<std::mutex> lock(mu_);
  std::vector<std::shared_ptr<Gallery>> galleries;
  galleries.reserve(galleries_.size());
  for (const auto& [name, gallery] : galleries_) galleries.push_back(gallery);
  return galleries;
}

absl::Status GalleryRegistry::Delete(absl::string_view name) {
  std::lock_guard<std::mutex> lock(mu_);
  auto it = galleries_.find(name);
  if (it == galleries_.end()) return NoSuchGallery(name);
  // Under the gallery's writer lock: a commit in progress reaches the store first, and no
  // later write of this gallery reaches it at all.
  SHAPEID_RETURN_IF_ERROR(it->second->MarkDeleted([&] { return store_->DeleteGallery(name); }));
  galleries_.erase(it);
  return absl::OkStatus();
}

absl::Status GalleryRegistry::ApplyStoredGallery(const StoredGallery& stored) {
  SHAPEID_ASSIGN_OR_RETURN(
      std::shared_ptr<Gallery> gallery,
      Gallery::Restore(stored, limits_, store_, Gallery::ApproximateBuild::kNow, catch_up_));
  std::shared_ptr<Gallery> same;      // the same incarnation, held: takes the stored state
  std::shared_ptr<Gallery> replaced;  // another incarnation: retired
  {
    std::lock_guard<std::mutex> lock(mu_);
    auto it = galleries_.find(stored.name);
    if (it == galleries_.end()) {
      // No max_galleries check: the gallery exists already; refusing to mirror it would only
      // make this server answer differently from the one that created it.
      galleries_.emplace(stored.name, std::move(gallery));
      return absl::OkStatus();
    }
    if (it->second->Snapshot()->incarnation() == stored.incarnation) {
      same = it->second;
    } else {
      replaced = std::exchange(it->second, std::move(gallery));
    }
  }
  // Outside the registry's lock: both wait for the gallery's writer, which may be a store
  // round trip away, and Get (every Classify) must not wait with them.
  if (same != nullptr) return same->AdoptStored(*gallery);
  // The store is the truth: the copy it replaces stops accepting writes (as after Delete).
  (void)replaced->MarkDeleted([] { return absl::OkStatus(); });
  return absl::OkStatus();
}

void GalleryRegistry::ApplyStoredDelete(absl::string_view name, uint64_t incarnation) {
  std::shared_ptr<Gallery> gone;
  {
    std::lock_guard<std::mutex> lock(mu_);
    auto it = galleries_.find(name);
    if (it == galleries_.end() || it->second->Snapshot()->incarnation() != incarnation) return;
    gone = std::move(it->second);
    galleries_.erase(it);
  }
  (void)gone->MarkDeleted([] { return absl::OkStatus(); });
}

size_t GalleryRegistry::size() const {
  std::lock_guard<std::mutex> lock(mu_);
  return galleries_.size();
}

}  // namespace shapeid
