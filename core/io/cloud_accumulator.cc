#include "core/io/cloud_accumulator.h"

#include <cmath>
#include <limits>
#include <utility>

#include "absl/strings/str_cat.h"

namespace shapeid {

CloudAccumulator::CloudAccumulator(absl::string_view name, absl::string_view where_label)
    : name_(name), where_label_(where_label) {}

void CloudAccumulator::Add(double x, double y, double z, uint64_t where) {
  xyz_.push_back(x);
  xyz_.push_back(y);
  xyz_.push_back(z);
  if (!(std::isfinite(x) && std::isfinite(y) && std::isfinite(z))) return;
  const double p[3] = {x, y, z};
  if (finite_ == 0) {
    for (int a = 0; a < 3; ++a) {
      min_[a] = max_[a] = p[a];
      min_where_[a] = max_where_[a] = where;
    }
  } else {
    for (int a = 0; a < 3; ++a) {
      if (p[a] < min_[a]) {
        min_[a] = p[a];
        min_where_[a] = where;
      } else if (p[a] > max_[a]) {
        max_[a] = p[a];
        max_where_[a] = where;
      }
    }
  }
  ++finite_;
}

absl::StatusOr<ReadResult> CloudAccumulator::Finish(const ReadOptions& options) && {
  ReadResult result;
  if (options.recenter && finite_ > 0) {
    // Halves first: (min + max) can overflow a double; each half cannot.
    for (int a = 0; a < 3; ++a) result.offset[a] = min_[a] / 2 + max_[a] / 2;
  }
  // Only the extremes can overflow a float, so checking them checks every point.
  constexpr double kFloatMax = std::numeric_limits<float>::max();
  for (int a = 0; a < 3 && finite_ > 0; ++a) {
    const double hi = max_[a] - result.offset[a];
    const double lo = min_[a] - result.offset[a];
    if (hi > kFloatMax || lo < -kFloatMax) {
      const bool blame_hi = hi > kFloatMax;
      return absl::InvalidArgumentError(
          absl::StrCat(name_, ": ", where_label_, " ", blame_hi ? max_where_[a] : min_where_[a],
                       ": ", absl::string_view(&"xyz"[a], 1), " = ", blame_hi ? max_[a] : min_[a],
                       " does not fit in a float",
                       options.recenter ? " even after recentering" : " (recentering is off)"));
    }
  }

  const size_t n = size();
  const bool drop = options.drop_non_finite;
  std::vector<float> out;
  out.reserve(3 * (drop ? finite_ : n));
  const double ox = result.offset.x(), oy = result.offset.y(), oz = result.offset.z();
  for (size_t i = 0; i < n; ++i) {
    const double* p = &xyz_[3 * i];
    if (drop && !(std::isfinite(p[0]) && std::isfinite(p[1]) && std::isfinite(p[2]))) continue;
    out.push_back(static_cast<float>(p[0] - ox));
    out.push_back(static_cast<float>(p[1] - oy));
    out.push_back(static_cast<float>(p[2] - oz));
  }
  result.dropped_non_finite = drop ? n - finite_ : 0;
  result.cloud = PointCloud(std::move(out));
  return result;
}

}  // namespace shapeid
