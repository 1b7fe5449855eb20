#include "server/ops/observed_gallery_store.h"

#include "absl/time/clock.h"

namespace shapeid {

template <typename Write>
absl::Status ObservedGalleryStore::Timed(absl::string_view operation, Write write) {
  const absl::Time start = absl::Now();
  const absl::Status status = write();
  // Aborted is a stale copy (a shared store), retried by the gallery: not a store failure.
  metrics_->ObserveStoreWrite(operation, absl::Now() - start,
                              status.ok() || absl::IsAborted(status));
  return status;
}

absl::Status ObservedGalleryStore::SaveGallery(const StoredGallery& gallery) {
  return Timed("save", [&] { return store_->SaveGallery(gallery); });
}

absl::Status ObservedGalleryStore::DeleteGallery(absl::string_view name) {
  return Timed("delete", [&] { return store_->DeleteGallery(name); });
}

absl::Status ObservedGalleryStore::AppendSamples(absl::string_view name,
                                                 absl::Span<const StoredSample> batch,
                                                 absl::Time updated, uint64_t version) {
  return Timed("append", [&] { return store_->AppendSamples(name, batch, updated, version); });
}

absl::Status ObservedGalleryStore::RemoveSamples(absl::string_view name,
                                                 absl::Span<const uint64_t> ids, absl::Time updated,
                                                 uint64_t version) {
  return Timed("remove", [&] { return store_->RemoveSamples(name, ids, updated, version); });
}

}  // namespace shapeid
