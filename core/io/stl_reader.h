#ifndef SHAPEID_CORE_IO_STL_READER_H_
#define SHAPEID_CORE_IO_STL_READER_H_

#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "core/io/read_options.h"

namespace shapeid {

// Parses an STL mesh held in memory, binary or ascii:
//  - binary when the size is exactly 84 + 50 * count (an 80-byte header, the uint32 triangle
//    count, then per triangle a normal and 3 vertices as little-endian float32 and a uint16
//    attribute), whatever the header says: many binary files (SolidWorks) start with "solid";
//    also, when the file is not ascii, the first `count` records of a longer file, or every
//    record of a file whose size is 84 plus whole records but whose count is wrong (exporters
//    write both);
//  - otherwise ascii when it starts, after blanks, with "solid" and holds no NUL byte: one or
//    more "solid [name]" ... "endsolid [name]" blocks of "facet normal nx ny nz", "outer loop",
//    three "vertex x y z", "endloop", "endfacet"; keywords are case-insensitive; the rest of
//    the "solid" line is its name.
// The mesh is sampled to ReadOptions::sample_points points, area-weighted and seeded with
// sample_seed, as for every mesh format; sample_points 0 gives the vertices, 3 per triangle in
// file order (shared corners are not merged). Normals and attributes are ignored.
// InvalidArgument, naming `name` and the line (ascii) or byte offset (binary): a file that is
// neither (the message gives the size a binary file of its triangle count would have), a
// misplaced or missing keyword, a non-numeric value, a facet without exactly 3 vertices, a
// missing endsolid, a non-finite vertex or no surface area when sampling.
absl::StatusOr<ReadResult> ParseStl(absl::string_view contents, absl::string_view name,
                                    const ReadOptions& options = {});

// True when `contents` are an STL file by their start or size: ASCII's "solid" as a word, or a
// binary file weighing exactly what its triangle count says (so a binary file whose header
// says "solid" is binary here, as in ParseStl). For files whose name names no format.
bool HasStlSignature(absl::string_view contents);

}  // namespace shapeid

#endif  // SHAPEID_CORE_IO_STL_READER_H_
