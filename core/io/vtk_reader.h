#ifndef SHAPEID_CORE_IO_VTK_READER_H_
#define SHAPEID_CORE_IO_VTK_READER_H_

#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "core/io/read_options.h"

namespace shapeid {

// Parses a legacy VTK file (".vtk", as vtkPolyDataWriter and pcl_pcd2vtk write it) held in
// memory: a "# vtk DataFile Version x.y" line, a title line, ASCII or BINARY, then
// "DATASET POLYDATA" and its sections, keywords case-insensitive:
//  - POINTS n <type>: 3n values, whitespace-separated (ascii) or big-endian (binary); <type> is
//    float, double, char, signed_char, unsigned_char, short, unsigned_short, int, unsigned_int,
//    long, unsigned_long (8 bytes), vtktypeint64, vtktypeuint64 or vtkIdType (4 bytes);
//  - VERTICES, LINES, POLYGONS, TRIANGLE_STRIPS n size: the legacy layout (VTK <= 4.2) of
//    `size` int32 values, each cell its count then its point indices; or the 5.x layout
//    "n m" followed by "OFFSETS <int type>" (n values) and "CONNECTIVITY <int type>" (m values);
//  - FIELD data and array METADATA blocks are skipped; parsing stops at POINT_DATA or
//    CELL_DATA, since attributes carry no geometry.
// With POLYGONS or TRIANGLE_STRIPS cells and ReadOptions::sample_points > 0, the surface is
// sampled as for every mesh format (polygons split into fans, strips into triangles
// (i, i+1, i+2)), area-weighted and seeded with sample_seed; otherwise the POINTS are the cloud
// (pcl_pcd2vtk writes a cloud as POINTS + VERTICES).
// DATASET UNSTRUCTURED_GRID and STRUCTURED_GRID give their POINTS as the cloud, whatever the
// options (their cells are not read); VTK writes POINTS before the cells.
// InvalidArgument, naming `name` and the line (header, ascii) or byte offset (binary), for
// malformed contents: a bad header, an unknown keyword or data type, a count beyond the data
// that follows, truncated binary data, a non-numeric value, a point index out of range, cells
// before POINTS, no POINTS section, nothing to sample. Unimplemented for datasets without
// points (STRUCTURED_POINTS, RECTILINEAR_GRID), graphs, tables and field-only files, and for
// FIELD arrays of strings.
absl::StatusOr<ReadResult> ParseVtk(absl::string_view contents, absl::string_view name,
                                    const ReadOptions& options = {});

}  // namespace shapeid

#endif  // SHAPEID_CORE_IO_VTK_READER_H_
