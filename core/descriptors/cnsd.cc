// CNSD-3D (docs/descriptors.md section 3; dissertation chapter 5 and 8.2).
//
// Readings of points the spec and the dissertation leave open:
//  - Comparison. "w_ij <= T" is decided once, in squared form: the pair's float squared
//    distance (dx*dx + dy*dy) + dz*dz on the normalized coordinates (bounding-box center
//    subtracted, scaled by a power of two) against the largest float <= T*T*d_max^2 (double).
//    d_max^2 is the largest float squared distance, so T = 1 joins the farthest pair exactly.
//    Every kernel (scalar, AVX2, AVX-512) computes the same floats and makes the same exact
//    comparison, so they agree bit for bit.
//  - Thresholds are t_start + k * t_step (multiplied, not accumulated); one within 1e-9 of
//    t_end is snapped to t_end, so 0.3 + 2 * 0.35 is exactly 1, not 0.99999999999999989.
//  - t_start may be 0 (the dissertation says T_start >= 0; at 0 only coincident points are
//    joined) and may equal t_end (one threshold; the text asks T_end > T_start, which only
//    rules out a useless corner).
//  - n, the degree divisor, is the number of vertices of the graph, i.e. after downsampling.
//    No self-loops; distinct vertices at the same position have distance 0 and are joined.
//    D_avg = sum of degrees / n^2 and D_max = max degree / n, in double, rounded to float.
//  - max_points >= 8, not 3: a box grid anchored at the minimum with cells as large as the
//    widest extent has at most 8 occupied cells and still separates the two ends of that
//    axis; below 8, some clouds (a cube's corners) only fit in one cell, a one-vertex graph.
//  - Box grid filter: cubic cells (one leaf size for all axes), as a box grid filter does;
//    the paper reduced clouds over 8000 points "to 7000 to 8000" and we keep as many cells as
//    the leaf-size search finds, never more than max_points. Random: the paper's RPR removed
//    60% of every cloud; here, like the box filter, it only runs when n > max_points and
//    keeps exactly max_points points.
//
// This file: thresholds, normalization, the features from the pair passes, the spec and the
// registry entry. The pair passes are in cnsd_kernels.cc, downsampling in cnsd_downsample.cc.
#include "core/descriptors/cnsd.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "absl/strings/str_cat.h"
#include "core/descriptors/cnsd_downsample.h"
#include "core/descriptors/cnsd_kernels.h"
#include "core/descriptors/cost_model.h"
#include "core/enum_names.h"
#include "core/status_macros.h"

