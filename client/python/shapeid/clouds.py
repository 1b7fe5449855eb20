"""Point clouds as robots hold them, turned into the bytes a shapeid server reads.

`encode` is the one entry point: it takes an N x 3 numpy array, an Open3D point cloud or a
ROS PointCloud2 message (ROS 1 or ROS 2, duck-typed) and returns an `EncodedCloud`: the
points' bytes and the `Layout` they are in.

- numpy arrays and Open3D clouds are converted by value into `PACKED_XYZ32`, the wire's
  default packed little-endian float32 x y z (proto PointChunk): float64 is rounded to the
  nearest float32, big-endian is swapped, never a reinterpretation of bytes.
- a PointCloud2's `data` goes as it is, with the layout its fields declare (proto
  PointLayout: point_step, x/y/z offset and FLOAT32/FLOAT64, is_bigendian, width/row_step
  of padded rows): the server decodes it into the same float32 x y z. The declaration is
  checked here with the same errors as before forwarding, and so are the coordinates (one
  strided pass); the server's own checks remain (overlapping x, y, z: its
  InvalidArgumentError). So that a sensor's bytes are never silently misread, every field
  (not only x, y, z) must fit in point_step, rows must pad by less than one point, and bytes
  that betray a mis-declared layout are refused as the server refuses them: a wrong
  is_bigendian or FLOAT32 and FLOAT64 exchanged (_layout_survey), a FLOAT64 coordinate
  float32 cannot hold. `encode(..., forward_point_cloud2=False)` converts it
  into PACKED_XYZ32 instead (Client.train does so for a stream mixing layouts).

Errors are raised before anything is sent: TypeError for something that is not a cloud or
an unsupported element type, ValueError for a cloud of the wrong shape, a mis-declared
PointCloud2, a coordinate beyond float32's range, or non-finite points when
drop_non_finite is False (the default, as in the CLI's --drop-nonfinite).
"""

import dataclasses
import sys

import numpy as np

from . import _layout_survey

__all__ = ["EncodedCloud", "Layout", "PACKED_XYZ32", "encode", "FLOAT32", "FLOAT64"]

# sensor_msgs/PointField datatypes (the same numbers in ROS 1 and ROS 2).
_DATATYPE_NAMES = {1: "INT8", 2: "UINT8", 3: "INT16", 4: "UINT16", 5: "INT32", 6: "UINT32",
                   7: "FLOAT32", 8: "FLOAT64"}
_DATATYPE_SIZES = {1: 1, 2: 1, 3: 2, 4: 2, 5: 4, 6: 4, 7: 4, 8: 8}
FLOAT32 = 7
FLOAT64 = 8
_FLOAT_SIZES = {FLOAT32: 4, FLOAT64: 8}
_PC2_ATTRIBUTES = ("height", "width", "fields", "is_bigendian", "point_step", "row_step", "data")
_EXPECTED = ("an N x 3 numpy array of floats, an open3d.geometry.PointCloud or a "
             "sensor_msgs PointCloud2 message")


@dataclasses.dataclass(frozen=True)
class Layout:
    """Where x, y and z sit in each point's bytes, as a PointCloud2 declares it (proto
    PointLayout). width and row_step are set only for rows padded beyond their points."""
    point_step: int
    offsets: tuple      # byte offsets of x, y, z
    datatypes: tuple    # of x, y, z: FLOAT32 or FLOAT64
    big_endian: bool
    width: int = 0      # points per row, when rows are padded
    row_step: int = 0   # bytes from one row to the next, when rows are padded


# The wire's default (proto PointChunk.xyz without a PointLayout): 12 bytes a point, float32
# x y z, little-endian.
PACKED_XYZ32 = Layout(point_step=12, offsets=(0, 4, 8), datatypes=(FLOAT32,) * 3,
                      big_endian=False)


