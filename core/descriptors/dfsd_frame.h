#ifndef SHAPEID_CORE_DESCRIPTORS_DFSD_FRAME_H_
#define SHAPEID_CORE_DESCRIPTORS_DFSD_FRAME_H_

// The frame DFSD lays its grid in (docs/descriptors.md section 5): the four frames, found from
// a cloud (the plane geometry of the box and upright frames is in dfsd_hull.h). Internal to
// core; exposed for dfsd.cc and tests.
//
// Working memory does not grow with the cloud: every frame reads the points in passes of
// kFramePassPoints and keeps sums, extremes and hulls, never a per-point array. Sums are added
// in the order Eigen added them when the frames held the whole cloud in one matrix, so every
// frame is the same to the last bit (dfsd_golden_test).

#include <cstddef>
#include <vector>

#include "Eigen/Core"
#include "core/descriptors/dfsd.h"
#include "core/descriptors/dfsd_hull.h"
#include "core/point_cloud.h"

namespace shapeid {
namespace dfsd_internal {

// Points per step of a pass over the cloud (even, so chunk columns keep the alignment they
// had in one matrix of all points).
inline constexpr size_t kFramePassPoints = 8192;

// The most heap CloudFrame::Find allocates for a cloud of n points (for hulls within
// StreamedHull::PeakBytes's allowance).
size_t FrameBytes(size_t n, DfsdOptions::Frame frame);

// A cloud's frame: its axes, and the box around the points along them.
class CloudFrame {
 public:
  // The frame `options.frame` chooses for a validated cloud (`stats` from ValidateCloud).
  // `hull_candidates` is for tests, which make it small to exercise the slabs.
  static CloudFrame Find(const PointCloud& cloud, const CloudStats& stats,
                         const DfsdOptions& options, size_t hull_candidates = kHullCandidates);

  // Coordinates of points [first, first + count) in the frame, relative to the center of the
  // box: axis a of point first + p goes to coord[a][p].
  void Coordinates(const PointCloud& cloud, size_t first, size_t count,
                   double* const coord[3]) const;

  // Columns: the frame's axes in input coordinates (the identity for frame=axes).
  const Eigen::Matrix3d& axes() const { return axes_; }
  // The center of the box, in frame coordinates about the centroid (frame=axes: input ones).
  const Eigen::Vector3d& center() const { return center_; }
  const Eigen::Vector3d& half_extent() const { return half_extent_; }
  // frame=box and upright: |third moment| / second moment^1.5 of the points along each axis,
  // about their centroid (0 for an axis without spread, infinite for the upright vertical,
  // whose sign is never a guess). Near 0, the axis's sign is a guess. 0 for pca and axes.
  const Eigen::Vector3d& skewness() const { return skewness_; }

 private:
  Eigen::Vector3d Rotated(const PointCloud& cloud, size_t p) const;

  bool input_axes_ = true;  // frame=axes: coordinates as given
  Eigen::Matrix3d axes_ = Eigen::Matrix3d::Identity();
  Eigen::Vector3d centroid_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d center_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d half_extent_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d skewness_ = Eigen::Vector3d::Zero();
};

// d d^T of a 3 x n matrix d given a few columns at a time, summed exactly as Eigen 3.4
// evaluates `d * d.transpose()` for the whole matrix: below 14 columns a loop over columns
// from the first product; from 14, a GEMM that sums each block of kc columns (kc from
// Eigen's blocking, which depends on the L1 cache it detects) from 0 and adds the block to
// the result.
class ScatterSum {
 public:
  explicit ScatterSum(size_t n);
  // The next columns of d, in order.
  void Add(const Eigen::Matrix3Xd& columns);
  // All n columns must have been added.
  Eigen::Matrix3d Sum();

 private:
  void Flush();

  bool coefficient_loop_;
  size_t block_;
  size_t seen_ = 0;
  size_t in_block_ = 0;
  double block_sum_[3][3] = {};
  double total_[3][3] = {};
};

// The sum of n doubles given one at a time, added as Eigen 3.4 sums a dynamic vector of
// them (`v.sum()`, 16-byte aligned, two doubles per SSE2 packet): four interleaved partial
// sums, folded in Eigen's order, then the odd last value.
class EigenOrderSum {
 public:
  explicit EigenOrderSum(size_t n) : n_(n), end4_(n / 4 * 4), end2_(n / 2 * 2) {}
  void Add(double v) {
    const size_t i = next_++;
    if (i < end4_) {
      lane_[i % 4] = i < 4 ? v : lane_[i % 4] + v;
    } else if (i < end2_) {
      pair_[i - end4_] = v;
    } else {
      last_ = v;
    }
  }
  // All n values must have been added.
  double Sum() const;

 private:
  size_t n_, end4_, end2_;
  size_t next_ = 0;
  double lane_[4] = {};
  double pair_[2] = {};
  double last_ = 0;
};

}  // namespace dfsd_internal
}  // namespace shapeid

#endif  // SHAPEID_CORE_DESCRIPTORS_DFSD_FRAME_H_
