#include "core/gallery/gallery_store.h"

#include <algorithm>
#include <utility>

#include "absl/container/flat_hash_set.h"
#include "absl/strings/str_cat.h"

namespace shapeid {

namespace {

absl::Status NotStored(absl::string_view name) {
  return absl::InternalError(absl::StrCat("store holds no gallery '", name, "'"));
}

// Keeps every gallery that ends, whole.
class Collector final : public GalleryLoader {
 public:
  absl::Status Begin(const GalleryMetadata& gallery) override {
    current_ = StoredGallery();
    static_cast<GalleryMetadata&>(current_) = gallery;
    begun_ = true;
    return absl::OkStatus();
  }
  absl::Status Add(StoredSample& sample) override {
    if (!begun_) return absl::InternalError("a stored sample arrived before its gallery");
    current_.samples.push_back(std::move(sample));
    return absl::OkStatus();
  }
  absl::Status End() override {
    if (!begun_) return absl::InternalError("a stored gallery ended before it began");
    galleries_.push_back(std::move(current_));
    current_ = StoredGallery();
    begun_ = false;
    return absl::OkStatus();
  }
  std::vector<StoredGallery> Take() { return std::move(galleries_); }

 private:
  std::vector<StoredGallery> galleries_;
  StoredGallery current_;
  bool begun_ = false;
};

}  // namespace

absl::Status HandOverGalleries(std::vector<StoredGallery> galleries,
                               const std::map<std::string, std::string, std::less<>>& heads,
                               GalleryLoader& loader) {
  for (StoredGallery& gallery : galleries) {
    if (absl::Status s = loader.Begin(gallery); !s.ok()) return s;
    for (StoredSample& sample : gallery.samples) {
      if (absl::Status s = loader.Add(sample); !s.ok()) return s;
    }
    if (absl::Status s = loader.End(); !s.ok()) return s;
    if (auto head = heads.find(gallery.name); head != heads.end()) {
      if (absl::Status s = loader.Head(head->second); !s.ok()) return s;
    }
    gallery = StoredGallery();
  }
  return absl::OkStatus();
}

absl::Status GalleryStore::Load(GalleryLoader& loader) {
  absl::StatusOr<std::vector<StoredGallery>> all = LoadAll();
  if (!all.ok()) return all.status();
  return HandOverGalleries(*std::move(all), {}, loader);
}

absl::StatusOr<std::vector<StoredGallery>> CollectGalleries(GalleryStore& store) {
  Collector collector;
  if (absl::Status s = store.Load(collector); !s.ok()) return s;
  return collector.Take();
}

absl::Status InMemoryGalleryStore::SaveGallery(const StoredGallery& gallery) {
  std::lock_guard<std::mutex> lock(mu_);
  if (!failure_.ok()) return failure_;
  galleries_[gallery.name] = gallery;
  return absl::OkStatus();
}

absl::Status InMemoryGalleryStore::DeleteGallery(absl::string_view name) {
  std::lock_guard<std::mutex> lock(mu_);
  if (!failure_.ok()) return failure_;
  auto it = galleries_.find(name);
  if (it == galleries_.end()) return NotStored(name);
  galleries_.erase(it);
  if (auto head = heads_.find(name); head != heads_.end()) heads_.erase(head);
  return absl::OkStatus();
}

absl::Status InMemoryGalleryStore::SaveHead(absl::string_view name, absl::string_view bytes) {
  std::lock_guard<std::mutex> lock(mu_);
  if (!failure_.ok()) return failure_;
  if (galleries_.find(name) == galleries_.end()) return NotStored(name);
  heads_[std::string(name)] = std::string(bytes);
  return absl::OkStatus();
}

absl::Status InMemoryGalleryStore::Load(GalleryLoader& loader) {
  absl::StatusOr<std::vector<StoredGallery>> all = LoadAll();
  if (!all.ok()) return all.status();
  std::map<std::string, std::string, std::less<>> heads;
  {
    std::lock_guard<std::mutex> lock(mu_);
    heads = heads_;
  }
  return HandOverGalleries(*std::move(all), heads, loader);
}

absl::Status InMemoryGalleryStore::AppendSamples(absl::string_view name,
                                                 absl::Span<const StoredSample> batch,
                                                 absl::Time updated, uint64_t version) {
  std::lock_guard<std::mutex> lock(mu_);
  if (!failure_.ok()) return failure_;
  auto it = galleries_.find(name);
  if (it == galleries_.end()) return NotStored(name);
  it->second.samples.insert(it->second.samples.end(), batch.begin(), batch.end());
  it->second.updated = updated;
  it->second.version = version;
  return absl::OkStatus();
}

absl::Status InMemoryGalleryStore::RemoveSamples(absl::string_view name,
                                                 absl::Span<const uint64_t> ids, absl::Time updated,
                                                 uint64_t version) {
  std::lock_guard<std::mutex> lock(mu_);
  if (!failure_.ok()) return failure_;
  auto it = galleries_.find(name);
  if (it == galleries_.end()) return NotStored(name);
  const absl::flat_hash_set<uint64_t> gone(ids.begin(), ids.end());
  auto& samples = it->second.samples;
  samples.erase(std::remove_if(samples.begin(), samples.end(),
                               [&](const StoredSample& s) { return gone.contains(s.id); }),
                samples.end());
  it->second.updated = updated;
  it->second.version = version;
  return absl::OkStatus();
}

absl::StatusOr<std::vector<StoredGallery>> InMemoryGalleryStore::LoadAll() {
  std::lock_guard<std::mutex> lock(mu_);
  if (!failure_.ok()) return failure_;
  std::vector<StoredGallery> all;
  for (const auto& [name, g] : galleries_) all.push_back(g);
  return all;
}

void InMemoryGalleryStore::SetFailure(absl::Status status) {
  std::lock_guard<std::mutex> lock(mu_);
  failure_ = std::move(status);
}

int64_t InMemoryGalleryStore::NumSamples(absl::string_view name) const {
  std::lock_guard<std::mutex> lock(mu_);
  auto it = galleries_.find(name);
  return it == galleries_.end() ? -1 : static_cast<int64_t>(it->second.samples.size());
}

}  // namespace shapeid
