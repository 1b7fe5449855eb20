"""What a PointCloud2's bytes betray about its declared layout: the server's LayoutSurvey
(server/wire/point_layout.cc), the same rule and message, so that a mis-declared message is
refused here before anything is sent, whether it is forwarded or converted.

The coordinates of about the first 1,024 points are read as declared and read with the byte
order, or (little-endian) FLOAT32 and FLOAT64, exchanged. Of those finite in both readings, over a quarter
implausible as declared (not 0 and of a magnitude outside [2^-40, 2^40]) and under a tenth
exchanged is a mis-declared layout: a sensor's coordinates are 0 or within that range, and
bytes read in the wrong order or width fall outside it about two times in three.
"""

import numpy as np

_PLAUSIBLE_MIN = 2.0 ** -40
_PLAUSIBLE_MAX = 2.0 ** 40
_VALUES = 3 * 1024       # per exchanged reading, as the server's kSurveyValues
_MAX_POINTS = 1 << 16    # as the server's kSurveyMaxPoints
_BLOCK = 1024            # points read at a time
_SIZES = {7: 4, 8: 8}    # FLOAT32, FLOAT64
_OTHER = {7: 8, 8: 7}


def check(declared):
    """Raises ValueError when the bytes of `declared` (clouds._Declared, whose layout holds
    together, with at least one point) fit an exchanged reading and not the declared one."""
    layout = declared.layout
    step = layout.point_step
    # Big-endian, a float64's first half read as a float32 is always plausible: the exchanged
    # width is surveyed in little-endian only, as by the server.
    other_width = not layout.big_endian and all(
        offset + _SIZES[_OTHER[d]] <= step for offset, d in zip(layout.offsets, layout.datatypes))
    readings = ["swapped"] + (["width"] if other_width else [])
    tallies = {r: [0, 0, 0] for r in readings}  # values, implausible as declared, exchanged
    height, width = declared.height, declared.width
    records = np.ndarray((height, width, step), np.uint8, np.frombuffer(declared.data, np.uint8),
                         0, (declared.row_step, step, 1))
    total = min(height * width, _MAX_POINTS)
    for start in range(0, total, _BLOCK):
        rows, columns = np.divmod(np.arange(start, min(start + _BLOCK, total)), width)
        block = records[rows, columns]  # (points, point_step), a copy of these points only
        declared_values = _read(block, layout.offsets, layout.datatypes, layout.big_endian)
        exchanged = {"swapped": _read(block, layout.offsets, layout.datatypes,
                                      not layout.big_endian)}
        if other_width:
            exchanged["width"] = _read(block, layout.offsets,
                                       [_OTHER[d] for d in layout.datatypes], layout.big_endian)
        for reading, values in exchanged.items():
            both = np.isfinite(declared_values) & np.isfinite(values)
            tally = tallies[reading]
            tally[0] += int(np.count_nonzero(both))
            tally[1] += int(np.count_nonzero(both & _implausible(declared_values)))
            tally[2] += int(np.count_nonzero(both & _implausible(values)))
        if all(t[0] >= _VALUES for t in tallies.values()):
            break
    for reading in readings:
        values, declared_implausible, implausible = tallies[reading]
        if values == 0 or 4 * declared_implausible <= values or 10 * implausible >= values:
            continue
        counts = ("%d of %d coordinates are implausible (not 0 and outside [2^-40, 2^40]) as "
                  "declared" % (declared_implausible, values))
        if reading == "swapped":
            raise ValueError(
                "PointCloud2: the points look byte-swapped: %s (is_bigendian %s), %d read "
                "%s-endian; is is_bigendian right?"
                % (counts, layout.big_endian, implausible,
                   "little" if layout.big_endian else "big"))
        what = {(8,): "FLOAT32 data declared FLOAT64",
                (7,): "FLOAT64 data declared FLOAT32"}.get(tuple(set(layout.datatypes)),
                                                          "data of the other float widths")
        raise ValueError(
            "PointCloud2: the points look like %s: %s, %d read with FLOAT32 and FLOAT64 "
            "exchanged at the same offsets; are the datatypes of fields x, y and z right?"
            % (what, counts, implausible))


def _read(block, offsets, datatypes, big_endian):
    """The (points, 3) values of x, y, z in `block` (points, point_step uint8) as float64."""
    order = ">" if big_endian else "<"
    out = np.empty((len(block), 3))
    with np.errstate(invalid="ignore"):  # NaN of the other byte order
        for axis, (offset, datatype) in enumerate(zip(offsets, datatypes)):
            size = _SIZES[datatype]
            out[:, axis] = np.ascontiguousarray(block[:, offset:offset + size]).view(
                "%sf%d" % (order, size))[:, 0]
    return out


def _implausible(values):
    with np.errstate(invalid="ignore"):
        magnitude = np.abs(values)
        return (values != 0) & ((magnitude < _PLAUSIBLE_MIN) | (magnitude > _PLAUSIBLE_MAX))
