#include "core/knn/knn_options.h"

#include <string>

#include "absl/strings/str_cat.h"
#include "core/enum_names.h"

namespace shapeid {

namespace {

constexpr EnumNames<FeatureScaling, 3> kFeatureScalingNames = {{
    {FeatureScaling::kNone, "none"},
    {FeatureScaling::kZScore, "zscore"},
    {FeatureScaling::kMaxAbs, "maxabs"},
}};

constexpr EnumNames<VoteWeighting, 2> kVoteWeightingNames = {{
    {VoteWeighting::kUniform, "uniform"},
    {VoteWeighting::kDistance, "distance"},
}};

}  // namespace

absl::StatusOr<FeatureScaling> ParseFeatureScaling(absl::string_view text) {
  if (auto scaling = ValueNamed(kFeatureScalingNames, text)) return *scaling;
  return absl::InvalidArgumentError(absl::StrCat(
      "unknown feature scaling \"", text, "\"; expected one of ", NameList(kFeatureScalingNames)));
}

absl::string_view FeatureScalingName(FeatureScaling scaling) {
  return NameOf(kFeatureScalingNames, scaling);
}

absl::StatusOr<VoteWeighting> ParseVoteWeighting(absl::string_view text) {
  if (auto weighting = ValueNamed(kVoteWeightingNames, text)) return *weighting;
  return absl::InvalidArgumentError(absl::StrCat(
      "unknown vote weighting \"", text, "\"; expected one of ", NameList(kVoteWeightingNames)));
}

absl::string_view VoteWeightingName(VoteWeighting weighting) {
  return NameOf(kVoteWeightingNames, weighting);
}

absl::Status ValidateKnnOptions(const KnnOptions& options) {
  if (options.k < 1) {
    return absl::InvalidArgumentError(absl::StrCat("k must be at least 1, got ", options.k));
  }
  if (FeatureScalingName(options.scaling) == "unknown") {
    return absl::InvalidArgumentError(
        absl::StrCat("invalid feature scaling value ", static_cast<int>(options.scaling)));
  }
  if (VoteWeightingName(options.weighting) == "unknown") {
    return absl::InvalidArgumentError(
        absl::StrCat("invalid vote weighting value ", static_cast<int>(options.weighting)));
  }
  return absl::OkStatus();
}

absl::Status ValidateApproximateOptions(const ApproximateOptions& options) {
  if (options.min_vectors < 0 || options.lists < 0 || options.probes < 0) {
    return absl::InvalidArgumentError(absl::StrCat(
        "approximate search options must not be negative (min_vectors ", options.min_vectors,
        ", lists ", options.lists, ", probes ", options.probes, "); 0 picks the default"));
  }
  if (options.lists > ApproximateOptions::kMaxLists) {
    return absl::InvalidArgumentError(absl::StrCat("approximate search lists must be at most ",
                                                   ApproximateOptions::kMaxLists, ", got ",
                                                   options.lists));
  }
  return absl::OkStatus();
}

}  // namespace shapeid
