#ifndef SHAPEID_CORE_GALLERY_GALLERY_OPTIONS_H_
#define SHAPEID_CORE_GALLERY_GALLERY_OPTIONS_H_

#include <cstddef>
#include <cstdint>
#include <string>

#include "absl/status/status.h"
#include "absl/strings/string_view.h"
#include "core/descriptor_registry.h"
#include "core/knn/knn_options.h"
#include "core/point_cloud.h"
#include "core/views/augment.h"

namespace shapeid {

// The label a classification answers when it rejects the query (see
// GalleryOptions::reject_distance). Reserved: no sample may carry it, in any gallery, so a
// client that only reads the label can never confuse "nobody trained this" with a class.
inline constexpr absl::string_view kUnknownLabel = "unknown";

// Longest label, in bytes.
inline constexpr size_t kMaxLabelBytes = 256;

// How one gallery describes and classifies. Fixed when the gallery is created.
struct GalleryOptions {
  // Descriptor spec text (core/descriptor_spec.h), e.g. "rphsd:bins=50". Canonicalised at
  // creation through the registry (every parameter present, defaults filled), so two
  // galleries with equal canonical specs compute identical descriptors. Default
  // kDefaultDescriptorSpec ("dfsd"): 240 floats per cloud with its defaults.
  std::string descriptor_spec = kDefaultDescriptorSpec;

  // Neighbors, vote weighting and feature scaling (core/knn/knn_options.h). Default k = 1,
  // uniform votes, no scaling: the published setting. Larger k smooths label noise but
  // blurs small classes.
  KnnOptions knn;

  // Open-set rejection. 0 (the default) turns it off: every query gets the nearest class.
  // When positive and the nearest neighbor is farther than this, the answer is
  // kUnknownLabel ("unknown") with confidence 0; the raw kNN result is still reported. The
  // distance is Neighbor::distance: Euclidean in the feature space of `knn.scaling`, so a
  // threshold is only meaningful for one descriptor spec and one scaling. Pick it from the
  // distribution of nearest-neighbor distances of known objects: too small rejects
  // known objects seen from a new angle, too large accepts objects nobody trained.
  double reject_distance = 0.0;

  // Training-time view augmentation (core/views/augment.h): each trained cloud also gets
  // `augment.views` synthetic single-view sensor scans, described and kept as views of the
  // same sample; a query matches each sample by its best view, and the k neighbors are
  // distinct samples, so one object's views cast one vote. Off by default. What a robot
  // needs when it sees one side of objects that were trained whole (docs/accuracy.md, robot
  // protocol: 50.7 -> 72.8 % with 8 views on ModelNet10), at the price of (1 + views) x the
  // memory and search time, and ~2 points on clean, whole-object queries. A Train stream may
  // override it for its own samples.
  AugmentOptions augment;
};

// Bounds a server puts on what it accepts; every violation is ResourceExhausted with the
// numbers in the message. The defaults admit the largest scans of the issue (2,000,000
// points) with headroom and cap memory at a few gigabytes for the default descriptor.
struct GalleryLimits {
  // Points per cloud, in every call that takes one (training, classifying, describing): the
  // server's one bound, --max_points_per_cloud. 10 million points is 120 MB of xyz and a few
  // seconds of describing: enough for a dense scan, small enough that one client cannot
  // exhaust the server's memory.
  size_t max_points_per_cloud = 10'000'000;
  // Samples per gallery: 1,000,000 x 240 floats (DFSD) = 960 MB of features.
  int64_t max_samples_per_gallery = 1'000'000;
  // Galleries per registry.
  size_t max_galleries = 1024;
  // When searches go approximate (core/knn/knn_options.h), for every gallery of the
  // registry: a server's setting, not a gallery's, since the lists are derived state rebuilt
  // from the stored vectors. Default: always exact (shapeid-server turns it on at 10^6
  // vectors). A Classify may still ask for an exact search.
  ApproximateOptions approximate;

  CloudLimits cloud_limits() const { return CloudLimits{max_points_per_cloud}; }
};

// InvalidArgument unless `name` matches [A-Za-z0-9][A-Za-z0-9_.-]{0,127}; the message quotes
// the pattern. Names are used as file names by future stores, hence the conservative set.
absl::Status ValidateGalleryName(absl::string_view name);

// The offset of the first byte of `text` that does not start a valid UTF-8 sequence (RFC
// 3629: no overlong forms, no surrogates), or npos when all of it is valid.
size_t InvalidUtf8Offset(absl::string_view text);

// `text` printable in an error message: quoted, C-escaped, cut at 64 bytes ("...").
std::string QuoteForMessage(absl::string_view text);

// InvalidArgument unless `label` is non-empty, at most kMaxLabelBytes bytes, valid UTF-8
// (RFC 3629: no overlong forms, no surrogates) and not kUnknownLabel.
absl::Status ValidateLabel(absl::string_view label);

// Checks everything but the descriptor spec (which the registry checks when it builds the
// descriptor): ValidateKnnOptions, and reject_distance finite and >= 0.
absl::Status ValidateGalleryOptions(const GalleryOptions& options);

}  // namespace shapeid

#endif  // SHAPEID_CORE_GALLERY_GALLERY_OPTIONS_H_
