#ifndef SHAPEID_CORE_GALLERY_GALLERY_HEAD_H_
#define SHAPEID_CORE_GALLERY_GALLERY_HEAD_H_

// A gallery's trained head: an MLP classifier (core/learning) fitted over every
// vector the gallery stores, its samples' descriptors and their augmented views, that answers
// Classify together with the kNN vote once fitted (GalleryClassification::by_head). The kNN
// search still runs: its neighbors, distances and provenance are returned with the answer,
// and the reject rule is the gallery's as before.
//
// Fitting holds out a slice of the samples (every view of a held-out sample with it, chosen
// by id so the slice is stable as the gallery grows) and reports the head's accuracy on that
// slice: a figure on the gallery's own data, not on a sensor's. The head served is the one
// fitted without the slice.

#include <cstdint>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "absl/time/time.h"
#include "core/learning/mlp_classifier.h"

namespace shapeid {

class GallerySnapshot;

struct HeadOptions {
  // MlpOptions' defaults with input noise: a regulariser against the simulator's signature
  // in the augmented views (docs/accuracy.md has the figures).
  MlpOptions mlp = [] {
    MlpOptions options;
    options.input_noise = 0.3;
    return options;
  }();
  // Samples held out of the fit, in per mille (100: about one in ten); 0 holds none out.
  int holdout_per_mille = 100;
  // Galleries with fewer samples or fewer than two labels are not fitted (FailedPrecondition).
  int min_samples = 20;
  // A fit reads at most about this many vectors, so that its time and memory stay bounded
  // however large the gallery: each sample's own descriptor first, then its views, each
  // kept by a hash of (id, view) with the probability that fills the rest.
  int64_t max_vectors = 250'000;
};

absl::Status ValidateHeadOptions(const HeadOptions& options);

struct GalleryHead {
  MlpClassifier classifier;
  std::vector<std::string> labels;  // class i's label; sorted (byte order)
  uint64_t fitted_version = 0;      // the snapshot version it was fitted on
  // SamplesFingerprint of the samples it was fitted on: a head kept by a store is used after
  // a restart only for exactly those samples (versions do not survive every store).
  uint64_t samples_fingerprint = 0;
  int64_t fitted_samples = 0;  // samples (and rows: vectors) fitted on
  int64_t fitted_rows = 0;
  int64_t holdout_samples = 0;  // samples held out, and the vectors among them that the
  int64_t holdout_rows = 0;     // head answered right
  int64_t holdout_right = 0;
  absl::Duration fit_time;  // wall time of the fit, on one thread

  double holdout_accuracy() const {
    return holdout_rows == 0 ? 0.0 : static_cast<double>(holdout_right) / holdout_rows;
  }
  // The index of `label` in labels, or -1.
  int ClassOf(absl::string_view label) const;

  // A versioned encoding of everything above (the classifier's own inside); Parse(Serialize())
  // is equal. DataLoss for bytes that are not a head.
  std::string Serialize() const;
  static absl::StatusOr<GalleryHead> Parse(absl::string_view bytes);
};

// A hash of a snapshot's sample ids and labels in training order. O(samples).
uint64_t SamplesFingerprint(const GallerySnapshot& snapshot);

// The vectors a fit of `snapshot` reads: min(its vectors, about options.max_vectors).
int64_t FitVectors(const GallerySnapshot& snapshot, const HeadOptions& options);

// Fits a head over `snapshot`'s vectors. FailedPrecondition when the gallery has fewer than
// options.min_samples samples or fewer than two labels (kNN answers it alone); InvalidArgument
// for bad options; what `progress` returns when it stops the fit. Deterministic for one
// snapshot and options. Runs on the calling thread: O(epochs * rows * parameters).
absl::StatusOr<GalleryHead> FitGalleryHead(const GallerySnapshot& snapshot,
                                           const HeadOptions& options,
                                           const FitProgress& progress = nullptr);

}  // namespace shapeid

#endif  // SHAPEID_CORE_GALLERY_GALLERY_HEAD_H_