@dataclasses.dataclass(slots=True)
class EncodedCloud:
    """A cloud ready for the wire: `num_points` points in `data`, laid out as `layout`.
    `data` is a read-only byte view over the converted points (over the caller's own array
    when that was already packed little-endian float32, over a PointCloud2's own data when
    forwarded): protobuf copies the bytes it sends, so they are copied once, a message at a
    time, not once more here."""
    data: memoryview
    num_points: int
    layout: Layout
    # Points with a non-finite coordinate (drop_non_finite=True): left out of `data` for
    # PACKED_XYZ32; in `data` for a forwarded PointCloud2, for the server to drop (counted
    # in num_points, as the server counts them).
    dropped_non_finite: int = 0

    def tobytes(self):
        return self.data.tobytes()

    def chunks(self, points_per_chunk):
        """The bytes in runs of `points_per_chunk` x point_step bytes (at least one run): whole
        points for PACKED_XYZ32; a padded layout's runs may end inside a row, as the server
        accepts."""
        step = points_per_chunk * self.layout.point_step
        if len(self.data) <= step:
            yield self.data.tobytes()
            return
        for start in range(0, len(self.data), step):
            yield self.data[start:start + step].tobytes()


def encode(cloud, *, drop_non_finite=False, keep_non_finite=False, forward_point_cloud2=True):
    """`cloud` as an EncodedCloud (see the module's comment for what is accepted).

    drop_non_finite: False (the default) refuses a cloud with a NaN or infinite coordinate
    (ValueError naming how many and the first); True leaves those points out (organized
    depth-camera clouds mark missing returns with NaN): here for arrays, on the server for
    a forwarded PointCloud2 (the layout says so).
    keep_non_finite: True sends such points as they are, in place (a scene: the server skips
    and counts them, and indices count every point sent).
    forward_point_cloud2: False converts a PointCloud2 into PACKED_XYZ32 as arrays are.
    """
    width = None  # of an organized cloud, to name a point by row and column
    if isinstance(cloud, np.ndarray):
        points, source = _from_array(cloud)
        what = "the array"
    elif _looks_like_point_cloud2(cloud):
        declared = _declared_point_cloud2(cloud)
        width = declared.width if declared.height > 1 else None
        what = "PointCloud2"
        if declared.height * declared.width == 0:
            points, source = np.empty((0, 3), _F32LE), None
        else:
            points, source = None, None
            if forward_point_cloud2:
                values, source = _point_cloud2_values(declared, packed=False)
                _check_narrowing(values, source, declared, width, what)
                dropped = 0
                # float64: `values` is their float32 rounding, isfinite's fast path is as quick
                if source is not None or not _sums_finite(values):
                    _, dropped = _finite(values, drop_non_finite or keep_non_finite, width,
                                         source, what, keep=False)
                # Already packed float32 xyz with points to drop: dropped here, as an array's.
                if keep_non_finite or not (dropped and declared.layout == PACKED_XYZ32):
                    return EncodedCloud(data=memoryview(declared.data).toreadonly(),
                                        num_points=declared.height * declared.width,
                                        layout=declared.layout, dropped_non_finite=0 if keep_non_finite else dropped)
            points, source = _point_cloud2_values(declared, packed=True)
            _check_narrowing(points, source, declared, width, what)
            points = points.reshape(-1, 3)
    elif hasattr(cloud, "points") and not isinstance(cloud, (str, bytes, dict)):
        what = type(cloud).__name__ + ".points"
        try:
            points, source = _from_array(np.asarray(cloud.points))
        except (TypeError, ValueError) as e:
            raise type(e)(what + str(e)[len("the array"):]) from None
    else:
        raise TypeError("expected %s; got %s%s" % (_EXPECTED, _type_name(cloud), _hint(cloud)))
    # keep_non_finite: counted and checked for float32 overflow, never left out.
    points, dropped = _finite(points, drop_non_finite or keep_non_finite, width, source, what,
                              keep=not keep_non_finite)
    data = memoryview(points.reshape(-1).view(np.uint8)).toreadonly()
    return EncodedCloud(data=data, num_points=len(points), layout=PACKED_XYZ32,
                        dropped_non_finite=0 if keep_non_finite else dropped)


# ---------------------------------------------------------------------------------------------
# numpy arrays (and Open3D's .points, a float64 N x 3 view)

_F32LE = np.dtype("<f4")
_FLOAT32_MAX = float(np.finfo(np.float32).max)
_FLOAT32_MIN = float(np.finfo(np.float32).tiny)  # the smallest normal


