#include "core/views/perturb.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <tuple>
#include <utility>
#include <vector>

#include "absl/strings/ascii.h"
#include "absl/strings/match.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "core/fnv1a.h"
#include "core/status_macros.h"
#include "core/views/scan_simulator.h"

namespace shapeid {
namespace {

// Geometry written out coordinate by coordinate rather than through Eigen reductions, whose
// summation order may follow the SIMD width the compiler was allowed: these must give the
// same bits on every build.
double Dot(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return a.x() * b.x() + a.y() * b.y() + a.z() * b.z();
}

Eigen::Vector3d Cross(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return {a.y() * b.z() - a.z() * b.y(), a.z() * b.x() - a.x() * b.z(),
          a.x() * b.y() - a.y() * b.x()};
}

Eigen::Vector3d Unit(const Eigen::Vector3d& v) { return v / std::sqrt(Dot(v, v)); }

absl::Status CheckUp(const Eigen::Vector3d& up) {
  if (!up.allFinite() || Dot(up, up) == 0) {
    return absl::InvalidArgumentError(absl::StrCat("up vector (", up.x(), ", ", up.y(), ", ",
                                                   up.z(), ") must be finite and non-zero"));
  }
  return absl::OkStatus();
}

// (cos t, sin t) for t uniform in [0, 2 pi): a point uniform in the unit disc (rejection from
// the square, accepted with probability pi / 4), normalized. Points very near the center are
// rejected too, so that the direction keeps full precision.
Eigen::Vector2d UnitCircle(SplitMix64& rng) {
  for (;;) {
    const double x = 2 * rng.Uniform() - 1;
    const double y = 2 * rng.Uniform() - 1;
    const double s = x * x + y * y;
    if (s <= 1 && s > 0x1.0p-40) {
      const double r = std::sqrt(s);
      return {x / r, y / r};
    }
  }
}

// Natural logarithm of x > 0 (finite, normal) with basic operations only, to ~1 ulp:
// x = m 2^e with m in [sqrt(1/2), sqrt(2)), ln m = 2 atanh(t), t = (m - 1) / (m + 1),
// |t| <= 0.172, by its odd series to t^23 (the rest is below 1e-19 of the sum).
double PortableLog(double x) {
  int e = 0;
  double m = std::frexp(x, &e);  // exact; m in [0.5, 1)
  if (m < 0.70710678118654752440) {
    m *= 2;
    --e;
  }
  const double t = (m - 1) / (m + 1);
  const double t2 = t * t;
  double series = 1.0 / 23;
  for (int k = 21; k >= 1; k -= 2) series = 1.0 / k + t2 * series;
  constexpr double kLn2 = 0.69314718055994530942;
  return static_cast<double>(e) * kLn2 + 2 * t * series;
}

// Standard normal deviates by Marsaglia's polar method, both values of each pair used.
class NormalDeviates {
 public:
  explicit NormalDeviates(uint64_t seed) : rng_(seed) {}
  double Next() {
    if (has_spare_) {
      has_spare_ = false;
      return spare_;
    }
    for (;;) {
      const double u = 2 * rng_.Uniform() - 1;
      const double v = 2 * rng_.Uniform() - 1;
      const double s = u * u + v * v;
      if (s < 1 && s > 0) {
        const double f = std::sqrt(-2 * PortableLog(s) / s);
        spare_ = v * f;
        has_spare_ = true;
        return u * f;
      }
    }
  }

