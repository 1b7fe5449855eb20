#ifndef SHAPEID_SERVER_OPS_OBSERVED_GALLERY_STORE_H_
#define SHAPEID_SERVER_OPS_OBSERVED_GALLERY_STORE_H_

// A GalleryStore that times every write of the store it wraps into the metrics
// (shapeid_store_write_duration_seconds, shapeid_store_write_failures_total), so core/ and the
// stores stay free of metrics. Reads (LoadAll, Load) pass through untimed.

#include <memory>
#include <vector>

#include "core/gallery/gallery_store.h"
#include "server/ops/metrics.h"

namespace shapeid {

class ObservedGalleryStore final : public GalleryStore {
 public:
  ObservedGalleryStore(std::shared_ptr<GalleryStore> store, std::shared_ptr<ServerMetrics> metrics)
      : store_(std::move(store)), metrics_(std::move(metrics)) {}

  absl::Status SaveGallery(const StoredGallery& gallery) override;
  absl::Status DeleteGallery(absl::string_view name) override;
  absl::Status AppendSamples(absl::string_view name, absl::Span<const StoredSample> batch,
                             absl::Time updated, uint64_t version) override;
  absl::Status RemoveSamples(absl::string_view name, absl::Span<const uint64_t> ids,
                             absl::Time updated, uint64_t version) override;
  absl::StatusOr<std::vector<StoredGallery>> LoadAll() override { return store_->LoadAll(); }
  absl::Status Load(GalleryLoader& loader) override { return store_->Load(loader); }
  // Derived state, written once per fit: not timed as a write.
  absl::Status SaveHead(absl::string_view name, absl::string_view bytes) override {
    return store_->SaveHead(name, bytes);
  }

 private:
  template <typename Write>
  absl::Status Timed(absl::string_view operation, Write write);

  const std::shared_ptr<GalleryStore> store_;
  const std::shared_ptr<ServerMetrics> metrics_;
};

}  // namespace shapeid

#endif  // SHAPEID_SERVER_OPS_OBSERVED_GALLERY_STORE_H_
