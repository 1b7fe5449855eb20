#ifndef SHAPEID_CORE_IO_NPY_READER_H_
#define SHAPEID_CORE_IO_NPY_READER_H_

#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "core/io/read_options.h"

namespace shapeid {

// Parses a NumPy .npy array (format versions 1.0, 2.0 and 3.0) held in memory; `name` is the
// file name that every error message starts with, followed by the byte offset of the problem.
// The header's dict literal is parsed here (no Python): keys in any order, either quote, any
// whitespace, a trailing comma, Python 2's "3L" integers. The array is read as points, in
// NumPy's index order (C order whatever fortran_order says):
//  - shape (N, C) with C >= 3: x y z are the first three columns, the others (normals,
//    colors, intensity) are skipped; (H, W, C) is an organized cloud of H * W points;
//  - a structured dtype (descr a list of fields, as ros_numpy, PCL and Open3D exports write)
//    of shape (N,) or (H, W): the fields named 'x', 'y' and 'z' (lower case) are read, every
//    other field is skipped by its size, whatever its type (sub-arrays and nested records too);
//  - coordinates of any float or integer dtype: f2, f4, f8, i1..i8, u1..u8 ('<' or '>', '|'
//    for one-byte types, '=' or none for the host's order); integers are read as their value
//    (e.g. depth-image units), without scaling.
// A shape with no element ((0, 3)) gives an empty cloud. Like np.load, contents starting with
// a zip archive's signature are read as by ParseNpz.
// Errors:
//  - InvalidArgument: a bad magic string, a header length past the end of the file or over
//    1 MiB (numpy's own limit is 10000 bytes), a header that is not a dict literal
//    with exactly 'descr', 'fortran_order' and 'shape', a malformed type string ('|f4', 'i3'),
//    object arrays ('|O': "pickled object arrays are not read"), a shape that is not a point
//    array ((3,), (N, 2), 4-D), a structured dtype without an 'x', 'y' or 'z' field, data whose
//    size differs from product(shape) * itemsize (expected and actual bytes), a coordinate
//    that does not fit in a float;
//  - Unimplemented: format versions other than 1.0, 2.0 and 3.0, coordinates of another kind
//    (bool, complex, long double, strings, datetimes), 'x', 'y' or 'z' fields that are
//    sub-arrays or nested records.
absl::StatusOr<ReadResult> ParseNpy(absl::string_view contents, absl::string_view name,
                                    const ReadOptions& options = {});

// Parses a NumPy .npz archive held in memory: a zip of .npy members, stored or deflated, as
// numpy.savez and numpy.savez_compressed write (ZIP64 included). The member read is the first
// of points.npy, xyz.npy, pcd.npy, cloud.npy, arr_0.npy found, in that priority, or else the
// only member; it is parsed as by ParseNpy, with "<name>:<member>" starting its messages. Like
// np.load, contents starting with the .npy magic string are read as by ParseNpy.
// Errors:
//  - InvalidArgument: no end-of-central-directory record, central directory or local headers
//    out of bounds or with a wrong signature, missing ZIP64 fields, several members none of
//    which has a known name (the message lists them), sizes that exceed the archive (stored)
//    or that deflate cannot reach (over 1032:1), corrupt deflate data, a CRC-32 mismatch;
//  - Unimplemented: split (multi-disk) archives, encrypted members, compression methods
//    other than stored (0) and deflate (8), named in the message.
absl::StatusOr<ReadResult> ParseNpz(absl::string_view contents, absl::string_view name,
                                    const ReadOptions& options = {});

}  // namespace shapeid

#endif  // SHAPEID_CORE_IO_NPY_READER_H_