namespace shapeid {
namespace cnsd_internal {
namespace {}  // namespace

std::vector<double> Thresholds(double t_start, double t_end, double t_step) {
  std::vector<double> thresholds;
  if (!(t_step > 0)) return thresholds;
  for (size_t k = 0;; ++k) {
    double t = t_start + static_cast<double>(k) * t_step;
    if (t > t_end + 1e-9) break;
    if (std::fabs(t - t_end) <= 1e-9) t = t_end;
    thresholds.push_back(t);
  }
  return thresholds;
}

std::vector<float> NormalizedXyz(const PointCloud& cloud) {
  const size_t n = cloud.size();
  const float* xyz = cloud.data();
  double lo[3], hi[3];
  for (int a = 0; a < 3; ++a) lo[a] = hi[a] = n > 0 ? xyz[a] : 0.0f;
  for (size_t i = 0; i < n; ++i) {
    for (int a = 0; a < 3; ++a) {
      lo[a] = std::min(lo[a], static_cast<double>(xyz[3 * i + a]));
      hi[a] = std::max(hi[a], static_cast<double>(xyz[3 * i + a]));
    }
  }
  double center[3];
  double radius = 0;
  for (int a = 0; a < 3; ++a) {
    center[a] = 0.5 * (lo[a] + hi[a]);
    radius = std::max({radius, hi[a] - center[a], center[a] - lo[a]});
  }
  int exponent = 0;
  if (radius > 0) std::frexp(radius, &exponent);  // radius = f * 2^exponent, f in [0.5, 1)
  std::vector<float> out(3 * n);
  for (size_t i = 0; i < 3 * n; ++i) {
    out[i] = static_cast<float>(std::ldexp(xyz[i] - center[i % 3], -exponent));
  }
  return out;
}

float SquaredThreshold(double t, float max_d2) {
  const double exact = t * t * static_cast<double>(max_d2);
  float bound = static_cast<float>(exact);
  if (static_cast<double>(bound) > exact) {
    bound = std::nextafter(bound, -std::numeric_limits<float>::infinity());
  }
  return bound;
}

absl::Status ComputeFeatures(const PointCloud& cloud, absl::Span<const double> thresholds,
                             SimdLevel level, absl::Span<float> out) {
  const size_t n = cloud.size();
  const size_t num_thresholds = thresholds.size();
  if (out.size() != 2 * num_thresholds || num_thresholds == 0) {
    return absl::InternalError(
        absl::StrCat("cnsd: ", num_thresholds, " thresholds but ", out.size(), " output values"));
  }
  if (n < 2) {
    return absl::InvalidArgumentError(
        absl::StrCat("cnsd: a network needs at least 2 points; the cloud has ", n));
  }
  level = std::min(level, DetectedSimdLevel());
  const std::vector<float> xyz = NormalizedXyz(cloud);
  const float max_d2 = MaxSquaredDistance(xyz, level);
  if (!(max_d2 > 0)) {
    return absl::InvalidArgumentError(
        absl::StrCat("cnsd: all ", n, " points coincide, so no distance can be normalized"));
  }

  std::vector<float> bounds(num_thresholds);
  for (size_t k = 0; k < num_thresholds; ++k) bounds[k] = SquaredThreshold(thresholds[k], max_d2);
  // a = sqrt(d2) / d_max / t_step - t_start / t_step + 0.5 (see BucketRule).
  const double step = num_thresholds > 1 ? thresholds[1] - thresholds[0] : 1.0;
  const double per_distance = 1.0 / (std::sqrt(static_cast<double>(max_d2)) * step);
  // That approximation needs thresholds evenly spaced at least 1e-4 apart, as Thresholds()
  // makes them for every valid spec; anything else takes the scalar kernel, exact regardless.
  bool evenly_spaced = num_thresholds == 1 || step >= 1e-4;
  for (size_t k = 0; k < num_thresholds; ++k) {
    evenly_spaced &=
        std::fabs(thresholds[k] - (thresholds[0] + static_cast<double>(k) * step)) <= 1e-3 * step;
  }
  const BucketRule rule{bounds, static_cast<float>(per_distance),
                        static_cast<float>(0.5 - thresholds[0] / step), evenly_spaced};

  std::vector<uint64_t> degree_sum(num_thresholds);
  std::vector<uint64_t> degree_max(num_thresholds);
  DegreeStatistics(xyz, rule, level, absl::MakeSpan(degree_sum), absl::MakeSpan(degree_max));
  const double nd = static_cast<double>(n);
  for (size_t k = 0; k < num_thresholds; ++k) {
    out[2 * k] = static_cast<float>(static_cast<double>(degree_sum[k]) / (nd * nd));
    out[2 * k + 1] = static_cast<float>(static_cast<double>(degree_max[k]) / nd);
  }
  return absl::OkStatus();
}

}  // namespace cnsd_internal

namespace {

enum class Downsample { kVoxel, kRandom };

constexpr EnumNames<Downsample, 2> kDownsampleNames = {{
    {Downsample::kVoxel, "voxel"},
    {Downsample::kRandom, "random"},
}};

class CnsdDescriptor final : public Descriptor {
 public:
  CnsdDescriptor(DescriptorSpec spec, std::vector<double> thresholds, size_t max_points,
                 Downsample downsample, uint64_t seed)
      : Descriptor(std::move(spec), 2 * thresholds.size()),
        thresholds_(std::move(thresholds)),
        max_points_(max_points),
        downsample_(downsample),
        seed_(seed) {}

  DescribeCost EstimateCost(size_t num_points) const override {
    // CPU: downsampling is per point (the box grid's cell-size search counts cells some 22
    // times); the network, per vertex and per pair of vertices. Constants:
    // docs/performance.md, "Describe cost".
    constexpr double kNsBase = 20000, kNsPerVoxelPoint = 100, kNsPerRandomPoint = 1,
                     kNsPerVertex = 100, kNsPerPackedPair = 0.4, kNsPerScatterPair = 6;
    const size_t s = thresholds_.size();
    const bool downsampled = num_points > max_points_;
    const double m = static_cast<double>(std::min(num_points, max_points_));
    // Up to 31 thresholds each pair i < j is measured once; beyond, from both ends.
    double ns = kNsBase + kNsPerVertex * m +
                (s + 1 <= 32 ? kNsPerPackedPair * m * m / 2 : kNsPerScatterPair * m * m);
    if (downsampled) {
      ns += (downsample_ == Downsample::kVoxel ? kNsPerVoxelPoint : kNsPerRandomPoint) *
            static_cast<double>(num_points);
    }
    DescribeCost cost;
    cost.cpu = cost_model::Nanoseconds(ns);
    // The reduced cloud and the normalized coordinates stay while the pair passes run.
    const size_t downsampling = !downsampled ? 0
                                : downsample_ == Downsample::kVoxel
                                    ? cnsd_internal::VoxelDownsampleBytes(num_points, max_points_)
                                    : cnsd_internal::RandomDownsampleBytes(num_points, max_points_);
    const size_t vertices = std::min(num_points, max_points_);
    const size_t network = (downsampled ? 3 * vertices * sizeof(float) : 0)  // reduced cloud
                           + 3 * vertices * sizeof(float)                    // NormalizedXyz
                           + cnsd_internal::PairPassBytes(vertices, s) +
                           s * (sizeof(float) + 2 * sizeof(uint64_t));  // bounds, degrees
    cost.working_bytes =
        std::max(downsampling, network) + dimension() * sizeof(float) + cost_model::kHeapSlack;
    return cost;
  }

