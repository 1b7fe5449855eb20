// DFSD's frames (docs/descriptors.md section 5): the axes, box and skewness that a descriptor
// lays its grid in, found from the points alone (box, pca), from the client's vertical
// (upright) or taken as given (axes).
//
// The frames read the cloud in passes of kFramePassPoints and keep what each pass learns (a
// scatter matrix, extremes, third moments, hulls), so that a cloud of any size can be
// described in bounded memory (docs/descriptors.md, "Cost"). They once held the cloud as one
// 3 x n matrix of doubles, and their output must not change: per-point values come from the
// very Eigen expressions on chunks of the same matrix type (columns at the same alignment),
// and every sum adds its terms in the order Eigen's whole-matrix evaluation did (ScatterSum,
// EigenOrderSum).
#include "core/descriptors/dfsd_frame.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "Eigen/Eigenvalues"

namespace shapeid {
namespace dfsd_internal {

static_assert(Eigen::internal::packet_traits<double>::size == 2,
              "EigenOrderSum and ScatterSum follow Eigen's SSE2 double packets; a build with "
              "other packets sums in another order and would change DFSD's box frame");
static_assert(kFramePassPoints % 2 == 0);

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

// The cloud's points less the centroid, in double, a chunk at a time: the columns that the
// whole cloud's 3 x n matrix had (same expression; chunks start at even columns, so each
// column keeps its 16-byte alignment).
class CenteredChunks {
 public:
  CenteredChunks(const PointCloud& cloud, const Eigen::Vector3d& centroid)
      : cloud_(cloud), centroid_(centroid) {}

  size_t size() const { return cloud_.size(); }

  // Points first .. first + count - 1; `first` a multiple of kFramePassPoints. A cloud of
  // one chunk is converted once, however many passes read it.
  const Eigen::Matrix3Xd& Get(size_t first, size_t count) {
    if (first == held_first_ && static_cast<size_t>(d_.cols()) == count) return d_;
    if (static_cast<size_t>(d_.cols()) != count) d_.resize(3, static_cast<Eigen::Index>(count));
    for (size_t p = 0; p < count; ++p) {
      d_.col(static_cast<Eigen::Index>(p)) = cloud_.point(first + p).cast<double>() - centroid_;
    }
    held_first_ = first;
    return d_;
  }

  // fn(first, columns) for every chunk, in order.
  template <typename Fn>
  void ForEach(Fn&& fn) {
    for (size_t first = 0; first < size(); first += kFramePassPoints) {
      fn(first, Get(first, std::min(kFramePassPoints, size() - first)));
    }
  }

 private:
  const PointCloud& cloud_;
  const Eigen::Vector3d& centroid_;
  Eigen::Matrix3Xd d_;
  size_t held_first_ = std::numeric_limits<size_t>::max();  // the chunk d_ holds
};

// Running extremes of the three rows of q = axes^T d, kept as Eigen's rowwise maxCoeff and
// minCoeff keep them (the first of equal values).
struct RowRange {
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
  Eigen::Vector3d hi = -lo;

