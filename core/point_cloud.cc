#include "core/point_cloud.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>

#include "absl/strings/str_cat.h"

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace shapeid {

PointCloud::PointCloud(std::initializer_list<Eigen::Vector3f> points) {
  Reserve(points.size());
  for (const auto& p : points) Add(p);
}

double CloudStats::MaxAbsCentered() const {
  return std::max({max.x() - centroid.x(), centroid.x() - min.x(), max.y() - centroid.y(),
                   centroid.y() - min.y(), max.z() - centroid.z(), centroid.z() - min.z()});
}

namespace {

absl::Status NonFiniteError(const PointCloud& cloud) {
  for (size_t i = 0; i < cloud.size(); ++i) {
    const auto p = cloud.point(i);
    if (!p.allFinite()) {
      // Which axis and what it holds, not the point itself: errors reach server logs, which
      // carry no point data.
      const char* axis = !std::isfinite(p.x()) ? "x" : (!std::isfinite(p.y()) ? "y" : "z");
      const float bad = !std::isfinite(p.x()) ? p.x() : (!std::isfinite(p.y()) ? p.y() : p.z());
      return absl::InvalidArgumentError(
          absl::StrCat("point ", i, " has a non-finite coordinate (", axis, " is ", bad,
                       "); drop or repair non-finite points before describing the cloud"));
    }
  }
  return absl::InternalError("non-finite coordinate detected but not found again");
}

}  // namespace

absl::StatusOr<CloudStats> ValidateCloud(const PointCloud& cloud, const CloudLimits& limits) {
  const size_t n = cloud.size();
  if (cloud.xyz().size() % 3 != 0) {
    return absl::InvalidArgumentError(absl::StrCat("cloud holds ", cloud.xyz().size(),
                                                   " floats, not a whole number of xyz points"));
  }
  if (n < 3) {
    return absl::InvalidArgumentError(
        absl::StrCat("cloud has ", n, " point", n == 1 ? "" : "s", "; at least 3 are needed"));
  }
  if (n > limits.max_points) {
    return absl::ResourceExhaustedError(
        absl::StrCat("cloud has ", n, " points, more than the limit of ", limits.max_points));
  }

  // One pass over the floats: box, sum and a finiteness flag. Four points (12 floats) per
  // step into 12 independent accumulators, one per position, so the additions do not wait
  // on each other and the compiler can vectorise; position l always holds axis l % 3. Sums
  // are in double so a million points do not lose the centroid. The order of operations is
  // fixed, so the result is the same bits on every machine.
  constexpr size_t kLanes = 12;
  const float* xyz = cloud.data();
  const size_t num_floats = 3 * n;
  const size_t blocked = num_floats / kLanes * kLanes;
  double sum[kLanes] = {};
  float lo[kLanes], hi[kLanes];
  for (size_t l = 0; l < kLanes; ++l) lo[l] = hi[l] = xyz[l % 3];
  uint32_t nonfinite = 0;
#if defined(__SSE2__)
  // The same 12 lanes in SSE2 registers (part of every x86-64 CPU): three float vectors for
  // the box, six double vectors for the sums, lane for lane the order of the loop below.
  {
    __m128 vlo[3], vhi[3];
    __m128d vsum[6];
    for (int v = 0; v < 3; ++v) vlo[v] = vhi[v] = _mm_loadu_ps(lo + 4 * v);
    for (int v = 0; v < 6; ++v) vsum[v] = _mm_setzero_pd();
    const __m128i exponent = _mm_set1_epi32(0x7f800000);
    __m128i bad = _mm_setzero_si128();
    for (size_t b = 0; b < blocked; b += kLanes) {
      for (int v = 0; v < 3; ++v) {
        const __m128 x = _mm_loadu_ps(xyz + b + 4 * v);
        bad = _mm_or_si128(bad,
                           _mm_cmpeq_epi32(_mm_and_si128(_mm_castps_si128(x), exponent), exponent));
        vsum[2 * v] = _mm_add_pd(vsum[2 * v], _mm_cvtps_pd(x));
        vsum[2 * v + 1] = _mm_add_pd(vsum[2 * v + 1], _mm_cvtps_pd(_mm_movehl_ps(x, x)));
        vlo[v] = _mm_min_ps(x, vlo[v]);  // same operand order as `v < lo ? v : lo`
        vhi[v] = _mm_max_ps(x, vhi[v]);
      }
    }
    for (int v = 0; v < 3; ++v) {
      _mm_storeu_ps(lo + 4 * v, vlo[v]);
      _mm_storeu_ps(hi + 4 * v, vhi[v]);
    }
    for (int v = 0; v < 6; ++v) _mm_storeu_pd(sum + 2 * v, vsum[v]);
    nonfinite = static_cast<uint32_t>(_mm_movemask_epi8(bad) != 0);
  }
#else
  for (size_t b = 0; b < blocked; b += kLanes) {
    for (size_t l = 0; l < kLanes; ++l) {
      const float v = xyz[b + l];
      uint32_t bits;
      std::memcpy(&bits, &v, sizeof(bits));
      nonfinite |= static_cast<uint32_t>((bits & 0x7f800000u) == 0x7f800000u);  // inf or NaN
      sum[l] += v;
      lo[l] = v < lo[l] ? v : lo[l];
      hi[l] = v > hi[l] ? v : hi[l];
    }
  }
#endif
  for (size_t f = blocked; f < num_floats; ++f) {  // the last 0-3 points
    const size_t l = f % 3;
    const float v = xyz[f];
    nonfinite |= static_cast<uint32_t>(!std::isfinite(v));
    sum[l] += v;
    lo[l] = v < lo[l] ? v : lo[l];
    hi[l] = v > hi[l] ? v : hi[l];
  }
  const bool all_finite = nonfinite == 0;
  // Fold the lanes per axis, in a fixed order.
  for (size_t l = 3; l < kLanes; ++l) {
    sum[l % 3] += sum[l];
    lo[l % 3] = std::min(lo[l % 3], lo[l]);
    hi[l % 3] = std::max(hi[l % 3], hi[l]);
  }
  if (!all_finite) return NonFiniteError(cloud);
  if (lo[0] == hi[0] && lo[1] == hi[1] && lo[2] == hi[2]) {
    return absl::InvalidArgumentError(
        absl::StrCat("all ", n, " points are identical: the cloud has zero extent and no shape"));
  }

  CloudStats stats;
  stats.num_points = n;
  stats.min = Eigen::Vector3d(lo[0], lo[1], lo[2]);
  stats.max = Eigen::Vector3d(hi[0], hi[1], hi[2]);
  stats.centroid = Eigen::Vector3d(sum[0], sum[1], sum[2]) / static_cast<double>(n);
  return stats;
}

}  // namespace shapeid
