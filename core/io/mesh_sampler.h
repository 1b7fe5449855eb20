#ifndef SHAPEID_CORE_IO_MESH_SAMPLER_H_
#define SHAPEID_CORE_IO_MESH_SAMPLER_H_

#include <cstddef>
#include <cstdint>
#include <vector>

#include "absl/status/status.h"
#include "absl/strings/string_view.h"
#include "core/io/cloud_accumulator.h"
#include "core/random.h"

namespace shapeid {

// Internal to core/io: the mesh readers (PLY, OFF, OBJ, STL, VTK) collect vertices and triangles
// here, then sample points on the surface, area-weighted, with a seeded PRNG of our own
// (splitmix64), so the same file and seed give the same points with every standard library.
class TriangleMesh {
 public:
  void AddVertex(double x, double y, double z);
  size_t vertex_count() const { return xyz_.size() / 3; }

  // Adds a polygon as a fan of triangles (a, b, c), (a, c, d), ... `where` locates the face in
  // the file for messages. The indices must have been checked against vertex_count().
  void AddPolygon(const std::vector<uint64_t>& indices, uint64_t where);
  size_t triangle_count() const { return triangles_.size(); }

  // Adds `n` points sampled uniformly on the surface to `cloud`. InvalidArgument, naming `name`
  // and the face (`where_label` and its location), for a face with a non-finite vertex; and
  // when the mesh has no face of positive area.
  absl::Status Sample(size_t n, uint64_t seed, absl::string_view name,
                      absl::string_view where_label, CloudAccumulator* cloud) const;

 private:
  struct Triangle {
    uint64_t v[3];
    uint64_t where;
  };
  std::vector<double> xyz_;
  std::vector<Triangle> triangles_;
};

}  // namespace shapeid

#endif  // SHAPEID_CORE_IO_MESH_SAMPLER_H_