  void Add(const Eigen::Matrix3Xd& q) {
    for (Eigen::Index p = 0; p < q.cols(); ++p) {
      for (int a = 0; a < 3; ++a) {
        lo[a] = std::min(lo[a], q(a, p));
        hi[a] = std::max(hi[a], q(a, p));
      }
    }
  }
  // (max - min).prod() through the very expression over a 3 x n matrix, which a 3 x 2
  // matrix of the extremes reproduces (the product's association is Eigen's).
  double Volume() const {
    Eigen::Matrix3Xd ends(3, 2);
    ends << lo, hi;
    const Eigen::Matrix3Xd& q = ends;
    return (q.rowwise().maxCoeff() - q.rowwise().minCoeff()).prod();
  }
};

// Volume of the box around the centered points along the columns of `axes`.
double BoxVolume(CenteredChunks& chunks, const Eigen::Matrix3d& axes) {
  RowRange range;
  chunks.ForEach([&](size_t, const Eigen::Matrix3Xd& d) {
    const Eigen::Matrix3Xd q = axes.transpose() * d;
    range.Add(q);
  });
  return range.Volume();
}

// Orders the first `free` columns of `axes` by the extent of the centered points along them,
// largest first (stable: equal extents keep their order), and points each of them to the
// side where the cubed coordinates sum positive; later columns stay as they are, with an
// infinite skewness (never a guess). `skewness` gets |third moment| / second moment^1.5 per
// resulting axis. Two passes: extents, then moments.
Eigen::Matrix3d OrderAndSign(const Eigen::Matrix3d& axes, CenteredChunks& chunks, int free,
                             Eigen::Vector3d* skewness) {
  RowRange range;
  chunks.ForEach([&](size_t, const Eigen::Matrix3Xd& d) {
    const Eigen::Matrix3Xd q = axes.transpose() * d;
    range.Add(q);
  });
  const Eigen::Vector3d extent = range.hi - range.lo;
  int order[3] = {0, 1, 2};
  std::stable_sort(order, order + free, [&](int a, int b) { return extent[a] > extent[b]; });
  const size_t count = chunks.size();
  std::vector<EigenOrderSum> m2(static_cast<size_t>(free), EigenOrderSum(count));
  std::vector<EigenOrderSum> m3(static_cast<size_t>(free), EigenOrderSum(count));
  chunks.ForEach([&](size_t, const Eigen::Matrix3Xd& d) {
    const Eigen::Matrix3Xd q = axes.transpose() * d;
    for (int a = 0; a < free; ++a) {
      for (Eigen::Index p = 0; p < q.cols(); ++p) {
        const double c = q(order[a], p);
        const double c2 = c * c;
        m2[static_cast<size_t>(a)].Add(c2);
        m3[static_cast<size_t>(a)].Add(c2 * c);  // Eigen's cube: c * (c * c)
      }
    }
  });
  Eigen::Matrix3d out = axes;
  const double n = static_cast<double>(count);
  for (int a = 0; a < 3; ++a) {
    if (a >= free) {
      (*skewness)[a] = std::numeric_limits<double>::infinity();
      continue;
    }
    const double sum2 = m2[static_cast<size_t>(a)].Sum();
    const double sum3 = m3[static_cast<size_t>(a)].Sum();
    out.col(a) = (sum3 < 0 ? -1.0 : 1.0) * axes.col(order[a]);
    const double variance = sum2 / n;
    (*skewness)[a] = variance > 0 ? std::abs(sum3 / n) / (variance * std::sqrt(variance)) : 0.0;
  }
  return out;
}

// The box frame: starting from the principal axes, each axis in turn is held and the other
// two turned to the smallest-area rectangle around the points' projection; the smallest box
// found wins, and a second round starts from it if the first found a smaller one. Principal
// axes tilt on L-shaped or asymmetric objects (a chair's back pulls them); the tightest box
// lines up with the flat sides that man-made objects and buildings have. Then the axes are
// ordered by box extent, largest first, and each points to the side its points are skewed
// to (a right- or left-handed frame: a mirror image gets the mirrored frame, hence the same
// descriptor). Uses + - * / sqrt and Eigen's symmetric eigensolver only, so a build gives
// the same frame on every CPU whose L1 cache Eigen sizes alike (see ScatterSum).
Eigen::Matrix3d BoxAxes(const PointCloud& cloud, const Eigen::Vector3d& centroid,
                        size_t hull_candidates, Eigen::Vector3d* skewness) {
  const size_t n = cloud.size();
  CenteredChunks chunks(cloud, centroid);
  ScatterSum scatter(n);
  chunks.ForEach([&](size_t, const Eigen::Matrix3Xd& d) { scatter.Add(d); });
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(scatter.Sum());
  Eigen::Matrix3d best;
  for (int a = 0; a < 3; ++a) best.col(a) = solver.eigenvectors().col(2 - a);  // descending
  double best_volume = BoxVolume(chunks, best);
  bool improved = true;
  for (int round = 0; round < 2 && improved; ++round) {
    improved = false;
    const Eigen::Matrix3d start = best;
    const Eigen::Vector3d axis[3] = {start.col(0), start.col(1), start.col(2)};
    // Holding axis h projects onto axes h + 1 and h + 2: one pass finds the three octagons
    // and the extents along the three axes.
    std::vector<StreamedHull> hulls;
    for (int held = 0; held < 3; ++held) hulls.emplace_back(n, hull_candidates);
    double along_lo[3], along_hi[3];
    for (int held = 0; held < 3; ++held) {
      along_lo[held] = std::numeric_limits<double>::infinity();
      along_hi[held] = -along_lo[held];
    }
    std::vector<Eigen::Vector2d> projected[3];
    for (auto& chunk : projected) chunk.resize(std::min(n, kFramePassPoints));
    chunks.ForEach([&](size_t, const Eigen::Matrix3Xd& d) {
      for (Eigen::Index p = 0; p < d.cols(); ++p) {
        const auto point = d.col(p);
        const double c[3] = {point.dot(axis[0]), point.dot(axis[1]), point.dot(axis[2])};
        for (int held = 0; held < 3; ++held) {
          projected[held][static_cast<size_t>(p)] =
              Eigen::Vector2d(c[(held + 1) % 3], c[(held + 2) % 3]);
        }
      }
      for (int held = 0; held < 3; ++held) {
        hulls[held].See(projected[held].data(), static_cast<size_t>(d.cols()));
        const Eigen::RowVectorXd along = start.col(held).transpose() * d;
        along_lo[held] = std::min(along_lo[held], along.minCoeff());
        along_hi[held] = std::max(along_hi[held], along.maxCoeff());
      }
    });
    for (int held = 0; held < 3; ++held) {
      const Eigen::Vector3d& u = axis[(held + 1) % 3];
      const Eigen::Vector3d& v = axis[(held + 2) % 3];
      StreamedHull& hull = hulls[held];
      std::vector<Eigen::Vector2d>& chunk = projected[held];
      // A cloud of one chunk: `chunk` still holds the projections the first pass made (the
      // same expressions), so the passes offer them as they are.
      const bool one_chunk = n <= kFramePassPoints;
      while (!hull.done()) {
        hull.BeginPass();
        if (one_chunk) {
          hull.Offer(chunk.data(), n);
          hull.EndPass();
          continue;
        }
        chunks.ForEach([&](size_t, const Eigen::Matrix3Xd& d) {
          for (Eigen::Index p = 0; p < d.cols(); ++p) {
            const auto point = d.col(p);
            chunk[static_cast<size_t>(p)] = Eigen::Vector2d(point.dot(u), point.dot(v));
          }
          hull.Offer(chunk.data(), static_cast<size_t>(d.cols()));
        });
        hull.EndPass();
      }
      Eigen::Vector2d e;
      double area;
      if (!MinAreaRectangle(hull.Hull(), &e, &area)) continue;
      const double volume = area * (along_hi[held] - along_lo[held]);
      if (volume < best_volume) {
        improved = true;
        best_volume = volume;
        best.col(0) = start.col(held);
        best.col(1) = e.x() * u + e.y() * v;
        best.col(2) = e.x() * v - e.y() * u;
      }
    }
  }
  return OrderAndSign(best, chunks, 3, skewness);
}

// The upright frame: the third axis is the client's vertical (`up`: e.g. from a robot's
// IMU, pointing up); the first two are the sides of the smallest-area rectangle around the
// points seen from above, ordered by extent and signed by skewness. Invariant to any turn
// about the vertical (yaw) and to mirroring in the horizontal plane; it keeps which way is
// up, which the box frame cannot know.
Eigen::Matrix3d UprightAxes(const PointCloud& cloud, const Eigen::Vector3d& centroid,
                            DfsdOptions::Up up, size_t hull_candidates, Eigen::Vector3d* skewness) {
  const Eigen::Matrix3d basis = UpBasis(up);
  CenteredChunks chunks(cloud, centroid);
  StreamedHull hull(cloud.size(), hull_candidates);
  std::vector<Eigen::Vector2d> projected(std::min(cloud.size(), kFramePassPoints));
  // The basis holds one signed 1 per column: these products are exact.
  const auto project = [&](const Eigen::Matrix3Xd& d) {
    for (Eigen::Index p = 0; p < d.cols(); ++p) {
      projected[static_cast<size_t>(p)] = basis.leftCols<2>().transpose() * d.col(p);
    }
  };
  chunks.ForEach([&](size_t, const Eigen::Matrix3Xd& d) {
    project(d);
    hull.See(projected.data(), static_cast<size_t>(d.cols()));
  });
  while (!hull.done()) {
    hull.BeginPass();
    chunks.ForEach([&](size_t, const Eigen::Matrix3Xd& d) {
      project(d);
      hull.Offer(projected.data(), static_cast<size_t>(d.cols()));
    });
    hull.EndPass();
  }
  Eigen::Matrix3d axes = basis;
  Eigen::Vector2d e;
  double area;
  // A cloud whose points all lie on one vertical line keeps the basis.
  if (MinAreaRectangle(hull.Hull(), &e, &area)) {
    axes.col(0) = e.x() * basis.col(0) + e.y() * basis.col(1);
    axes.col(1) = e.x() * basis.col(1) - e.y() * basis.col(0);
  }
  return OrderAndSign(axes, chunks, 2, skewness);
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

ScatterSum::ScatterSum(size_t n)
    // Eigen evaluates a product through coefficients below EIGEN_GEMM_TO_COEFFBASED_THRESHOLD
    // (rows + columns + depth < 20), through GEMM above.
    : coefficient_loop_(n + 3 + 3 < EIGEN_GEMM_TO_COEFFBASED_THRESHOLD) {
  Eigen::Index depth = static_cast<Eigen::Index>(n), rows = 3, cols = 3;
  Eigen::internal::computeProductBlockingSizes<double, double, 1>(depth, rows, cols,
                                                                  Eigen::Index{1});
  block_ = static_cast<size_t>(depth);
}

void ScatterSum::Add(const Eigen::Matrix3Xd& columns) {
  for (Eigen::Index p = 0; p < columns.cols(); ++p) {
    const double x[3] = {columns(0, p), columns(1, p), columns(2, p)};
    if (coefficient_loop_) {
      for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) {
          total_[i][j] = seen_ == 0 ? x[i] * x[j] : total_[i][j] + x[i] * x[j];
        }
      }
    } else {
      for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) block_sum_[i][j] = block_sum_[i][j] + x[i] * x[j];
      }
      if (++in_block_ == block_) Flush();
    }
    ++seen_;
  }
}

