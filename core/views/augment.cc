#include "core/views/augment.h"

#include <cmath>
#include <optional>
#include <utility>

#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_replace.h"
#include "absl/strings/str_split.h"
#include "core/status_macros.h"

namespace shapeid {

absl::Status ValidateAugmentOptions(const AugmentOptions& options) {
  if (options.views < 0 || options.views > AugmentOptions::kMaxViews) {
    return absl::InvalidArgumentError(absl::StrCat(
        "augmentation: views ", options.views, " is outside [0, ", AugmentOptions::kMaxViews, "]"));
  }
  const SensorViewOptions& s = options.sensor;
  if (!(std::isfinite(s.noise_fraction) && s.noise_fraction >= 0 && s.noise_fraction <= 1)) {
    return absl::InvalidArgumentError(absl::StrCat("augmentation: noise ", s.noise_fraction,
                                                   " is outside [0, 1] (a fraction of the "
                                                   "object's extent)"));
  }
  if (s.min_points < 3 || s.min_points > s.max_points) {
    return absl::InvalidArgumentError(absl::StrCat("augmentation: points [", s.min_points, ", ",
                                                   s.max_points, "] must satisfy 3 <= min <= max"));
  }
  if (!(s.view.min_up >= -1 && s.view.min_up <= s.view.max_up && s.view.max_up <= 1)) {
    return absl::InvalidArgumentError(absl::StrCat("augmentation: viewpoint band [", s.view.min_up,
                                                   ", ", s.view.max_up,
                                                   "] must satisfy -1 <= min <= max <= 1"));
  }
  return absl::OkStatus();
}

std::string AugmentOptionsToString(const AugmentOptions& options) {
  if (!options.enabled()) return "off";
  const SensorViewOptions& s = options.sensor;
  return absl::StrCat("views=", options.views, ",noise=", s.noise_fraction,
                      ",points=", s.min_points, "-", s.max_points,
                      ",pose=", s.random_pose ? "random" : "fixed", ",seed=", options.seed,
                      options.mix == ViewMix::kCamera ? "" : ",mix=",
                      options.mix == ViewMix::kCamera ? "" : NameOf(kViewMixNames, options.mix));
}

absl::StatusOr<AugmentOptions> ParseAugmentOptions(absl::string_view text) {
  AugmentOptions options;
  if (text == "off" || text.empty()) return options;
  const auto bad = [&](absl::string_view item) {
    return absl::InvalidArgumentError(absl::StrCat(
        "augmentation \"", text, "\": cannot read \"", item,
        "\"; expected off or views=N,noise=F,points=MIN-MAX,pose=fixed|random,seed=S,mix=",
        absl::StrReplaceAll(NameList(kViewMixNames), {{", ", "|"}})));
  };
  for (absl::string_view item : absl::StrSplit(text, ',')) {
    const std::pair<absl::string_view, absl::string_view> kv = absl::StrSplit(item, '=');
    const absl::string_view key = kv.first, value = kv.second;
    if (key == "views") {
      if (!absl::SimpleAtoi(value, &options.views)) return bad(item);
    } else if (key == "noise") {
      if (!absl::SimpleAtod(value, &options.sensor.noise_fraction)) return bad(item);
    } else if (key == "points") {
      const std::pair<absl::string_view, absl::string_view> range = absl::StrSplit(value, '-');
      uint64_t lo = 0, hi = 0;
      if (!absl::SimpleAtoi(range.first, &lo) || !absl::SimpleAtoi(range.second, &hi)) {
        return bad(item);
      }
      options.sensor.min_points = static_cast<size_t>(lo);
      options.sensor.max_points = static_cast<size_t>(hi);
    } else if (key == "pose") {
      if (value != "fixed" && value != "random") return bad(item);
      options.sensor.random_pose = value == "random";
    } else if (key == "mix") {
      const std::optional<ViewMix> mix = ValueNamed(kViewMixNames, value);
      if (!mix) return bad(item);
      options.mix = *mix;
    } else if (key == "seed") {
      if (!absl::SimpleAtoi(value, &options.seed)) return bad(item);
    } else {
      return bad(item);
    }
  }
  SHAPEID_RETURN_IF_ERROR(ValidateAugmentOptions(options));
  return options;
}

absl::StatusOr<std::vector<PointCloud>> AugmentedViews(const PointCloud& cloud,
                                                       const AugmentOptions& options,
                                                       uint64_t cloud_seed) {
  SHAPEID_RETURN_IF_ERROR(ValidateAugmentOptions(options));
  std::vector<PointCloud> views;
  views.reserve(static_cast<size_t>(options.views));
  for (int i = 0; i < options.views; ++i) {
    const uint64_t seed = DeriveSeed(options.seed ^ cloud_seed, absl::StrCat("view", i));
    SensorViewOptions sensor = options.sensor;
    if (options.mix == ViewMix::kVaried) {
      constexpr Visibility kTurns[] = {Visibility::kCamera, Visibility::kPlaneCut,
                                       Visibility::kOccludedCamera};
      sensor.visibility = kTurns[i % 3];
      SplitMix64 noise_rng(DeriveSeed(seed, "noise"));
      sensor.noise_fraction = 2 * options.sensor.noise_fraction * noise_rng.Uniform();
    }
    SHAPEID_ASSIGN_OR_RETURN(PointCloud view, SensorView(cloud, sensor, seed));
    views.push_back(std::move(view));
  }
  return views;
}

}  // namespace shapeid
