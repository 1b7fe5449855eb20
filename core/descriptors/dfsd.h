#ifndef SHAPEID_CORE_DESCRIPTORS_DFSD_H_
#define SHAPEID_CORE_DESCRIPTORS_DFSD_H_

// DFSD, the Distance-Field Spectrum Shape Descriptor (docs/descriptors.md section 5): how far
// each cell of a G^3 grid over the object lies from its nearest point, seen through the
// low-frequency end of a 3D cosine transform. Not from the dissertation: shapeid's own
// descriptor, measured against the dissertation's on the same protocol in docs/accuracy.md.
//
// Why it works: a distance field is a dense, smooth function of the whole shape, so two
// samplings of one surface give nearly the same field (unlike histograms of point
// positions, which jump between bins), and its energy sits in a few low frequencies, so
// 120 cosine coefficients per field keep what separates classes in a vector short enough
// for a fast kNN search.

#include <array>
#include <cstdint>
#include <memory>
#include <vector>

#include "Eigen/Core"
#include "absl/status/statusor.h"
#include "core/descriptor_registry.h"

namespace shapeid {

// Registry entry: kind "dfsd"; parameters grid, order, frame, fields, size, up, smooth (see
// the entry's help lines). Canonical spec "dfsd:grid=12,order=8,frame=box,fields=both,size=0".
DescriptorKind DfsdKind();

struct DfsdOptions {
  // Cells per axis of the distance grid, G, in [kMinGrid, kMaxGrid].
  int grid = 12;
  // Cosine coefficients (a, b, c) kept per field: those with a + b + c < order, so a
  // low-pass of the field that treats the three axes alike. In [1, 3 * (grid - 1) + 1].
  int order = 8;
  // The frame the grid is laid in.
  enum class Frame {
    // The cloud's own axes: right for objects that arrive upright and aligned (CAD models,
    // gravity-aligned scans); the most accurate when that holds.
    kAxes,
    // The principal axes of the points (largest spread first), each axis pointing to the
    // side its points are skewed to, the third made right-handed. Any rotation of the input
    // gives the same frame, so the descriptor is rotation invariant, at some accuracy cost on
    // aligned data and with unstable axes where two spreads are nearly equal.
    kPca,
    // The axes of the tightest box around the points (principal axes refined by smallest
    // rectangles), largest extent first, each pointing to the side its points are skewed
    // to. Rotation and reflection invariant, and it lines up with the flat sides of man-made
    // objects where principal axes tilt. Where the frame is ambiguous (near-equal extents,
    // near-symmetric axes) ComputeWithPoseVariants also gives the descriptor in the other
    // plausible poses, and a gallery matches the best of them.
    kBox,
    // The vertical as given by `up` (the client's gravity, e.g. from a robot's IMU, or a
    // dataset's convention: y up for most meshes, z up for LiDAR); the horizontal axes the
    // sides of the smallest rectangle around the points seen from above, ordered by extent
    // and signed by skewness. Invariant to any yaw, and keeps which way is up, which the box
    // frame cannot know. Pose variants swap or flip the horizontal axes where the frame is
    // ambiguous; the vertical never moves.
    kUpright,
  };
  // kBox by default: a robot sees objects in any pose. On data known to be upright and
  // aligned kAxes or kUpright is more accurate (figures in docs/accuracy.md).
  Frame frame = Frame::kBox;
  // frame=upright only: which input axis points up. Spec values z (default), y, x, -z, -y,
  // -x. A cloud whose up is +y gives, with up=y, exactly the descriptor that the same cloud
  // turned to +z up gives with up=z: the axes are permuted, never resampled.
  enum class Up { kPlusZ, kPlusY, kPlusX, kMinusZ, kMinusY, kMinusX };
  Up up = Up::kPlusZ;
  // Which normalizations of the bounding box get a field.
  enum class Fields {
    kBoth,         // isotropic then anisotropic: shape and proportions, each seen both ways
    kIsotropic,    // one scale for all axes: keeps the proportions
    kAnisotropic,  // each axis to its own extent: proportions removed, layout kept
  };
  Fields fields = Fields::kBoth;
  // Weight of the size block: size * ln(extent) of the frame's three bounding-box extents,
  // largest first, appended. 0 (default) leaves it out. Only meaningful when all clouds of
  // a gallery share a unit (metric sensors: LiDAR, depth cameras); there 0.15 is a good start.
  double size_weight = 0;
  // Smoothing before describing: each point moved to the mean of its nearest points, this
  // share of the cloud (SmoothPoints, core/descriptors/point_smoothing.h), and the frame and
  // field taken of the moved points. 0 (default) leaves the points as they are. A gallery
  // and its queries agree through the spec. Figures: docs/accuracy.md, "Noise".
  double smooth = 0;
};

namespace dfsd_internal {

inline constexpr int kMinGrid = 4;
inline constexpr int kMaxGrid = 32;
inline constexpr int kSizeFeatures = 3;
// frame=box pose variants: two axes whose box extents differ by less than this fraction may
// come in either order, and an axis whose skewness is below kSkewnessTolerance may point
// either way. Chosen on ModelNet10 (docs/accuracy.md): wider tolerances try more poses
// (slower queries) for no measurable gain, narrower ones miss right poses.
inline constexpr double kAxisOrderTolerance = 0.2;
inline constexpr double kSkewnessTolerance = 0.3;

// The kept cosine frequencies (a, b, c), a along x: a + b + c < order, every index < grid;
// ordered by a + b + c, then a, then b (lowest frequencies first).
struct Frequency {
  int a, b, c;
};
std::vector<Frequency> KeptFrequencies(int grid, int order);

// Length of the descriptor.
size_t DfsdDimension(const DfsdOptions& options);

// The size block: weight * ln(extent) of a box's three extents, largest first, into
// out[0, kSizeFeatures). Also the learned descriptor's (docs/descriptors.md sections 5, 6).
void WriteSizeBlock(const Eigen::Vector3d& extent, double weight, float* out);

// How the descriptor changes when the object is described in another pose of its frame:
// new axis i is old axis axis_of[i] (a permutation of 0, 1, 2), reversed (about the box
// center) where bit i of `flips` is set. The new descriptor is
// value[q] = sign[q] * old[source[q]]: no recomputation.
void PoseMap(const DfsdOptions& options, const std::array<int, 3>& axis_of, int flips,
             std::vector<int>* source, std::vector<float>* sign);

absl::StatusOr<std::unique_ptr<Descriptor>> CreateDfsd(const DfsdOptions& options);

}  // namespace dfsd_internal
}  // namespace shapeid

#endif  // SHAPEID_CORE_DESCRIPTORS_DFSD_H_
