"""A small OpenEXR reader for the tests: single-part scanline files, uncompressed or ZIP
(1 or 16 lines per block), HALF or FLOAT channels; enough for what `relight` and `reference`
write (and most environment maps).

Its own code, independent of the Rust side's reader (the `exr` crate), so that comparing
`render()` with the command-line tool's file does not use the project's code to read what the
project's code wrote. Follows the OpenEXR file layout document (openexr.com, "OpenEXR File
Layout"): header attributes, the line offset table, then chunks of (y, size, data) whose ZIP
data is zlib with a delta predictor over byte halves.
"""

import struct
import zlib

import numpy as np

_MAGIC = 20000630
_LINES_PER_BLOCK = {0: 1, 2: 1, 3: 16}  # NONE, ZIPS, ZIP
_DTYPES = {1: np.dtype("<f2"), 2: np.dtype("<f4")}  # HALF, FLOAT


def _cstring(data, pos):
    end = data.index(b"\0", pos)
    return data[pos:end].decode(), end + 1


def _header(data):
    magic, version = struct.unpack_from("<ii", data, 0)
    if magic != _MAGIC:
        raise ValueError("not an OpenEXR file")
    if version & 0x1200:  # tiled (0x200) or multi-part (0x1000)
        raise ValueError("tiled and multi-part files are not supported")
    pos, attrs = 8, {}
    while data[pos] != 0:
        name, pos = _cstring(data, pos)
        kind, pos = _cstring(data, pos)
        (size,) = struct.unpack_from("<i", data, pos)
        pos += 4
        attrs[name] = (kind, data[pos : pos + size])
        pos += size
    return attrs, pos + 1


def _channels(raw):
    out, pos = [], 0
    while raw[pos] != 0:
        name, pos = _cstring(raw, pos)
        pixel_type, _linear, xs, ys = struct.unpack_from("<iB3xii", raw, pos)
        pos += 16
        if pixel_type not in _DTYPES or (xs, ys) != (1, 1):
            raise ValueError(f"channel {name}: unsupported type or subsampling")
        out.append((name, _DTYPES[pixel_type]))
    return out


def _unzip(raw, size):
    """Undoes ZIP compression: zlib, the delta predictor, and the split into byte halves."""
    t = np.frombuffer(zlib.decompress(raw), dtype=np.uint8).astype(np.int32)
    if t.size != size:
        raise ValueError("ZIP block of the wrong size")
    t = (np.cumsum(t - 128) + 128) % 256  # t[i] = t[i-1] + d[i] - 128, with t[0] = d[0]
    t = t.astype(np.uint8)
    half = (size + 1) // 2
    out = np.empty(size, dtype=np.uint8)
    out[0::2] = t[:half]
    out[1::2] = t[half:]
    return out.tobytes()


def read_exr(path):
    """Returns the R, G, B channels of `path` as a float32 array (height, width, 3)."""
    with open(path, "rb") as f:
        data = f.read()
    attrs, pos = _header(data)
    channels = _channels(attrs["channels"][1])
    (compression,) = struct.unpack("<B", attrs["compression"][1])
    if compression not in _LINES_PER_BLOCK:
        raise ValueError(f"compression {compression} is not supported")
    x0, y0, x1, y1 = struct.unpack("<iiii", attrs["dataWindow"][1])
    width, height = x1 - x0 + 1, y1 - y0 + 1
    lines = _LINES_PER_BLOCK[compression]
    blocks = (height + lines - 1) // lines
    offsets = struct.unpack_from(f"<{blocks}Q", data, pos)
    planes = {name: np.empty((height, width), dtype=np.float32) for name, _ in channels}
    for offset in offsets:
        y, size = struct.unpack_from("<ii", data, offset)
        raw = data[offset + 8 : offset + 8 + size]
        rows = min(lines, y1 + 1 - y)
        expected = rows * width * sum(dt.itemsize for _, dt in channels)
        # A block that does not shrink is stored as it is.
        block = raw if compression == 0 or size == expected else _unzip(raw, expected)
        at = 0
        for row in range(rows):
            for name, dt in channels:
                n = width * dt.itemsize
                values = np.frombuffer(block, dtype=dt, count=width, offset=at)
                planes[name][y - y0 + row] = values.astype(np.float32)
                at += n
    return np.stack([planes["R"], planes["G"], planes["B"]], axis=-1)
