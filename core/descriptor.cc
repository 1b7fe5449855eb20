#include "core/descriptor.h"

#include <cmath>

#include "absl/strings/str_cat.h"
#include "core/status_macros.h"

namespace shapeid {

absl::Status Descriptor::Compute(const PointCloud& cloud, std::vector<float>* out,
                                 const CloudLimits& limits) const {
  SHAPEID_ASSIGN_OR_RETURN(const CloudStats stats, ValidateCloud(cloud, limits));
  out->resize(dimension_);
  SHAPEID_RETURN_IF_ERROR(ComputeValidated(cloud, stats, absl::MakeSpan(*out)));
  // Every descriptor guards its divisions; this is the last line of defence that keeps a
  // NaN out of a gallery, where it would poison every distance.
  for (size_t i = 0; i < out->size(); ++i) {
    if (!std::isfinite((*out)[i])) {
      return absl::InternalError(absl::StrCat(spec_.ToString(), " produced a non-finite value at ",
                                              "index ", i, " for a ", cloud.size(),
                                              "-point cloud; please report this cloud"));
    }
  }
  return absl::OkStatus();
}

absl::StatusOr<std::vector<float>> Descriptor::Compute(const PointCloud& cloud,
                                                       const CloudLimits& limits) const {
  std::vector<float> out;
  SHAPEID_RETURN_IF_ERROR(Compute(cloud, &out, limits));
  return out;
}

}  // namespace shapeid
