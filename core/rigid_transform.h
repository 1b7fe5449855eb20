#ifndef SHAPEID_CORE_RIGID_TRANSFORM_H_
#define SHAPEID_CORE_RIGID_TRANSFORM_H_

// A rotation and translation applied to points before they are described: how a caller's
// sensor frame becomes the frame a gallery was trained in (proto SensorFrame).

#include <array>
#include <cstddef>

#include "absl/status/statusor.h"
#include "absl/types/span.h"

namespace shapeid {

struct RigidTransform {
  std::array<float, 9> rotation = {1, 0, 0, 0, 1, 0, 0, 0, 1};  // row-major
  std::array<float, 3> translation = {0, 0, 0};

  bool is_identity() const;
};

// From the 12 numbers of [R | t], row after row. InvalidArgument unless there are 12, all
// finite and within float32's range (the points are moved in float32), and R is a rotation:
// orthonormal within 1e-3 and of determinant +1 (a reflection would mirror the object).
absl::StatusOr<RigidTransform> RigidTransformFromRows(absl::Span<const double> rows);

// The smallest rotation that turns the direction `up` (3 numbers, any length > 0) onto
// `target` (a unit vector). InvalidArgument for a zero-length or non-finite `up`. Opposite
// directions turn by half a turn about an axis perpendicular to `target`.
absl::StatusOr<RigidTransform> RotationTakingUpTo(absl::Span<const double> up,
                                                  const std::array<float, 3>& target);

// p' = R p + t for `points` points packed x y z in `xyz`, in place.
void ApplyRigidTransform(const RigidTransform& transform, float* xyz, size_t points);

}  // namespace shapeid

#endif  // SHAPEID_CORE_RIGID_TRANSFORM_H_
