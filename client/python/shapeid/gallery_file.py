"""The portable gallery file of `shapeid gallery export` / `import` (client/gallery_file.h):
the 8 bytes "SHAPEIDG", then each GalleryExportChunk of an export, in order, each preceded
by its length as a varint (protobuf's delimited format). Files written here and by the CLI
are the same bytes. Only the framing is checked here; the server checks the content.
"""

import os
import tempfile

import grpc
from google.protobuf.message import DecodeError

from .errors import DataLossError

MAGIC = b"SHAPEIDG"
MAX_CHUNK_BYTES = 64 << 20  # as kMaxGalleryFileChunkBytes: a damaged length stops here


def _varint(value):
    out = bytearray()
    while True:
        bits = value & 0x7F
        value >>= 7
        if value:
            out.append(bits | 0x80)
        else:
            out.append(bits)
            return bytes(out)


class Writer:
    """Writes chunks to `target`: a path (through a temporary file beside it that `commit`
    fsyncs and renames over the path, so the path only ever holds a whole file; without
    commit, `close` removes it) or a binary file object (written directly)."""

    def __init__(self, target):
        self._path = None
        if isinstance(target, (str, bytes, os.PathLike)):
            self._path = os.fspath(target)
            directory = os.path.dirname(os.path.abspath(self._path))
            fd, self._temp = tempfile.mkstemp(prefix=".%s." % os.path.basename(self._path),
                                              dir=directory)
            self._file = os.fdopen(fd, "wb")
        else:
            self._file, self._temp = target, None
        self._file.write(MAGIC)

    def write(self, chunk_bytes):
        if len(chunk_bytes) > MAX_CHUNK_BYTES:
            raise ValueError("gallery export chunk of %d bytes is over the file's limit of %d"
                             % (len(chunk_bytes), MAX_CHUNK_BYTES))
        self._file.write(_varint(len(chunk_bytes)))
        self._file.write(chunk_bytes)

    def commit(self):
        self._file.flush()
        if self._temp is None:
            return
        os.fsync(self._file.fileno())
        self._file.close()
        os.replace(self._temp, self._path)
        self._temp = None
        fd = os.open(os.path.dirname(os.path.abspath(self._path)), os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)

    def close(self):
        """Removes the temporary file of an uncommitted path; leaves a file object open."""
        if self._temp is not None:
            self._file.close()
            os.unlink(self._temp)
            self._temp = None


def read_chunks(source, chunk_type):
    """The chunks of the gallery file `source` (a path or a binary file object), in order,
    each parsed as a `chunk_type` (GalleryExportChunk). ValueError if it does not start with
    the magic (raised by the first next()); DataLossError when it ends inside a chunk, a
    length is impossible or a chunk does not parse."""
    name = os.fspath(source) if isinstance(source, (str, bytes, os.PathLike)) else getattr(
        source, "name", "the gallery file")
    own = isinstance(source, (str, bytes, os.PathLike))
    stream = open(source, "rb") if own else source
    try:
        if stream.read(len(MAGIC)) != MAGIC:
            raise ValueError("%s is not a shapeid gallery export (bad magic)" % name)
        index = 0
        while True:
            length = _read_varint(stream, name, index)
            if length is None:
                return
            if length > MAX_CHUNK_BYTES:
                raise _data_loss("%s: chunk %d claims %d bytes, over the limit of %d (a damaged "
                                 "file?)" % (name, index, length, MAX_CHUNK_BYTES))
            data = stream.read(length)
            if len(data) != length:
                raise _data_loss("%s: ends inside chunk %d (%d of %d bytes; a truncated copy?)"
                                 % (name, index, len(data), length))
            chunk = chunk_type()
            try:
                chunk.ParseFromString(data)
            except DecodeError:
                raise _data_loss("%s: chunk %d does not parse (a damaged file?)"
                                 % (name, index)) from None
            yield chunk
            index += 1
    finally:
        if own:
            stream.close()


def _read_varint(stream, name, index):
    """The next length, or None at a clean end of file."""
    value, shift = 0, 0
    while True:
        byte = stream.read(1)
        if not byte:
            if shift == 0:
                return None
            raise _data_loss("%s: ends inside the length of chunk %d" % (name, index))
        value |= (byte[0] & 0x7F) << shift
        if not byte[0] & 0x80:
            return value
        shift += 7
        if shift > 63:
            raise _data_loss("%s: the length of chunk %d is not a varint" % (name, index))


def _data_loss(message):
    return DataLossError(grpc.StatusCode.DATA_LOSS, message)