void ScatterSum::Flush() {
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) {
      total_[i][j] = total_[i][j] + block_sum_[i][j];
      block_sum_[i][j] = 0;
    }
  }
  in_block_ = 0;
}

Eigen::Matrix3d ScatterSum::Sum() {
  if (in_block_ > 0) Flush();
  Eigen::Matrix3d sum;
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) sum(i, j) = total_[i][j];
  }
  return sum;
}

double EigenOrderSum::Sum() const {
  if (n_ == 0) return 0;
  double sum;
  if (end2_ == 0) {
    return last_;  // one value
  } else if (end4_ == 0) {
    sum = pair_[0] + pair_[1];  // one packet
  } else {
    double low = lane_[0] + lane_[2], high = lane_[1] + lane_[3];
    if (end2_ > end4_) {
      low = low + pair_[0];
      high = high + pair_[1];
    }
    sum = low + high;
  }
  return n_ > end2_ ? sum + last_ : sum;
}

size_t FrameBytes(size_t n, DfsdOptions::Frame frame) {
  if (frame == DfsdOptions::Frame::kAxes || frame == DfsdOptions::Frame::kPca) return 0;
  const size_t chunk = std::min(n, kFramePassPoints);
  // The centered chunk, a product of it (q or the extents along an axis), projections.
  const size_t columns = 3 * sizeof(double) * chunk;
  const size_t projections =
      (frame == DfsdOptions::Frame::kBox ? 3 : 1) * chunk * sizeof(Eigen::Vector2d);
  // The box frame's three hulls of a round see their octagons together, then are made one
  // after another.
  const size_t hulls = (frame == DfsdOptions::Frame::kBox ? 3 : 1) *
                           (StreamedHull::IdleBytes() + sizeof(StreamedHull)) +
                       StreamedHull::PeakBytes(n);
  return 2 * columns + chunk * sizeof(double) + projections + hulls;
}

