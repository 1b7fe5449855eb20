#ifndef SHAPEID_CORE_VIEWS_AUGMENT_H_
#define SHAPEID_CORE_VIEWS_AUGMENT_H_

// Training-time view augmentation. A robot sees one side of an object, sparse and
// noisy; a gallery trained on whole, clean models matches such a view poorly however good
// the descriptor (a partial view's shape really is different). So each training cloud is
// also turned into synthetic sensor views (SensorView: one random viewpoint, noise,
// subsampling, optionally a random pose), and the gallery keeps their descriptors as views
// of the same sample: a query then finds the view of each trained object seen from nearly
// the same side. Seeded and deterministic: the same cloud, options and seed give the same
// views on every platform (perturb.h).

#include <cstdint>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "core/enum_names.h"
#include "core/point_cloud.h"
#include "core/views/perturb.h"

namespace shapeid {

// How a gallery's synthetic views are made.
enum class ViewMix {
  // Every view by the depth-camera simulator (Visibility::kCamera) with the configured noise:
  // the default, and what a stored text without `mix` means.
  kCamera,
  // More than one notion of "seen", so that the gallery does not learn one simulator's
  // signature: views take turns between the camera, a plane cut and an occluded camera
  // (view i: Visibility i mod 3), and each view's noise is drawn uniformly in [0, 2 x noise].
  kVaried,
};

inline constexpr EnumNames<ViewMix, 2> kViewMixNames = {{
    {ViewMix::kCamera, "camera"},
    {ViewMix::kVaried, "varied"},
}};

struct AugmentOptions {
  // Most synthetic views per training cloud.
  static constexpr int kMaxViews = 64;

  // Synthetic views per training cloud, besides the cloud itself; 0 turns augmentation off.
  int views = 0;
  // How each view is made. Default: a viewpoint anywhere on the sphere, 1 % noise, 300-500
  // points, no random pose (a rotation-invariant frame, DFSD's frame=box, makes poses
  // redundant; turn it on for descriptors that are not).
  SensorViewOptions sensor = [] {
    SensorViewOptions o;
    o.random_pose = false;
    return o;
  }();
  // Which visibility and noise models make the views.
  ViewMix mix = ViewMix::kCamera;
  // Mixed with each cloud's own seed (AugmentedViews), so two galleries with different seeds
  // get different views of the same cloud.
  uint64_t seed = 1;

  bool enabled() const { return views > 0; }
};

// InvalidArgument unless 0 <= views <= kMaxViews, the sensor options are valid (as
// SensorView checks them) and view.min_up <= view.max_up lie in [-1, 1].
absl::Status ValidateAugmentOptions(const AugmentOptions& options);

// A short, stable text of the options ("off", or e.g. "views=8,noise=0.01,points=300-500,
// pose=fixed,seed=1", with ",mix=varied" when the mix is not the camera's): what a gallery
// reports and stores. The viewpoint band and camera
// distance are not part of it: galleries always use SensorViewOptions' defaults for them.
std::string AugmentOptionsToString(const AugmentOptions& options);

// The inverse of AugmentOptionsToString (exact for its output; keys in any order, missing
// keys take the defaults). InvalidArgument for unknown keys or bad values, naming them.
absl::StatusOr<AugmentOptions> ParseAugmentOptions(absl::string_view text);

// The `options.views` synthetic views of `cloud`: view i is SensorView with the seed
// DeriveSeed(options.seed ^ cloud_seed, "view<i>") (ViewMix::kVaried: its visibility and, from
// the same seed, its noise as ViewMix says). Give each training cloud its own
// cloud_seed (a gallery uses the sample id) so its views differ from its neighbors'. A view
// that cannot be made (PartialView refuses a degenerate cloud) fails the call with
// SensorView's error; an empty vector when augmentation is off.
absl::StatusOr<std::vector<PointCloud>> AugmentedViews(const PointCloud& cloud,
                                                       const AugmentOptions& options,
                                                       uint64_t cloud_seed);

}  // namespace shapeid

#endif  // SHAPEID_CORE_VIEWS_AUGMENT_H_
