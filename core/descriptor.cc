#include "core/descriptor.h"

#include <cmath>

#include "absl/strings/str_cat.h"
#include "core/status_macros.h"

namespace shapeid {

namespace {

// Every descriptor guards its divisions; this is the last line of defence that keeps a NaN
// out of a gallery, where it would poison every distance.
absl::Status CheckFinite(const DescriptorSpec& spec, const PointCloud& cloud,
                         absl::Span<const float> values) {
  for (size_t i = 0; i < values.size(); ++i) {
    if (!std::isfinite(values[i])) {
      return absl::InternalError(absl::StrCat(spec.ToString(), " produced a non-finite value at ",
                                              "index ", i, " for a ", cloud.size(),
                                              "-point cloud; please report this cloud"));
    }
  }
  return absl::OkStatus();
}

}  // namespace

absl::Status Descriptor::Compute(const PointCloud& cloud, std::vector<float>* out,
                                 const CloudLimits& limits) const {
  SHAPEID_ASSIGN_OR_RETURN(const CloudStats stats, ValidateCloud(cloud, limits));
  out->resize(dimension_);
  SHAPEID_RETURN_IF_ERROR(ComputeValidated(cloud, stats, limits, absl::MakeSpan(*out)));
  return CheckFinite(spec_, cloud, *out);
}

absl::Status Descriptor::ComputeWithPoseVariants(const PointCloud& cloud, std::vector<float>* out,
                                                 std::vector<float>* variants,
                                                 const CloudLimits& limits) const {
  SHAPEID_ASSIGN_OR_RETURN(const CloudStats stats, ValidateCloud(cloud, limits));
  out->resize(dimension_);
  variants->clear();
  SHAPEID_RETURN_IF_ERROR(
      ComputeValidatedWithPoseVariants(cloud, stats, limits, absl::MakeSpan(*out), variants));
  if (variants->size() % dimension_ != 0) {
    return absl::InternalError(absl::StrCat(spec_.ToString(), " produced ", variants->size(),
                                            " pose-variant values, not a multiple of ",
                                            dimension_));
  }
  SHAPEID_RETURN_IF_ERROR(CheckFinite(spec_, cloud, *out));
  return CheckFinite(spec_, cloud, *variants);
}

absl::StatusOr<std::vector<float>> Descriptor::Compute(const PointCloud& cloud,
                                                       const CloudLimits& limits) const {
  std::vector<float> out;
  SHAPEID_RETURN_IF_ERROR(Compute(cloud, &out, limits));
  return out;
}

}  // namespace shapeid
