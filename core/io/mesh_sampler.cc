#include "core/io/mesh_sampler.h"

#include <algorithm>
#include <cmath>
#include <utility>

#include "Eigen/Core"
#include "Eigen/Geometry"
#include "absl/strings/str_cat.h"

namespace shapeid {

void TriangleMesh::AddVertex(double x, double y, double z) {
  xyz_.push_back(x);
  xyz_.push_back(y);
  xyz_.push_back(z);
}

void TriangleMesh::AddPolygon(const std::vector<uint64_t>& indices, uint64_t where) {
  for (size_t k = 2; k < indices.size(); ++k) {
    triangles_.push_back(Triangle{{indices[0], indices[k - 1], indices[k]}, where});
  }
}

absl::Status TriangleMesh::Sample(size_t n, uint64_t seed, absl::string_view name,
                                  absl::string_view where_label, CloudAccumulator* cloud) const {
  const auto vertex = [this](uint64_t i) { return Eigen::Vector3d(&xyz_[3 * i]); };
  // Cumulative areas; degenerate triangles add nothing, so they are never chosen.
  std::vector<double> cumulative;
  cumulative.reserve(triangles_.size());
  double total = 0;
  for (const Triangle& t : triangles_) {
    const Eigen::Vector3d a = vertex(t.v[0]);
    const double area = 0.5 * (vertex(t.v[1]) - a).cross(vertex(t.v[2]) - a).norm();
    if (!std::isfinite(area)) {
      return absl::InvalidArgumentError(
          absl::StrCat(name, ": ", where_label, " ", t.where,
                       ": the face has a non-finite vertex or area; cannot sample it"));
    }
    total += area;
    cumulative.push_back(total);
  }
  if (n == 0) return absl::OkStatus();
  if (!(total > 0) || !std::isfinite(total)) {
    return absl::InvalidArgumentError(absl::StrCat(
        name, ": the mesh has ", triangles_.size(),
        " triangles and no surface area to sample points on",
        triangles_.empty() ? " (no faces; read its vertices instead by turning sampling off)"
                           : ""));
  }
  SplitMix64 rng(seed);
  cloud->Reserve(cloud->size() + n);
  for (size_t i = 0; i < n; ++i) {
    const double u = rng.Uniform() * total;
    const size_t k = std::min<size_t>(
        static_cast<size_t>(std::upper_bound(cumulative.begin(), cumulative.end(), u) -
                            cumulative.begin()),
        triangles_.size() - 1);
    const Triangle& t = triangles_[k];
    // Uniform on the triangle (Osada et al. 2002): s = sqrt(r1).
    const double s = std::sqrt(rng.Uniform());
    const double r2 = rng.Uniform();
    const Eigen::Vector3d p =
        (1 - s) * vertex(t.v[0]) + s * (1 - r2) * vertex(t.v[1]) + s * r2 * vertex(t.v[2]);
    cloud->Add(p.x(), p.y(), p.z(), t.where);
  }
  return absl::OkStatus();
}

}  // namespace shapeid