def _from_array(array):
    """(points, source): an (N, 3) C-contiguous little-endian float32 array holding `array`'s
    values, and `array` itself when its values may overflow float32 (else None)."""
    if array.dtype.kind != "f":
        if array.dtype.kind in "iub":
            raise TypeError(
                "the array has dtype %s: points must be floating point. If the integers are "
                "coordinates, convert them explicitly: cloud.astype(numpy.float32)" % array.dtype)
        raise TypeError("the array has dtype %s: points must be float16, float32 or float64"
                        % array.dtype)
    if array.ndim != 2 or array.shape[1] != 3:
        hint = ""
        if array.ndim == 2 and array.shape[0] == 3:
            hint = ": points are rows; for 3 x N coordinates pass cloud.T"
        elif array.ndim == 2 and array.shape[1] > 3:
            hint = ": shapeid takes x y z only; pass cloud[:, :3]"
        elif array.ndim == 1 and array.size % 3 == 0:
            hint = ": for a flat x y z x y z ... array pass cloud.reshape(-1, 3)"
        raise ValueError("the array has shape %s; expected (N, 3), one x y z row per point%s"
                         % (array.shape, hint))
    if array.dtype == _F32LE and array.flags.c_contiguous:
        return array, None
    out = np.empty(array.shape, _F32LE)
    with np.errstate(over="ignore", invalid="ignore"):
        out[...] = array   # by value: rounds float64, swaps big-endian, gathers any strides
    return out, (array if array.dtype.itemsize > 4 else None)


def _sums_finite(values):
    """True when x + y + z of every point of `values` (rows, columns, 3) is finite: then no
    coordinate is NaN or infinite. One BLAS pass over a strided view (2.4 ms for 1,000,000
    points in 32-byte records, half of numpy.isfinite's over the same view); False sends the
    cloud to _finite's exact check (also when only a sum overflowed)."""
    with np.errstate(all="ignore"):
        sums = values @ np.ones(3, values.dtype.newbyteorder("="))
    return bool(np.isfinite(sums).all())


def _finite(points, drop, width, source, what, keep=True):
    """(points without non-finite rows (drop) or unchanged, how many were non-finite);
    ValueError if any and not drop, or if a finite value of `source` (the values before
    conversion, or a function giving them) overflowed float32. `points`: (N, 3), or
    (rows, columns, 3) of an organized cloud, any strides; `width`: the row length of an
    organized cloud. keep=False: only count (the points stay as they are)."""
    finite = np.isfinite(points)
    if finite.all():  # one pass over the points when all is well
        return points, 0
    points, finite = points.reshape(-1, 3), finite.reshape(-1, 3)
    if source is not None:
        source = source() if callable(source) else source
        overflow = ~finite & np.isfinite(source)
        if overflow.any():
            row, axis = np.argwhere(overflow)[0]
            raise ValueError(
                "%s: point %d: %s = %r does not fit in a float32 (|value| <= %.4g); subtract "
                "an offset first (every descriptor is translation invariant)"
                % (what, row, "xyz"[axis], float(source[row, axis]), _FLOAT32_MAX))
    rows = finite.all(axis=1)
    bad = len(points) - int(np.count_nonzero(rows))
    if not drop:
        first = int(np.argmin(rows))
        where = "point %d" % first
        if width:
            where += " (row %d, column %d)" % divmod(first, width)
        raise ValueError(
            "%d of %d points have a NaN or infinite coordinate (the first: %s, %s); pass "
            "drop_non_finite=True to leave them out"
            % (bad, len(points), where, points[first].tolist()))
    return (points[rows] if keep else points), bad


# ---------------------------------------------------------------------------------------------
# sensor_msgs/PointCloud2, ROS 1 or ROS 2

def _looks_like_point_cloud2(cloud):
    return any(hasattr(cloud, a) for a in ("fields", "point_step", "row_step"))


@dataclasses.dataclass(frozen=True)
class _Declared:
    """A PointCloud2's declaration, checked: its layout and data (see _declared_point_cloud2)."""
    height: int
    width: int
    row_step: int
    layout: Layout
    data: object  # bytes-like, height x row_step bytes