 private:
  SplitMix64 rng_;
  bool has_spare_ = false;
  double spare_ = 0;
};

uint32_t Bits(float f) {
  uint32_t b;
  std::memcpy(&b, &f, sizeof b);
  return b;
}

// The input points, in input order, that `seen` (exact copies of some of them) contains.
// Each seen point is matched to the first input point with its bits: a scan shows the first
// of identical points.
PointCloud InInputOrder(const PointCloud& cloud, const PointCloud& seen) {
  struct Key {
    uint32_t x, y, z;
    size_t index;
    bool operator<(const Key& o) const {
      return std::tie(x, y, z, index) < std::tie(o.x, o.y, o.z, o.index);
    }
  };
  std::vector<Key> keys(cloud.size());
  for (size_t i = 0; i < cloud.size(); ++i) {
    const float* p = cloud.data() + 3 * i;
    keys[i] = Key{Bits(p[0]), Bits(p[1]), Bits(p[2]), i};
  }
  std::sort(keys.begin(), keys.end());
  std::vector<bool> kept(cloud.size(), false);
  for (size_t j = 0; j < seen.size(); ++j) {
    const float* p = seen.data() + 3 * j;
    const Key probe{Bits(p[0]), Bits(p[1]), Bits(p[2]), 0};
    auto it = std::lower_bound(keys.begin(), keys.end(), probe);
    if (it != keys.end() && it->x == probe.x && it->y == probe.y && it->z == probe.z) {
      kept[it->index] = true;
    }
  }
  PointCloud out;
  out.Reserve(seen.size());
  for (size_t i = 0; i < cloud.size(); ++i) {
    if (kept[i]) out.Add(cloud.point(i));
  }
  return out;
}

constexpr char kPerturbationForms[] =
    "clean, yaw, rot3d, noise<percent of the extent> (noise1), sub<points> (sub256), partial, "
    "robot";

}  // namespace

uint64_t DeriveSeed(uint64_t base_seed, absl::string_view key) {
  Fnv1a hash;
  hash.Add(key.data(), key.size());
  SplitMix64 mix(base_seed);
  return SplitMix64(mix.Next() ^ hash.value()).Next();
}

double CloudExtent(const PointCloud& cloud) {
  if (cloud.empty()) return 0.0;
  Eigen::Vector3d lo = cloud.point(0).cast<double>(), hi = lo;
  for (size_t i = 1; i < cloud.size(); ++i) {
    const Eigen::Vector3d p = cloud.point(i).cast<double>();
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  const Eigen::Vector3d d = hi - lo;
  return std::sqrt(Dot(d, d));
}

Eigen::Vector3d CloudCentroid(const PointCloud& cloud) {
  double sx = 0, sy = 0, sz = 0;
  const float* xyz = cloud.data();
  for (size_t i = 0; i < cloud.size(); ++i) {
    sx += xyz[3 * i];
    sy += xyz[3 * i + 1];
    sz += xyz[3 * i + 2];
  }
  if (cloud.empty()) return Eigen::Vector3d::Zero();
  const double n = static_cast<double>(cloud.size());
  return {sx / n, sy / n, sz / n};
}

Eigen::Matrix3d RandomYawMatrix(const Eigen::Vector3d& up, SplitMix64& rng) {
  const Eigen::Vector3d u = Unit(up);
  const Eigen::Vector2d cs = UnitCircle(rng);
  const double c = cs.x(), s = cs.y(), t = 1 - c;
  // Rodrigues: c I + s [u]x + (1 - c) u u^T.
  Eigen::Matrix3d r;
  r << c + t * u.x() * u.x(), t * u.x() * u.y() - s * u.z(), t * u.x() * u.z() + s * u.y(),
      t * u.y() * u.x() + s * u.z(), c + t * u.y() * u.y(), t * u.y() * u.z() - s * u.x(),
      t * u.z() * u.x() - s * u.y(), t * u.z() * u.y() + s * u.x(), c + t * u.z() * u.z();
  return r;
}

Eigen::Matrix3d RandomRotationMatrix(SplitMix64& rng) {
  const double u1 = rng.Uniform();
  const Eigen::Vector2d a = UnitCircle(rng);  // (cos t2, sin t2)
  const Eigen::Vector2d b = UnitCircle(rng);  // (cos t3, sin t3)
  const double r1 = std::sqrt(1 - u1), r2 = std::sqrt(u1);
  const double x = r1 * a.y(), y = r1 * a.x(), z = r2 * b.y(), w = r2 * b.x();
  // The rotation of the quaternion (w, x, y, z), divided by its squared norm so that its
  // rounding from 1 does not scale the cloud.
  const double s = 2 / (w * w + x * x + y * y + z * z);
  Eigen::Matrix3d r;
  r << 1 - s * (y * y + z * z), s * (x * y - w * z), s * (x * z + w * y),  //
      s * (x * y + w * z), 1 - s * (x * x + z * z), s * (y * z - w * x),   //
      s * (x * z - w * y), s * (y * z + w * x), 1 - s * (x * x + y * y);
  return r;
}

PointCloud RotateAboutCentroid(const PointCloud& cloud, const Eigen::Matrix3d& rotation) {
  const Eigen::Vector3d c = CloudCentroid(cloud);
  const Eigen::Matrix3d& r = rotation;
  PointCloud out;
  out.Reserve(cloud.size());
  const float* xyz = cloud.data();
  for (size_t i = 0; i < cloud.size(); ++i) {
    const double x = xyz[3 * i] - c.x(), y = xyz[3 * i + 1] - c.y(), z = xyz[3 * i + 2] - c.z();
    out.Add(static_cast<float>(r(0, 0) * x + r(0, 1) * y + r(0, 2) * z + c.x()),
            static_cast<float>(r(1, 0) * x + r(1, 1) * y + r(1, 2) * z + c.y()),
            static_cast<float>(r(2, 0) * x + r(2, 1) * y + r(2, 2) * z + c.z()));
  }
  return out;
}

absl::StatusOr<PointCloud> RandomYaw(const PointCloud& cloud, const Eigen::Vector3d& up,
                                     uint64_t seed) {
  SHAPEID_RETURN_IF_ERROR(CheckUp(up));
  SplitMix64 rng(seed);
  return RotateAboutCentroid(cloud, RandomYawMatrix(up, rng));
}

PointCloud RandomRotation(const PointCloud& cloud, uint64_t seed) {
  SplitMix64 rng(seed);
  return RotateAboutCentroid(cloud, RandomRotationMatrix(rng));
}

absl::StatusOr<PointCloud> AddGaussianNoise(const PointCloud& cloud, double sigma_fraction,
                                            uint64_t seed) {
  if (!(sigma_fraction >= 0) || !std::isfinite(sigma_fraction)) {
    return absl::InvalidArgumentError(absl::StrCat(
        "noise level ", sigma_fraction, " must be finite and >= 0 (a fraction of the extent)"));
  }
  const double sigma = sigma_fraction * CloudExtent(cloud);
  if (sigma == 0) return cloud;
  NormalDeviates normal(seed);
  PointCloud out;
  out.Reserve(cloud.size());
  const float* xyz = cloud.data();
  for (size_t i = 0; i < 3 * cloud.size(); i += 3) {
    const double x = xyz[i] + sigma * normal.Next();
    const double y = xyz[i + 1] + sigma * normal.Next();
    const double z = xyz[i + 2] + sigma * normal.Next();
    out.Add(static_cast<float>(x), static_cast<float>(y), static_cast<float>(z));
  }
  return out;
}

PointCloud RandomSubsample(const PointCloud& cloud, size_t points, uint64_t seed) {
  const size_t n = cloud.size();
  if (n <= points) return cloud;
  SplitMix64 rng(seed);
  PointCloud out;
  out.Reserve(points);
  size_t wanted = points;
  for (size_t i = 0; i < n && wanted > 0; ++i) {
    // Keep point i with probability wanted / remaining: every subset equally likely.
    if (rng.Uniform() * static_cast<double>(n - i) < static_cast<double>(wanted)) {
      out.Add(cloud.point(i));
      --wanted;
    }
  }
  return out;
}

absl::StatusOr<Eigen::Vector3d> RandomViewDirection(const PartialViewOptions& options,
                                                    uint64_t seed) {
  SHAPEID_RETURN_IF_ERROR(CheckUp(options.up));
  if (!(options.min_up >= -1 && options.min_up <= options.max_up && options.max_up <= 1)) {
    return absl::InvalidArgumentError(
        absl::StrCat("view band [", options.min_up, ", ", options.max_up,
                     "] (components along up) must satisfy -1 <= min <= max <= 1"));
  }
  const Eigen::Vector3d u = Unit(options.up);
  // Azimuth 0 along +z made perpendicular to up, or +x when up is along z (as ViewDirections).
  Eigen::Vector3d e1 = Eigen::Vector3d::UnitZ() - u.z() * u;
  if (Dot(e1, e1) < 1e-12) e1 = Eigen::Vector3d::UnitX() - u.x() * u;
  e1 = Unit(e1);
  const Eigen::Vector3d e2 = Cross(u, e1);
  SplitMix64 rng(seed);
  const double h = options.min_up + (options.max_up - options.min_up) * rng.Uniform();
  const Eigen::Vector2d cs = UnitCircle(rng);
  const double r = std::sqrt(std::max(0.0, 1 - h * h));
  return Eigen::Vector3d(h * u + r * (cs.x() * e1 + cs.y() * e2));
}

absl::StatusOr<PointCloud> PartialView(const PointCloud& cloud, const PartialViewOptions& options,
                                       uint64_t seed) {
  SHAPEID_ASSIGN_OR_RETURN(const Eigen::Vector3d direction, RandomViewDirection(options, seed));
  if (!(options.distance > 1 && options.distance <= 1e6)) {
    return absl::InvalidArgumentError(absl::StrCat("view distance ", options.distance,
                                                   " must be in (1, 1e6] (half box diagonals)"));
  }
  SHAPEID_ASSIGN_OR_RETURN(ScanSimulator simulator, ScanSimulator::Create(cloud));
  ScanOptions scan;
  scan.direction = direction;
  scan.up = std::abs(direction.z()) < 0.9 ? Eigen::Vector3d::UnitZ() : Eigen::Vector3d::UnitX();
  scan.distance = options.distance;
  scan.depth_noise = 0;
  scan.fov_degrees = 45;
  // A square image spans 2 * distance * radius * tan(22.5 degrees) at the object's center;
  // pixels a third of a sample spacing wide there rarely hold two visible points, so what
  // is hidden, not the resolution, decides what is lost.
  constexpr double kTanHalfFov = 0.41421356237309504880;  // tan(22.5 deg) = sqrt(2) - 1
  const double span = 2 * options.distance * 0.5 * CloudExtent(cloud) * kTanHalfFov;
  const double side = std::ceil(3 * span / simulator.sample_spacing());
  scan.width = scan.height = static_cast<int>(std::clamp(side, 64.0, 2048.0));
  SHAPEID_ASSIGN_OR_RETURN(const PointCloud seen, simulator.Scan(scan));
  return InInputOrder(cloud, seen);
}

absl::StatusOr<PointCloud> PlaneCutView(const PointCloud& cloud, const PartialViewOptions& options,
                                        double max_offset, uint64_t seed) {
  if (!(max_offset >= 0 && max_offset <= 1)) {
    return absl::InvalidArgumentError(
        absl::StrCat("plane cut: offset ", max_offset, " must be in [0, 1] half box diagonals"));
  }
  if (cloud.empty()) return absl::InvalidArgumentError("plane cut: the cloud is empty");
  SplitMix64 rng(seed);
  const uint64_t direction_seed = rng.Next();
  SHAPEID_ASSIGN_OR_RETURN(const Eigen::Vector3d normal,
                           RandomViewDirection(options, direction_seed));
  const double offset = (2 * rng.Uniform() - 1) * max_offset * 0.5 * CloudExtent(cloud);
  const Eigen::Vector3d centroid = CloudCentroid(cloud);
  const auto cut = [&](double at) {
    PointCloud kept;
    for (size_t i = 0; i < cloud.size(); ++i) {
      const Eigen::Vector3d p = cloud.point(i).cast<double>();
      if (Dot(p - centroid, normal) >= at) kept.Add(cloud.point(i));
    }
    return kept;
  };
  PointCloud kept = cut(offset);
  if (kept.size() * 10 < cloud.size()) kept = cut(0.0);
  if (kept.empty()) kept = cut(-std::numeric_limits<double>::infinity());  // rounding: keep all
  return kept;
}

absl::StatusOr<PointCloud> OccludedView(const PointCloud& cloud, const PartialViewOptions& options,
                                        uint64_t seed) {
  SplitMix64 rng(seed);
  const uint64_t view_seed = rng.Next();
  SHAPEID_ASSIGN_OR_RETURN(PointCloud view, PartialView(cloud, options, view_seed));
  SHAPEID_ASSIGN_OR_RETURN(const Eigen::Vector3d sight, RandomViewDirection(options, view_seed));
  // A unit direction across the line of sight, at a random angle about it.
  const Eigen::Vector3d helper =
      std::abs(sight.z()) < 0.9 ? Eigen::Vector3d::UnitZ() : Eigen::Vector3d::UnitX();
  const Eigen::Vector3d e1 = Unit(Cross(sight, helper));
  const Eigen::Vector3d e2 = Cross(sight, e1);
  const Eigen::Vector2d cs = UnitCircle(rng);
  const Eigen::Vector3d across = cs.x() * e1 + cs.y() * e2;
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (size_t i = 0; i < view.size(); ++i) {
    const double s = Dot(view.point(i).cast<double>(), across);
    lo = std::min(lo, s);
    hi = std::max(hi, s);
  }
  const double width = (0.1 + 0.2 * rng.Uniform()) * (hi - lo);
  const double start = lo + (hi - lo - width) * rng.Uniform();
  PointCloud kept;
  for (size_t i = 0; i < view.size(); ++i) {
    const double s = Dot(view.point(i).cast<double>(), across);
    if (s < start || s > start + width) kept.Add(view.point(i));
  }
  if (kept.size() * 3 < view.size()) return view;
  return kept;
}

absl::StatusOr<PointCloud> SensorView(const PointCloud& cloud, const SensorViewOptions& options,
                                      uint64_t seed) {
  if (!(std::isfinite(options.noise_fraction) && options.noise_fraction >= 0)) {
    return absl::InvalidArgumentError(absl::StrCat(
        "sensor view: noise fraction ", options.noise_fraction, " must be finite and >= 0"));
  }
  if (options.min_points < 1 || options.min_points > options.max_points) {
    return absl::InvalidArgumentError(absl::StrCat("sensor view: points [", options.min_points,
                                                   ", ", options.max_points,
                                                   "] must satisfy 1 <= min <= max"));
  }
  SplitMix64 rng(seed);
  const uint64_t view_seed = rng.Next(), noise_seed = rng.Next(), subsample_seed = rng.Next(),
                 pose_seed = rng.Next();
  // The count before anything else, so it does not depend on what the view kept.
  const size_t span = options.max_points - options.min_points + 1;
  const size_t points =
      options.min_points +
      std::min(span - 1, static_cast<size_t>(rng.Uniform() * static_cast<double>(span)));
  PointCloud view;
  switch (options.visibility) {
    case Visibility::kCamera: {
      SHAPEID_ASSIGN_OR_RETURN(view, PartialView(cloud, options.view, view_seed));
      break;
    }
    case Visibility::kPlaneCut: {
      SHAPEID_ASSIGN_OR_RETURN(view, PlaneCutView(cloud, options.view, 0.3, view_seed));
      break;
    }
    case Visibility::kOccludedCamera: {
      SHAPEID_ASSIGN_OR_RETURN(view, OccludedView(cloud, options.view, view_seed));
      break;
    }
  }
  // Noise relative to the whole object: the visible part's extent varies with the viewpoint.
  const double view_extent = CloudExtent(view);
  const double fraction =
      view_extent > 0 ? options.noise_fraction * CloudExtent(cloud) / view_extent : 0.0;
  SHAPEID_ASSIGN_OR_RETURN(PointCloud noisy, AddGaussianNoise(view, fraction, noise_seed));
  PointCloud sparse = RandomSubsample(noisy, points, subsample_seed);
  if (!options.random_pose) return sparse;
  return RandomRotation(sparse, pose_seed);
}

absl::StatusOr<Perturbation> ParsePerturbation(absl::string_view name) {
  const std::string text = absl::AsciiStrToLower(absl::StripAsciiWhitespace(name));
  const absl::string_view t = text;
  Perturbation p;
  const auto unknown = [&] {
    return absl::InvalidArgumentError(
        absl::StrCat("unknown perturbation \"", name, "\"; known: ", kPerturbationForms));
  };
  if (t == "clean" || t == "none") {
    p.kind = Perturbation::Kind::kNone;
    p.name = "clean";
  } else if (t == "yaw") {
    p.kind = Perturbation::Kind::kYaw;
    p.name = "yaw";
  } else if (t == "rot3d") {
    p.kind = Perturbation::Kind::kRotation;
    p.name = "rot3d";
  } else if (t == "partial") {
    p.kind = Perturbation::Kind::kPartialView;
    p.name = "partial";
  } else if (t == "robot") {
    p.kind = Perturbation::Kind::kSensorView;
    p.name = "robot";
  } else if (absl::StartsWith(t, "noise")) {
    double percent = 0;
    if (!absl::SimpleAtod(t.substr(5), &percent) || !(percent > 0 && percent <= 100)) {
      return unknown();
    }
    p.kind = Perturbation::Kind::kNoise;
    p.noise_fraction = percent / 100;
    p.name = absl::StrCat("noise", percent);
  } else if (absl::StartsWith(t, "sub")) {
    uint64_t points = 0;
    if (!absl::SimpleAtoi(t.substr(3), &points) || points < 1) return unknown();
    p.kind = Perturbation::Kind::kSubsample;
    p.points = static_cast<size_t>(points);
    p.name = absl::StrCat("sub", points);
  } else {
    return unknown();
  }
  return p;
}

absl::StatusOr<PointCloud> ApplyPerturbation(const PointCloud& cloud,
                                             const Perturbation& perturbation, uint64_t seed) {
  switch (perturbation.kind) {
    case Perturbation::Kind::kNone:
      return cloud;
    case Perturbation::Kind::kYaw:
      return RandomYaw(cloud, perturbation.view.up, seed);
    case Perturbation::Kind::kRotation:
      return RandomRotation(cloud, seed);
    case Perturbation::Kind::kNoise:
      return AddGaussianNoise(cloud, perturbation.noise_fraction, seed);
    case Perturbation::Kind::kSubsample:
      return RandomSubsample(cloud, perturbation.points, seed);
    case Perturbation::Kind::kPartialView:
      return PartialView(cloud, perturbation.view, seed);
    case Perturbation::Kind::kSensorView:
      return SensorView(cloud, perturbation.sensor, seed);
  }
  return absl::InvalidArgumentError("invalid perturbation kind");
}

}  // namespace shapeid
