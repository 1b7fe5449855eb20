#ifndef SHAPEID_CORE_IO_PCD_WRITER_H_
#define SHAPEID_CORE_IO_PCD_WRITER_H_

#include <string>

#include "absl/status/status.h"
#include "core/point_cloud.h"

namespace shapeid {

enum class PcdEncoding {
  // One "x y z" line per point, each value with 9 significant digits (%.9g), which is enough
  // for every float to read back bit-identical. About 3x larger than binary; readable.
  kAscii,
  // The points' float32 xyz triples, host byte order, as PCL writes DATA binary.
  kBinary,
};

// The bytes of a PCD v0.7 file holding `cloud`: FIELDS x y z, SIZE 4 4 4, TYPE F F F,
// COUNT 1 1 1, WIDTH n, HEIGHT 1 (unorganized), VIEWPOINT 0 0 0 1 0 0 0, POINTS n, then the data.
// Non-finite coordinates are written as they are ("nan", "inf" in ascii). ParsePcd and PCL read
// the result back; with ReadOptions::recenter false, to the same bits.
std::string EncodePcd(const PointCloud& cloud, PcdEncoding encoding);

// Writes EncodePcd(cloud, encoding) to `path` as WriteFileAtomically (core/io/file_writer.h)
// does: never half-written, errors naming the path.
absl::Status WritePcd(const std::string& path, const PointCloud& cloud,
                      PcdEncoding encoding = PcdEncoding::kBinary);

}  // namespace shapeid

#endif  // SHAPEID_CORE_IO_PCD_WRITER_H_