def _declared_point_cloud2(msg):
    """The PointCloud2's declaration, checked as the server would: ValueError / TypeError
    naming what does not hold together (the server's own checks stay as a second line)."""
    missing = [a for a in _PC2_ATTRIBUTES if not hasattr(msg, a)]
    if missing:
        raise TypeError("%s looks like a PointCloud2 but has no %s; expected %s"
                        % (_type_name(msg), ", ".join(missing), _EXPECTED))
    height, width = _count(msg.height, "height"), _count(msg.width, "width")
    point_step, row_step = _count(msg.point_step, "point_step"), _count(msg.row_step, "row_step")
    big_endian = bool(msg.is_bigendian)
    data = _bytes_of(msg.data)
    if height * width == 0:
        return _Declared(height, width, row_step, PACKED_XYZ32, b"")
    if point_step == 0:
        raise ValueError("PointCloud2: point_step is 0")
    if row_step < width * point_step:
        raise ValueError("PointCloud2: row_step %d < width %d x point_step %d"
                         % (row_step, width, point_step))
    if len(data) != height * row_step:
        raise ValueError("PointCloud2: data holds %d bytes; height %d x row_step %d is %d"
                         % (len(data), height, row_step, height * row_step))

    by_name = {}
    for field in msg.fields:
        by_name.setdefault(getattr(field, "name", None), field)
    offsets, datatypes = [], []
    for name in "xyz":
        field = by_name.get(name)
        if field is None:
            present = ", ".join(repr(getattr(f, "name", "?")) for f in msg.fields) or "none"
            raise ValueError("PointCloud2 has no field '%s' (fields: %s); shapeid needs x, y "
                             "and z" % (name, present))
        datatype, offset = int(field.datatype), int(field.offset)
        size = _FLOAT_SIZES.get(datatype)
        if size is None:
            raise ValueError(
                "PointCloud2 field '%s' has datatype %d (%s); shapeid reads FLOAT32 (7) or "
                "FLOAT64 (8) coordinates"
                % (name, datatype, _DATATYPE_NAMES.get(datatype, "unknown")))
        if getattr(field, "count", 1) not in (0, 1):
            raise ValueError("PointCloud2 field '%s' has count %d; a coordinate is one value"
                             % (name, field.count))
        if offset < 0 or offset + size > point_step:
            raise ValueError("PointCloud2 field '%s' at offset %d (%d bytes) does not fit in "
                             "point_step %d" % (name, offset, size, point_step))
        offsets.append(offset)
        datatypes.append(datatype)
    # Every field, not only x, y and z: a field past point_step is a point_step too small.
    for field in msg.fields:
        offset = int(field.offset)
        size = _DATATYPE_SIZES.get(int(field.datatype), 1) * max(int(getattr(field, "count", 1)), 1)
        if offset < 0 or offset + size > point_step:
            raise ValueError("PointCloud2 field '%s' at offset %d (%d bytes) does not fit in "
                             "point_step %d" % (getattr(field, "name", "?"), offset, size,
                                                point_step))
    padding = row_step - width * point_step
    if padding >= point_step:  # as the server: what rows of points point_step too short are
        raise ValueError("PointCloud2: row_step %d leaves %d bytes after width %d x point_step "
                         "%d, room for %d more points; rows pad by less than one point (is "
                         "point_step right?)" % (row_step, padding, width, point_step,
                                                 padding // point_step))
    padded = row_step > width * point_step
    layout = Layout(point_step=point_step, offsets=tuple(offsets), datatypes=tuple(datatypes),
                    big_endian=big_endian, width=width if padded else 0,
                    row_step=row_step if padded else 0)
    declared = _Declared(height, width, row_step, layout, data)
    _layout_survey.check(declared)
    return declared


def _point_cloud2_values(declared, packed):
    """(values, source): the float32 values of x, y, z as (height, width, 3) and, for float64
    coordinates, their values before rounding (or a function giving them) for _finite.
    packed=True: values is a new C-contiguous little-endian float32 array (the wire's
    default); else, for float32 x y z adjacent (nearly every driver), a strided view over
    the message's data, no copy: only what the finiteness check reads."""
    layout = declared.layout
    height, width, row_step = declared.height, declared.width, declared.row_step
    point_step, offsets = layout.point_step, layout.offsets
    order = ">" if layout.big_endian else "<"
    sizes = [_FLOAT_SIZES[d] for d in layout.datatypes]
    formats = [order + ("f4" if size == 4 else "f8") for size in sizes]
    raw = np.frombuffer(declared.data, np.uint8)
    size = sizes[0]
    if sizes == [size] * 3 and offsets[1] == offsets[0] + size and offsets[2] == offsets[1] + size:
        if packed and size == 4 and not layout.big_endian:
            # 12 bytes a point copied as one opaque item
            out = np.empty((height, width, 3), _F32LE)
            out.view("V12").reshape(height, width)[...] = np.ndarray(
                (height, width), "V12", raw, offsets[0], (row_step, point_step))
            return out, None
        xyz = np.ndarray((height, width, 3), formats[0], raw, offsets[0],
                         (row_step, point_step, size))
        if size == 4 and not packed:
            return xyz, None
        out = np.empty((height, width, 3), _F32LE)
        with np.errstate(over="ignore", invalid="ignore"):
            out[...] = xyz
        return out, ((lambda: xyz.reshape(-1, 3)) if size == 8 else None)
    struct = np.dtype({"names": list("xyz"), "formats": formats, "offsets": list(offsets),
                       "itemsize": point_step})
    points = np.ndarray((height, width), struct, raw, 0, (row_step, point_step))
    out = np.empty((height, width, 3), _F32LE)
    with np.errstate(over="ignore", invalid="ignore"):
        for axis, name in enumerate("xyz"):
            out[..., axis] = points[name]

    def source():
        return np.stack([points[name].reshape(-1).astype(np.float64) for name in "xyz"], axis=1)

    return out, (source if 8 in sizes else None)


def _check_narrowing(values, source, declared, width, what):
    """ValueError when a FLOAT64 coordinate is not 0 but below float32's smallest normal, as
    float32 data declared FLOAT64 reads (the server refuses it too; one beyond float32's
    range is _finite's). `values`: the float32 x y z; `source` as _point_cloud2_values."""
    if source is None:
        return
    candidates = (np.abs(values) < _FLOAT32_MIN).reshape(-1, 3)  # 0 included: checked below
    for axis, datatype in enumerate(declared.layout.datatypes):
        if datatype != FLOAT64:
            candidates[:, axis] = False  # (a broadcast & over 3 columns is 10 times slower)
    if not candidates.any():
        return
    source = source() if callable(source) else source
    lost = candidates & (source != 0)
    if lost.any():
        point, axis = np.argwhere(lost)[0]
        where = "point %d" % point
        if width:
            where += " (row %d, column %d)" % divmod(int(point), width)
        raise ValueError(
            "%s: %s: %s = %r (FLOAT64) is not 0 but below float32's smallest normal (%.6g): "
            "float32 data declared FLOAT64 reads like this; is the field's datatype right?"
            % (what, where, "xyz"[axis], float(source[point, axis]), _FLOAT32_MIN))


def _count(value, name):
    try:
        number = int(value)
    except (TypeError, ValueError):
        raise TypeError("PointCloud2 %s is %r; expected an integer" % (name, value)) from None
    if number < 0:
        raise ValueError("PointCloud2 %s is %d" % (name, number))
    return number


def _bytes_of(data):
    """A PointCloud2's data as something numpy reads without copying where it can: bytes
    (ROS 1), array.array('B') (ROS 2), bytearray, memoryview or a list of ints."""
    if isinstance(data, (bytes, bytearray)):
        return data
    if isinstance(data, (list, tuple)):
        values = np.asarray(data)
        if values.size and (values.dtype.kind not in "iu" or values.min() < 0 or values.max() > 255):
            raise ValueError("PointCloud2 data is a list that is not of bytes (0-255)")
        return values.astype(np.uint8).tobytes()
    try:
        view = memoryview(data)
    except TypeError:
        raise TypeError("PointCloud2 data is %s; expected bytes, bytearray, memoryview, "
                        "array.array('B') or a list of ints" % _type_name(data)) from None
    if not view.c_contiguous:
        raise ValueError("PointCloud2 data is a non-contiguous buffer")
    return view.cast("B") if view.format != "B" or view.ndim != 1 else view


# ---------------------------------------------------------------------------------------------

def _type_name(value):
    kind = type(value)
    return kind.__name__ if kind.__module__ == "builtins" else "%s.%s" % (kind.__module__, kind.__name__)


def _hint(value):
    if isinstance(value, (list, tuple)):
        return " (a list: convert it with numpy.asarray(points, dtype=numpy.float32))"
    if "torch" in sys.modules and type(value).__module__.startswith("torch"):
        return " (a tensor: pass tensor.cpu().numpy())"
    return ""
