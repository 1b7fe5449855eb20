#ifndef SHAPEID_CORE_DESCRIPTORS_LEARNED_H_
#define SHAPEID_CORE_DESCRIPTORS_LEARNED_H_

// The `learned` descriptor: the embedding of a cloud by a point network trained apart from
// the product (learn/), shipped inside the binary and named by the spec
// (`learned:model=pointnet-box-v1`). The cloud is laid in DFSD's frame (box: any pose;
// upright: gravity known), scaled to its box, subsampled to the network's points and
// embedded; the vector has unit length, so kNN distances compare directions.

#include <cstdint>
#include <string>
#include <vector>

#include "Eigen/Core"
#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "core/descriptor_registry.h"
#include "core/descriptors/point_network.h"
#include "core/point_cloud.h"

namespace shapeid {

DescriptorKind LearnedKind();

// The model a `learned` spec names by default.
inline constexpr char kDefaultPointNetwork[] = "pointnet-box-v1";

// The networks built into this binary, by name (shipped files under core/descriptors/models/).
// NotFound naming the shipped ones for any other name.
absl::StatusOr<const PointNetwork*> ShippedPointNetwork(absl::string_view name);
std::vector<std::string> ShippedPointNetworkNames();

// A cloud as a point network reads it, and where its frame was a guess.
struct CanonicalPoints {
  // 3 x m, m = min(n, max_points): the points in the frame, about the center of the frame's
  // box, divided by the box's largest half extent (so in [-1, 1]); a cloud of more points is
  // subsampled by a fixed stride (point floor(i n / m) for i < m).
  Eigen::Matrix3Xf points;
  // Bit a (a < 3): axis a's direction is a guess (its skewness is below DFSD's tolerance).
  // Bit 3: axes 0 and 1 may come in either order (extents within DFSD's tolerance); bit 4:
  // axes 1 and 2. The upright frame's vertical is never a guess. Training augments exactly
  // these guesses (learn/), so the network answers alike whichever way they fell.
  uint32_t ambiguous = 0;
  // The frame's box: its extent along each frame axis, in the cloud's units.
  Eigen::Vector3d extent = Eigen::Vector3d::Zero();
};
inline constexpr uint32_t kAmbiguousSwap01 = 1u << 3;
inline constexpr uint32_t kAmbiguousSwap12 = 1u << 4;

// The canonical points of `cloud` (validated as Descriptor::Compute validates) for a network
// with `frame` and `max_points`: the one preparation shared by inference and by the tool that
// writes training data (learn/export_views), so the two can never disagree.
absl::StatusOr<CanonicalPoints> MakeCanonicalPoints(const PointCloud& cloud,
                                                    PointNetwork::Frame frame, uint32_t max_points);

}  // namespace shapeid

#endif  // SHAPEID_CORE_DESCRIPTORS_LEARNED_H_