CloudFrame CloudFrame::Find(const PointCloud& cloud, const CloudStats& stats,
                            const DfsdOptions& options, size_t hull_candidates) {
  CloudFrame frame;
  frame.centroid_ = stats.centroid;
  Eigen::Vector3d lo = stats.min;
  Eigen::Vector3d hi = stats.max;
  if (options.frame != DfsdOptions::Frame::kAxes) {
    frame.input_axes_ = false;
    frame.axes_ =
        options.frame == DfsdOptions::Frame::kPca ? PrincipalFrame(cloud, stats.centroid)
        : options.frame == DfsdOptions::Frame::kBox
            ? BoxAxes(cloud, stats.centroid, hull_candidates, &frame.skewness_)
            : UprightAxes(cloud, stats.centroid, options.up, hull_candidates, &frame.skewness_);
    lo.setConstant(std::numeric_limits<double>::infinity());
    hi = -lo;
    for (size_t p = 0; p < cloud.size(); ++p) {
      const Eigen::Vector3d q = frame.Rotated(cloud, p);
      lo = lo.cwiseMin(q);
      hi = hi.cwiseMax(q);
    }
  }
  frame.center_ = 0.5 * (lo + hi);
  frame.half_extent_ = 0.5 * (hi - lo);
  return frame;
}

Eigen::Vector3d CloudFrame::Rotated(const PointCloud& cloud, size_t p) const {
  return axes_.transpose() * (cloud.point(p).cast<double>() - centroid_);
}

void CloudFrame::Coordinates(const PointCloud& cloud, size_t first, size_t count,
                             double* const coord[3]) const {
  if (input_axes_) {
    const float* xyz = cloud.data() + 3 * first;
    for (size_t p = 0; p < count; ++p) {
      for (int a = 0; a < 3; ++a) coord[a][p] = static_cast<double>(xyz[3 * p + a]) - center_[a];
    }
    return;
  }
  for (size_t p = 0; p < count; ++p) {
    const Eigen::Vector3d q = Rotated(cloud, first + p);
    for (int a = 0; a < 3; ++a) coord[a][p] = q[a] - center_[a];
  }
}

}  // namespace dfsd_internal
}  // namespace shapeid
