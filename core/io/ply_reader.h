#ifndef SHAPEID_CORE_IO_PLY_READER_H_
#define SHAPEID_CORE_IO_PLY_READER_H_

#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "core/io/read_options.h"

namespace shapeid {

// Parses a PLY file (Stanford polygon format) held in memory: format ascii 1.0,
// binary_little_endian 1.0 or binary_big_endian 1.0. Every element and property is parsed,
// whatever its type (char/int8, uchar/uint8, short/int16, ushort/uint16, int/int32,
// uint/uint32, float/float32, double/float64) or list type, so unknown elements (edges,
// materials) and properties (normals, colors) are skipped. The "vertex" element must have
// scalar x, y and z properties. A file with faces (a "face" element of at least one instance)
// is a mesh: ReadOptions::sample_points points are sampled on its polygons (list property
// vertex_indices or vertex_index), area-weighted and seeded with sample_seed, as for OFF and
// OBJ; sample_points 0, or a file without faces, gives the vertices.
// InvalidArgument, naming `name` and the header line, data line (ascii) or byte offset
// (binary), for malformed contents: a bad header, missing x / y / z, truncated or extra data,
// non-numeric values, out-of-range vertex indices, a mesh without a face of positive area. A
// face element without a vertex_indices list is no mesh: the vertices are read.
absl::StatusOr<ReadResult> ParsePly(absl::string_view contents, absl::string_view name,
                                    const ReadOptions& options = {});

}  // namespace shapeid

#endif  // SHAPEID_CORE_IO_PLY_READER_H_
