#include "core/knn/knn_options.h"

#include <string>

#include "absl/strings/ascii.h"
#include "absl/strings/str_cat.h"

namespace shapeid {

absl::StatusOr<FeatureScaling> ParseFeatureScaling(absl::string_view text) {
  const std::string name = absl::AsciiStrToLower(absl::StripAsciiWhitespace(text));
  if (name == "none") return FeatureScaling::kNone;
  if (name == "zscore") return FeatureScaling::kZScore;
  if (name == "maxabs") return FeatureScaling::kMaxAbs;
  return absl::InvalidArgumentError(
      absl::StrCat("unknown feature scaling \"", text, "\"; expected one of none, zscore, maxabs"));
}

absl::string_view FeatureScalingName(FeatureScaling scaling) {
  switch (scaling) {
    case FeatureScaling::kNone:
      return "none";
    case FeatureScaling::kZScore:
      return "zscore";
    case FeatureScaling::kMaxAbs:
      return "maxabs";
  }
  return "unknown";
}

absl::StatusOr<VoteWeighting> ParseVoteWeighting(absl::string_view text) {
  const std::string name = absl::AsciiStrToLower(absl::StripAsciiWhitespace(text));
  if (name == "uniform") return VoteWeighting::kUniform;
  if (name == "distance") return VoteWeighting::kDistance;
  return absl::InvalidArgumentError(
      absl::StrCat("unknown vote weighting \"", text, "\"; expected one of uniform, distance"));
}

absl::string_view VoteWeightingName(VoteWeighting weighting) {
  switch (weighting) {
    case VoteWeighting::kUniform:
      return "uniform";
    case VoteWeighting::kDistance:
      return "distance";
  }
  return "unknown";
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
