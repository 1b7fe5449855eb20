#ifndef SHAPEID_CORE_IO_OBJ_READER_H_
#define SHAPEID_CORE_IO_OBJ_READER_H_

#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "core/io/read_options.h"

namespace shapeid {

// Parses a Wavefront OBJ mesh held in memory, with Debian's tinyobjloader; `name` is the file
// name that every error message starts with. Reads `v x y z` vertices (a w or color after
// them is ignored) and `f` faces of any size in every form (`i`, `i/t`, `i//n`, `i/t/n`;
// negative indices count back from the last vertex read so far). Normals, texture
// coordinates, lines, points, groups, objects, smoothing groups and materials are skipped:
// `mtllib` never opens a file, so a missing .mtl is not an error. '#' starts a comment line;
// tinyobjloader has no trailing comments, so "f 1 2 3 # c" is an error (index 0), and it reads
// indices with atoi, so characters after an index's digits ("3x") are ignored.
// As for OFF, the faces are sampled to ReadOptions::sample_points points, area-weighted and
// seeded with sample_seed (polygons split into fans); sample_points 0, or a file with
// vertices and no faces (a point cloud saved as OBJ), returns the vertices.
// InvalidArgument, naming `name` and the line where there is one, for: an empty file, no
// vertices, a vertex without three numeric coordinates, a face with fewer than 3 vertices or
// an index that is 0, not a number or out of range, and nothing of positive area to sample.
absl::StatusOr<ReadResult> ParseObj(absl::string_view contents, absl::string_view name,
                                    const ReadOptions& options = {});

}  // namespace shapeid

#endif  // SHAPEID_CORE_IO_OBJ_READER_H_
