"""The files learn/ reads and writes, byte for byte as the C++ side does.

  views file    written by shapeid_export_views (learn/export_views.cc): labels and canonical
                points of every training view.
  model file    read by PointNetwork::Parse (core/descriptors/point_network.cc): "SHPDPNET",
                version, name, card, frame, max_points, layer widths, then each layer's
                weight (out x in, row-major) and bias, all float32; closed by zlib's CRC-32.
  golden file   read by core/descriptors/learned_test.cc: canonical point sets and the
                embeddings torch gives them.
All little-endian, as core/binary_codec.h encodes.
"""

import struct
import zlib

import numpy as np

MODEL_MAGIC = b"SHPDPNET"
MODEL_VERSION = 1
GOLDEN_MAGIC = b"SHPDGOLD"
FRAMES = {"box": 0, "upright": 1}


def _string(value: bytes) -> bytes:
    return struct.pack("<I", len(value)) + value


def _finish(body: bytes) -> bytes:
    return body + struct.pack("<I", zlib.crc32(body) & 0xFFFFFFFF)


def _open(data: bytes, magic: bytes) -> memoryview:
    if data[: len(magic)] != magic:
        raise ValueError("no magic %r" % magic)
    (stored,) = struct.unpack("<I", data[-4:])
    if stored != zlib.crc32(data[:-4]) & 0xFFFFFFFF:
        raise ValueError("checksum mismatch")
    return memoryview(data)[len(magic) : -4]


def read_views(path):
    """(labels, label[R], object[R], view[R], ambiguous[R], points: list of m x 3 arrays)."""
    with open(path, "rb") as f:
        data = f.read()
    body = _open(data, b"SHPDVIEW")
    at = 0

    def u32():
        nonlocal at
        (v,) = struct.unpack_from("<I", body, at)
        at += 4
        return v

    labels = []
    for _ in range(u32()):
        n = u32()
        labels.append(bytes(body[at : at + n]).decode())
        at += n
    records = u32()
    meta = np.zeros((records, 4), dtype=np.int64)
    points = []
    for r in range(records):
        meta[r] = struct.unpack_from("<4I", body, at)
        at += 16
        m = u32()
        points.append(np.frombuffer(body, dtype="<f4", count=3 * m, offset=at).reshape(m, 3))
        at += 12 * m
    return labels, meta[:, 0], meta[:, 1], meta[:, 2], meta[:, 3], points


def write_model(path, name, card, frame, max_points, layers):
    """layers: [(weight out x in, bias out)] as float32 numpy arrays, 3 inputs first."""
    body = MODEL_MAGIC + struct.pack("<I", MODEL_VERSION)
    body += _string(name.encode()) + _string(card.encode())
    body += struct.pack("<III", FRAMES[frame], max_points, len(layers))
    for weight, _ in layers:
        body += struct.pack("<I", weight.shape[0])
    for weight, bias in layers:
        body += np.ascontiguousarray(weight, dtype="<f4").tobytes()
        body += np.ascontiguousarray(bias, dtype="<f4").tobytes()
    with open(path, "wb") as f:
        f.write(_finish(body))


def read_model_card(path):
    """(name, card) of a model file, after checking its magic, version and checksum."""
    with open(path, "rb") as f:
        body = _open(f.read(), MODEL_MAGIC)
    (version,) = struct.unpack_from("<I", body, 0)
    if version != MODEL_VERSION:
        raise ValueError("model format version %d, this reads %d" % (version, MODEL_VERSION))
    at, fields = 4, []
    for _ in range(2):
        (n,) = struct.unpack_from("<I", body, at)
        fields.append(bytes(body[at + 4 : at + 4 + n]).decode())
        at += 4 + n
    return fields[0], fields[1]


def write_golden(path, point_sets, embeddings):
    """point_sets: m x 3 arrays as the network sees them; embeddings: one vector each."""
    body = GOLDEN_MAGIC + struct.pack("<I", len(point_sets))
    for points, embedding in zip(point_sets, embeddings):
        body += struct.pack("<I", points.shape[0])
        body += np.ascontiguousarray(points, dtype="<f4").tobytes()
        body += struct.pack("<I", embedding.shape[0])
        body += np.ascontiguousarray(embedding, dtype="<f4").tobytes()
    with open(path, "wb") as f:
        f.write(_finish(body))


if __name__ == "__main__":
    import sys

    for model in sys.argv[1:]:
        print(read_model_card(model)[1])