 protected:
  absl::Status ComputeValidated(const PointCloud& cloud, const CloudStats& /*stats*/,
                                const CloudLimits& /*limits*/,
                                absl::Span<float> out) const override {
    if (cloud.size() <= max_points_) {
      return cnsd_internal::ComputeFeatures(cloud, thresholds_, ActiveSimdLevel(), out);
    }
    const PointCloud reduced = downsample_ == Downsample::kVoxel
                                   ? cnsd_internal::VoxelDownsample(cloud, max_points_)
                                   : cnsd_internal::RandomDownsample(cloud, max_points_, seed_);
    const absl::Status status =
        cnsd_internal::ComputeFeatures(reduced, thresholds_, ActiveSimdLevel(), out);
    if (status.ok()) return status;
    return absl::Status(status.code(),
                        absl::StrCat(status.message(), " (after downsampling ", cloud.size(),
                                     " points to ", reduced.size(), ")"));
  }

 private:
  std::vector<double> thresholds_;
  size_t max_points_;
  Downsample downsample_;
  uint64_t seed_;
};

absl::StatusOr<std::unique_ptr<Descriptor>> CreateCnsd(const DescriptorSpec& filled) {
  const SpecParams params(filled);
  SHAPEID_ASSIGN_OR_RETURN(const double t_start, params.Double("t_start", 0.0, 1.0));
  SHAPEID_ASSIGN_OR_RETURN(const double t_end, params.Double("t_end", 0.0, 1.0));
  SHAPEID_ASSIGN_OR_RETURN(const double t_step, params.Double("t_step", 1e-4, 1.0));
  SHAPEID_ASSIGN_OR_RETURN(const int64_t max_points, params.Int("max_points", 8, 100000));
  SHAPEID_ASSIGN_OR_RETURN(const Downsample downsample,
                           params.Choice("downsample", kDownsampleNames));
  SHAPEID_ASSIGN_OR_RETURN(const int64_t seed,
                           params.Int("seed", 0, std::numeric_limits<int64_t>::max()));
  if (t_start > t_end) {
    return absl::InvalidArgumentError(
        absl::StrCat("cnsd: t_start=", FormatSpecNumber(t_start),
                     " is greater than t_end=", FormatSpecNumber(t_end)));
  }
  std::vector<double> thresholds = cnsd_internal::Thresholds(t_start, t_end, t_step);
  DescriptorSpec canonical{"cnsd",
                           {{"t_start", FormatSpecNumber(t_start)},
                            {"t_end", FormatSpecNumber(t_end)},
                            {"t_step", FormatSpecNumber(t_step)},
                            {"max_points", absl::StrCat(max_points)},
                            {"downsample", std::string(NameOf(kDownsampleNames, downsample))},
                            {"seed", absl::StrCat(seed)}}};
  return std::unique_ptr<Descriptor>(new CnsdDescriptor(std::move(canonical), std::move(thresholds),
                                                        static_cast<size_t>(max_points), downsample,
                                                        static_cast<uint64_t>(seed)));
}

}  // namespace

DescriptorKind CnsdKind() {
  return {
      "cnsd",
      "complex network shape descriptor (CNSD-3D): mean and maximum vertex degree / n of "
      "the graph joining points at most T * d_max apart, for each threshold T",
      {{"t_start", "0.05", "first threshold T_0, a fraction of the largest distance; in [0, 1]"},
       {"t_end", "0.95", "last threshold (inclusive, 1e-9 slack); in [t_start, 1]"},
       {"t_step", "0.05",
        "threshold step; in [0.0001, 1] (at most 10001 thresholds; dimension 2 per threshold)"},
       {"max_points", "8000",
        "larger clouds are downsampled first (O(n^2) pairs); integer in [8, 100000]"},
       {"downsample", "voxel",
        "voxel (box grid filter: one centroid per occupied cell, cell size searched) | "
        "random (seeded subset of exactly max_points points)"},
       {"seed", "0", "seed of random downsampling; integer in [0, 2^63 - 1]"}},
      CreateCnsd};
}

}  // namespace shapeid
