// DFSD's frames (docs/descriptors.md section 5): the axes, box and skewness that a descriptor
// lays its grid in, found from the points alone (box, pca), from the client's vertical
// (upright) or taken as given (axes).
#include "core/descriptors/dfsd_frame.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "Eigen/Eigenvalues"

namespace shapeid {
namespace dfsd_internal {
namespace {

// The upright frame's starting basis: columns (b0, b1, up), right-handed, each a signed unit
// axis of the input. Up = +e_k takes b0 = e_(k+1), b1 = e_(k+2) (cyclic); up = -e_k swaps
// them. So up=z is the identity, and a cloud with up=y whose coordinates are cyclically
// permuted to z up projects to the very same horizontal coordinates.
Eigen::Matrix3d UpBasis(DfsdOptions::Up up) {
  const int index = static_cast<int>(up);
  const int k = 2 - index % 3;  // kPlusZ -> 2, kPlusY -> 1, kPlusX -> 0
  const bool reversed = index >= 3;
  Eigen::Matrix3d basis = Eigen::Matrix3d::Zero();
  basis((k + 1) % 3, reversed ? 1 : 0) = 1;
  basis((k + 2) % 3, reversed ? 0 : 1) = 1;
  basis(k, 2) = reversed ? -1 : 1;
  return basis;
}

// ---- frame=box (docs/descriptors.md section 5.2)

double Turn(const Eigen::Vector2d& o, const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  return (a.x() - o.x()) * (b.y() - o.y()) - (a.y() - o.y()) * (b.x() - o.x());
}

// Drops points strictly inside the polygon of the extreme points in 8 directions (Akl and
// Toussaint 1978): they cannot be on the hull, and on object surfaces they are most points,
// so the sort that follows is several times shorter. Exact; keeps the survivors' order.
void DropInteriorPoints(std::vector<Eigen::Vector2d>& points) {
  if (points.size() < 16) return;
  // Extremes along x, x+y, y, y-x, -x, -x-y, -y, x-y: counter-clockwise around the cloud.
  static constexpr double kDirections[8][2] = {{1, 0},  {1, 1},   {0, 1},  {-1, 1},
                                               {-1, 0}, {-1, -1}, {0, -1}, {1, -1}};
  Eigen::Vector2d extreme[8];
  double best[8];
  for (int k = 0; k < 8; ++k) best[k] = -std::numeric_limits<double>::infinity();
  for (const Eigen::Vector2d& p : points) {
    for (int k = 0; k < 8; ++k) {
      const double v = kDirections[k][0] * p.x() + kDirections[k][1] * p.y();
      if (v > best[k]) {
        best[k] = v;
        extreme[k] = p;
      }
    }
  }
  size_t kept = 0;
  for (const Eigen::Vector2d& p : points) {
    bool inside = true;
    for (int k = 0; k < 8 && inside; ++k) {
      const Eigen::Vector2d& a = extreme[k];
      const Eigen::Vector2d& b = extreme[(k + 1) % 8];
      // A repeated extreme gives a zero edge, which says nothing: skip it.
      inside = (a == b) || Turn(a, b, p) > 0;
    }
    if (!inside) points[kept++] = p;
  }
  points.resize(kept);
}

}  // namespace

std::vector<Eigen::Vector2d> ConvexHull(std::vector<Eigen::Vector2d>& points) {
  DropInteriorPoints(points);
  std::sort(points.begin(), points.end(), [](const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
    return a.x() < b.x() || (a.x() == b.x() && a.y() < b.y());
  });
  std::vector<Eigen::Vector2d> hull(2 * points.size());
  size_t h = 0;
  for (const Eigen::Vector2d& p : points) {  // lower hull
    while (h >= 2 && Turn(hull[h - 2], hull[h - 1], p) <= 0) --h;
    hull[h++] = p;
  }
  const size_t lower = h + 1;
  for (size_t i = points.size(); i-- > 0;) {  // upper hull
    while (h >= lower && Turn(hull[h - 2], hull[h - 1], points[i]) <= 0) --h;
    hull[h++] = points[i];
  }
  hull.resize(h > 1 ? h - 1 : h);  // the last point repeats the first
  return hull;
}

bool MinAreaRectangle(const std::vector<Eigen::Vector2d>& hull, Eigen::Vector2d* direction,
                      double* area) {
  if (hull.size() < 3) return false;
  *area = std::numeric_limits<double>::infinity();
  for (size_t i = 0; i < hull.size(); ++i) {
    Eigen::Vector2d e = hull[(i + 1) % hull.size()] - hull[i];
    const double length = e.norm();
    if (length == 0) continue;
    e /= length;
    double lo_u = std::numeric_limits<double>::infinity(), hi_u = -lo_u, lo_v = lo_u, hi_v = -lo_u;
    for (const Eigen::Vector2d& q : hull) {
      const double u = q.dot(e), v = e.x() * q.y() - e.y() * q.x();
      lo_u = std::min(lo_u, u);
      hi_u = std::max(hi_u, u);
      lo_v = std::min(lo_v, v);
      hi_v = std::max(hi_v, v);
    }
    const double a = (hi_u - lo_u) * (hi_v - lo_v);
    if (a < *area) {
      *area = a;
      *direction = e;
    }
  }
  return std::isfinite(*area);
}

namespace {

// Volume of the box around the centred points `d` (3 x n) along the columns of `axes`.
double BoxVolume(const Eigen::Matrix3Xd& d, const Eigen::Matrix3d& axes) {
  const Eigen::Matrix3Xd q = axes.transpose() * d;
  return (q.rowwise().maxCoeff() - q.rowwise().minCoeff()).prod();
}

// Orders the first `free` columns of `axes` by the extent of the centred points `d` along
// them, largest first (stable: equal extents keep their order), and points each of them to
// the side where the cubed coordinates sum positive; later columns stay as they are, with an
// infinite skewness (never a guess). `skewness` gets |third moment| / second moment^1.5
// per resulting axis.
Eigen::Matrix3d OrderAndSign(const Eigen::Matrix3d& axes, const Eigen::Matrix3Xd& d, int free,
                             Eigen::Vector3d* skewness) {
  const Eigen::Matrix3Xd q = axes.transpose() * d;
  const Eigen::Vector3d extent = q.rowwise().maxCoeff() - q.rowwise().minCoeff();
  int order[3] = {0, 1, 2};
  std::stable_sort(order, order + free, [&](int a, int b) { return extent[a] > extent[b]; });
  Eigen::Matrix3d out = axes;
  const double n = static_cast<double>(d.cols());
  for (int a = 0; a < 3; ++a) {
    if (a >= free) {
      (*skewness)[a] = std::numeric_limits<double>::infinity();
      continue;
    }
    const Eigen::RowVectorXd c = q.row(order[a]);
    const double m2 = c.array().square().sum();
    const double m3 = c.array().cube().sum();
    out.col(a) = (m3 < 0 ? -1.0 : 1.0) * axes.col(order[a]);
    const double variance = m2 / n;
    (*skewness)[a] = variance > 0 ? std::abs(m3 / n) / (variance * std::sqrt(variance)) : 0.0;
  }
  return out;
}

// The points less their centroid, in double, one column each (box and upright frames).
Eigen::Matrix3Xd CentredPoints(const PointCloud& cloud, const Eigen::Vector3d& centroid) {
  Eigen::Matrix3Xd d(3, static_cast<Eigen::Index>(cloud.size()));
  for (size_t p = 0; p < cloud.size(); ++p) {
    d.col(static_cast<Eigen::Index>(p)) = cloud.point(p).cast<double>() - centroid;
  }
  return d;
}

// The box frame: starting from the principal axes, each axis in turn is held and the other
// two turned to the smallest-area rectangle around the points' projection; the smallest box
// found wins, and a second round starts from it if the first found a smaller one. Principal
// axes tilt on L-shaped or asymmetric objects (a chair's back pulls them); the tightest box
// lines up with the flat sides that man-made objects and buildings have. Then the axes are
// ordered by box extent, largest first, and each points to the side its points are skewed
// to (a right- or left-handed frame: a mirror image gets the mirrored frame, hence the same
// descriptor). Uses + - * / sqrt and Eigen's
// symmetric eigensolver only, so a build gives the same frame on every CPU.
Eigen::Matrix3d BoxAxes(const PointCloud& cloud, const Eigen::Vector3d& centroid,
                        Eigen::Vector3d* skewness) {
  const size_t n = cloud.size();
  const Eigen::Matrix3Xd d = CentredPoints(cloud, centroid);
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(d * d.transpose());
  Eigen::Matrix3d best;
  for (int a = 0; a < 3; ++a) best.col(a) = solver.eigenvectors().col(2 - a);  // descending
  double best_volume = BoxVolume(d, best);
  std::vector<Eigen::Vector2d> projected;
  bool improved = true;
  for (int round = 0; round < 2 && improved; ++round) {
    improved = false;
    const Eigen::Matrix3d start = best;
    for (int held = 0; held < 3; ++held) {
      const Eigen::Vector3d u = start.col((held + 1) % 3), v = start.col((held + 2) % 3);
      projected.resize(n);
      for (size_t p = 0; p < n; ++p) {
        const auto point = d.col(static_cast<Eigen::Index>(p));
        projected[p] = Eigen::Vector2d(point.dot(u), point.dot(v));
      }
      Eigen::Vector2d e;
      double area;
      if (!MinAreaRectangle(ConvexHull(projected), &e, &area)) continue;
      const Eigen::RowVectorXd along = start.col(held).transpose() * d;
      const double volume = area * (along.maxCoeff() - along.minCoeff());
      if (volume < best_volume) {
        improved = true;
        best_volume = volume;
        best.col(0) = start.col(held);
        best.col(1) = e.x() * u + e.y() * v;
        best.col(2) = e.x() * v - e.y() * u;
      }
    }
  }
  return OrderAndSign(best, d, 3, skewness);
}

// The upright frame: the third axis is the client's vertical (`up`: e.g. from a robot's
// IMU, pointing up); the first two are the sides of the smallest-area rectangle around the
// points seen from above, ordered by extent and signed by skewness. Invariant to any turn
// about the vertical (yaw) and to mirroring in the horizontal plane; it keeps which way is
// up, which the box frame cannot know.
Eigen::Matrix3d UprightAxes(const PointCloud& cloud, const Eigen::Vector3d& centroid,
                            DfsdOptions::Up up, Eigen::Vector3d* skewness) {
  const size_t n = cloud.size();
  const Eigen::Matrix3d basis = UpBasis(up);
  const Eigen::Matrix3Xd d = CentredPoints(cloud, centroid);
  std::vector<Eigen::Vector2d> projected(n);
  for (size_t p = 0; p < n; ++p) {
    // The basis holds one signed 1 per column: these products are exact.
    projected[p] = basis.leftCols<2>().transpose() * d.col(static_cast<Eigen::Index>(p));
  }
  Eigen::Matrix3d axes = basis;
  Eigen::Vector2d e;
  double area;
  // A cloud whose points all lie on one vertical line keeps the basis.
  if (MinAreaRectangle(ConvexHull(projected), &e, &area)) {
    axes.col(0) = e.x() * basis.col(0) + e.y() * basis.col(1);
    axes.col(1) = e.x() * basis.col(1) - e.y() * basis.col(0);
  }
  return OrderAndSign(axes, d, 2, skewness);
}

// The principal axes of the points, as the columns of a rotation (largest spread first),
// each pointing to the side where the cubed coordinates sum positive, the third then made
// right-handed. Accumulated in double in point order.
Eigen::Matrix3d PrincipalFrame(const PointCloud& cloud, const Eigen::Vector3d& centroid) {
  const size_t n = cloud.size();
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();
  for (size_t p = 0; p < n; ++p) {
    const Eigen::Vector3d d = cloud.point(p).cast<double>() - centroid;
    covariance += d * d.transpose();
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(covariance);
  Eigen::Matrix3d axes;
  for (int a = 0; a < 3; ++a) axes.col(a) = solver.eigenvectors().col(2 - a);  // descending
  Eigen::Vector3d skew = Eigen::Vector3d::Zero();
  for (size_t p = 0; p < n; ++p) {
    const Eigen::Vector3d q = axes.transpose() * (cloud.point(p).cast<double>() - centroid);
    skew += q.cwiseProduct(q).cwiseProduct(q);
  }
  for (int a = 0; a < 2; ++a) {
    if (skew[a] < 0) axes.col(a) = -axes.col(a);
  }
  axes.col(2) = axes.col(0).cross(axes.col(1));
  return axes;
}

}  // namespace

FramedCloud Frame(const PointCloud& cloud, const CloudStats& stats, const DfsdOptions& options) {
  const DfsdOptions::Frame frame = options.frame;
  const size_t n = cloud.size();
  FramedCloud framed;
  for (auto& axis : framed.coord) axis.resize(n);
  Eigen::Vector3d lo = stats.min;
  Eigen::Vector3d hi = stats.max;
  if (frame != DfsdOptions::Frame::kAxes) {
    const Eigen::Matrix3d axes =
        frame == DfsdOptions::Frame::kPca ? PrincipalFrame(cloud, stats.centroid)
        : frame == DfsdOptions::Frame::kBox
            ? BoxAxes(cloud, stats.centroid, &framed.skewness)
            : UprightAxes(cloud, stats.centroid, options.up, &framed.skewness);
    lo.setConstant(std::numeric_limits<double>::infinity());
    hi = -lo;
    for (size_t p = 0; p < n; ++p) {
      const Eigen::Vector3d q = axes.transpose() * (cloud.point(p).cast<double>() - stats.centroid);
      for (int a = 0; a < 3; ++a) framed.coord[a][p] = q[a];
      lo = lo.cwiseMin(q);
      hi = hi.cwiseMax(q);
    }
  } else {
    const float* xyz = cloud.data();
    for (size_t p = 0; p < n; ++p) {
      for (int a = 0; a < 3; ++a) framed.coord[a][p] = xyz[3 * p + a];
    }
  }
  const Eigen::Vector3d centre = 0.5 * (lo + hi);
  framed.half_extent = 0.5 * (hi - lo);
  for (int a = 0; a < 3; ++a) {
    for (double& v : framed.coord[a]) v -= centre[a];
  }
  return framed;
}

}  // namespace dfsd_internal
}  // namespace shapeid
