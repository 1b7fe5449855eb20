#ifndef SHAPEID_CORE_IO_READ_OPTIONS_H_
#define SHAPEID_CORE_IO_READ_OPTIONS_H_

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>

#include "Eigen/Core"
#include "core/point_cloud.h"

namespace shapeid {

// The file formats ReadPointCloud (core/io/point_cloud_reader.h) knows, by extension
// (case-insensitive). Meshes (PLY with faces, OFF, OBJ with faces, STL, VTK with polygons) are
// sampled on their surface to ReadOptions::sample_points points; 0 reads their vertices.
//   .pcd               PCD v0.7, DATA ascii, binary or binary_compressed (core/io/pcd_reader.h)
//   .ply               PLY ascii / binary little or big endian (core/io/ply_reader.h)
//   .off               OFF mesh (core/io/off_reader.h)
//   .obj               Wavefront OBJ; an OBJ without faces gives its vertices
//   .stl               STL mesh, ascii or binary (core/io/stl_reader.h)
//   .vtk               legacy VTK polydata, ascii or binary (core/io/vtk_reader.h)
//   .las               LAS 1.0-1.4, every point format (core/io/las_reader.h); .laz is refused
//                      with the command that decompresses it
//   .npy .npz          NumPy arrays (core/io/npy_reader.h): float or integer, (N, 3+) or an
//                      organized (H, W, 3+), C or Fortran order, or structured with x, y, z
//                      fields; .npz as np.savez / np.savez_compressed write it
//   .xyz .txt .xyzn .xyzrgb
//                      text, blank- or comma-separated, x y z first (core/io/xyz_reader.h)
//   .pts               text as .xyz, whose lines holding a single integer (point counts) are
//                      skipped
//   .csv               text, comma- or semicolon-separated
// Any of them may be gzip-compressed (FILE.EXT.gz); contents starting with gzip's magic bytes
// are inflated before parsing, whatever the name.
enum class CloudFormat { kPcd, kPly, kOff, kObj, kStl, kVtk, kLas, kNpy, kNpz, kXyz, kPts, kCsv };

// How the point-cloud readers turn a file into a PointCloud. Every reader honours
// drop_non_finite and recenter; the sample_* fields concern the mesh formats.
struct ReadOptions {
  // Organized PCD clouds (from depth cameras) mark missing pixels with NaN points. Default
  // false: they are kept, so that describing the cloud fails and says so, rather than
  // silently describing fewer points than the file holds. When true, every point with a
  // non-finite coordinate is removed and ReadResult::dropped_non_finite counts them.
  bool drop_non_finite = false;

  // Default true: coordinates are parsed in double and the cloud is shifted by its
  // bounding-box center (computed in double, over the finite points) before conversion to
  // float, because float32 cannot hold georeferenced coordinates (e.g. DALES, ~5e5 m) to the
  // centimetre (its spacing there is 3 cm to 6 cm), and every descriptor is translation
  // invariant, so the shift costs nothing. ReadResult::offset gives the shift back. False
  // keeps the file's coordinates (rounded to float), e.g. for viewing alongside other data.
  bool recenter = true;

  // Meshes can be sampled to points on their surface, area-weighted:
  // each point picks a triangle (polygons are split into fans) with probability proportional
  // to its area, then a uniform point in it. The PRNG is splitmix64 seeded with sample_seed,
  // so the same file, count and seed give the same points everywhere.

  // The number of points sampled on a mesh's faces (PLY with a face element, OFF, OBJ, STL,
  // VTK with polygons or strips); 0 reads the vertices as the cloud. A file without faces (a
  // point cloud saved as PLY, OBJ or VTK) gives its vertices whatever the value.
  size_t sample_points = 2048;
  // Seed for the sampling.
  uint64_t sample_seed = 0;

  // A gzipped input inflating past this many bytes is refused (a decompression bomb would
  // otherwise take all memory): 8 GiB by default, about 700 million binary PCD points.
  size_t max_inflated_bytes = size_t{8} << 30;

  // When set, every input is parsed as this format whatever its name says; standard input
  // ("-") needs it, having no name.
  std::optional<CloudFormat> input_format;
};

// A cloud as read, and what reading did to it.
struct ReadResult {
  PointCloud cloud;
  // The shift applied by ReadOptions::recenter: file coordinate = cloud point + offset.
  // Zero when recenter is false or the cloud has no finite point.
  Eigen::Vector3d offset = Eigen::Vector3d::Zero();
  // Points removed by ReadOptions::drop_non_finite; always 0 when it is false.
  size_t dropped_non_finite = 0;
  // Points with a non-finite coordinate, dropped or not, found while reading, so that no caller
  // scans the cloud again for them. When there is one, the first one's index among the points
  // read (its index in `cloud` unless dropped) and where it is in the file ("line 12",
  // "byte offset 4096"; a mesh's sampled points have their face's place).
  size_t non_finite_points = 0;
  size_t first_non_finite = 0;
  std::string first_non_finite_location;
};

}  // namespace shapeid

#endif  // SHAPEID_CORE_IO_READ_OPTIONS_H_
