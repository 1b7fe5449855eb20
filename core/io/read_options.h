#ifndef SHAPEID_CORE_IO_READ_OPTIONS_H_
#define SHAPEID_CORE_IO_READ_OPTIONS_H_

#include <cstddef>
#include <cstdint>

#include "Eigen/Core"
#include "core/point_cloud.h"

namespace shapeid {

// How the point-cloud readers turn a file into a PointCloud. Every reader honours
// drop_non_finite and recenter; the sample_* fields concern the mesh formats (PLY, OFF, OBJ).
struct ReadOptions {
  // Organised PCD clouds (from depth cameras) mark missing pixels with NaN points. Default
  // false: they are kept, so that describing the cloud fails and says so, rather than
  // silently describing fewer points than the file holds. When true, every point with a
  // non-finite coordinate is removed and ReadResult::dropped_non_finite counts them.
  bool drop_non_finite = false;

  // Default true: coordinates are parsed in double and the cloud is shifted by its
  // bounding-box centre (computed in double, over the finite points) before conversion to
  // float, because float32 cannot hold georeferenced coordinates (e.g. DALES, ~5e5 m) to the
  // centimetre (its spacing there is 3 cm to 6 cm), and every descriptor is translation
  // invariant, so the shift costs nothing. ReadResult::offset gives the shift back. False
  // keeps the file's coordinates (rounded to float), e.g. for viewing alongside other data.
  bool recenter = true;

  // Meshes (PLY with faces, OFF, OBJ) can be sampled to points on their surface, area-weighted:
  // each point picks a triangle (polygons are split into fans) with probability proportional
  // to its area, then a uniform point in it. The PRNG is splitmix64 seeded with sample_seed,
  // so the same file, count and seed give the same points everywhere.

  // PLY: 0 (default) reads the vertex element as the cloud; N > 0 samples N points on the
  // faces instead (an error if the file has no face element).
  size_t sample_faces = 0;
  // OFF and OBJ: the number of points sampled on the mesh; 0 reads the vertices as the cloud.
  // An OBJ without faces (a point cloud saved as OBJ) gives its vertices whatever the value.
  size_t sample_points = 2048;
  // Seed for both kinds of sampling.
  uint64_t sample_seed = 0;
};

// A cloud as read, and what reading did to it.
struct ReadResult {
  PointCloud cloud;
  // The shift applied by ReadOptions::recenter: file coordinate = cloud point + offset.
  // Zero when recenter is false or the cloud has no finite point.
  Eigen::Vector3d offset = Eigen::Vector3d::Zero();
  // Points removed by ReadOptions::drop_non_finite; always 0 when it is false.
  size_t dropped_non_finite = 0;
};

}  // namespace shapeid

#endif  // SHAPEID_CORE_IO_READ_OPTIONS_H_
