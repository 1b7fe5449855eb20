#include "core/rigid_transform.h"

#include <cmath>
#include <limits>

#include "Eigen/Geometry"
#include "absl/strings/str_cat.h"

namespace shapeid {
namespace {

constexpr double kRotationTolerance = 1e-3;

RigidTransform FromEigen(const Eigen::Matrix3d& r, const Eigen::Vector3d& t) {
  RigidTransform out;
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) out.rotation[3 * i + j] = static_cast<float>(r(i, j));
    out.translation[i] = static_cast<float>(t(i));
  }
  return out;
}

}  // namespace

bool RigidTransform::is_identity() const {
  return rotation == RigidTransform().rotation && translation == RigidTransform().translation;
}

absl::StatusOr<RigidTransform> RigidTransformFromRows(absl::Span<const double> rows) {
  if (rows.size() != 12) {
    return absl::InvalidArgumentError(absl::StrCat("sensor transform: ", rows.size(),
                                                   " numbers; expected 12 (the rows of [R | t])"));
  }
  Eigen::Matrix3d r;
  Eigen::Vector3d t;
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 4; ++j) {
      const double v = rows[4 * i + j];
      if (!std::isfinite(v)) {
        return absl::InvalidArgumentError(
            absl::StrCat("sensor transform: row ", i, " column ", j, " is not finite"));
      }
      // The points are moved in float32: a number that is infinite there would make every
      // point non-finite, and the error would then blame the points.
      if (std::abs(v) > std::numeric_limits<float>::max()) {
        return absl::InvalidArgumentError(absl::StrCat(
            "sensor transform: row ", i, " column ", j, " (transform[", 4 * i + j, "]) is ", v,
            ", beyond float32's range (|value| <= ", std::numeric_limits<float>::max(),
            "); the points are moved in float32"));
      }
      if (j < 3) {
        r(i, j) = v;
      } else {
        t(i) = v;
      }
    }
  }
  const double off_orthonormal =
      (r * r.transpose() - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
  if (off_orthonormal > kRotationTolerance) {
    return absl::InvalidArgumentError(
        absl::StrCat("sensor transform: R is not a rotation (R R^T differs from I by ",
                     off_orthonormal, "; scaling and shear are not rigid)"));
  }
  if (r.determinant() < 0) {
    return absl::InvalidArgumentError(
        "sensor transform: R has determinant -1, a reflection (it would mirror the object)");
  }
  return FromEigen(r, t);
}

absl::StatusOr<RigidTransform> RotationTakingUpTo(absl::Span<const double> up,
                                                  const std::array<float, 3>& target) {
  if (up.size() != 3) {
    return absl::InvalidArgumentError(
        absl::StrCat("sensor up: ", up.size(), " numbers; expected 3 (x, y, z)"));
  }
  const Eigen::Vector3d u(up[0], up[1], up[2]);
  // stableNorm: the squared norm of (1e200, 0, 0) is infinite and that of (1e-200, 0, 0) zero.
  if (!u.allFinite() || !(u.stableNorm() > 0)) {
    return absl::InvalidArgumentError(
        absl::StrCat("sensor up: (", up[0], ", ", up[1], ", ", up[2],
                     ") is not a direction (zero length or not finite)"));
  }
  const Eigen::Vector3d to = Eigen::Vector3d(target[0], target[1], target[2]).normalized();
  const Eigen::Quaterniond q = Eigen::Quaterniond::FromTwoVectors(u.stableNormalized(), to);
  return FromEigen(q.toRotationMatrix(), Eigen::Vector3d::Zero());
}

void ApplyRigidTransform(const RigidTransform& transform, float* xyz, size_t points) {
  const std::array<float, 9>& r = transform.rotation;
  const std::array<float, 3>& t = transform.translation;
  for (size_t i = 0; i < points; ++i, xyz += 3) {
    const float x = xyz[0], y = xyz[1], z = xyz[2];
    xyz[0] = r[0] * x + r[1] * y + r[2] * z + t[0];
    xyz[1] = r[3] * x + r[4] * y + r[5] * z + t[1];
    xyz[2] = r[6] * x + r[7] * y + r[8] * z + t[2];
  }
}

}  // namespace shapeid
