#include "core/views/view_directions.h"

#include <algorithm>
#include <cmath>

#include "Eigen/Geometry"
#include "absl/strings/str_cat.h"

namespace shapeid {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kGoldenAngleDeg = 180.0 * (3.0 - 2.2360679774997896964);  // 137.5...

}  // namespace

absl::StatusOr<std::vector<Eigen::Vector3d>> ViewDirections(size_t n, const Eigen::Vector3d& up,
                                                            double min_elevation_deg,
                                                            double max_elevation_deg,
                                                            double azimuth_offset_deg) {
  if (!up.allFinite() || up.squaredNorm() == 0) {
    return absl::InvalidArgumentError(absl::StrCat("view up vector (", up.x(), ", ", up.y(), ", ",
                                                   up.z(), ") must be finite and non-zero"));
  }
  if (!(min_elevation_deg >= -90 && min_elevation_deg <= max_elevation_deg &&
        max_elevation_deg <= 90)) {
    return absl::InvalidArgumentError(
        absl::StrCat("view elevations [", min_elevation_deg, ", ", max_elevation_deg,
                     "] degrees must satisfy -90 <= min <= max <= 90"));
  }
  if (!std::isfinite(azimuth_offset_deg)) {
    return absl::InvalidArgumentError(
        absl::StrCat("view azimuth offset ", azimuth_offset_deg, " must be finite"));
  }
  const Eigen::Vector3d axis = up.normalized();
  // Azimuth 0: +z made perpendicular to `up`, or +x when `up` is along z.
  Eigen::Vector3d e1 = Eigen::Vector3d::UnitZ() - axis.z() * axis;
  if (e1.norm() < 1e-6) e1 = Eigen::Vector3d::UnitX() - axis.x() * axis;
  e1.normalize();
  const Eigen::Vector3d e2 = axis.cross(e1);  // azimuth 90: a right-handed turn about `up`
  const double s0 = std::sin(min_elevation_deg * kPi / 180);
  const double s1 = std::sin(max_elevation_deg * kPi / 180);
  std::vector<Eigen::Vector3d> directions;
  directions.reserve(n);
  for (size_t i = 0; i < n; ++i) {
    // Equal steps in sin(elevation) are equal areas of the sphere (Archimedes).
    const double s = s0 + (s1 - s0) * (static_cast<double>(i) + 0.5) / static_cast<double>(n);
    const double c = std::sqrt(std::max(0.0, 1 - s * s));
    const double azimuth =
        std::fmod(static_cast<double>(i) * kGoldenAngleDeg + azimuth_offset_deg, 360.0) * kPi / 180;
    directions.push_back(
        (c * (std::cos(azimuth) * e1 + std::sin(azimuth) * e2) + s * axis).normalized());
  }
  return directions;
}

}  // namespace shapeid
