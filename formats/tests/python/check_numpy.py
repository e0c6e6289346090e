"""Independent check that a PRT bake file is a standard safetensors file readable from numpy,
and that its checksums follow docs/format.md.

Run by the ignored Rust test `python_numpy_reads_bake_files` (formats/tests/python_compat.rs):
    python3 -m venv /tmp/prt-pyenv && /tmp/prt-pyenv/bin/pip install safetensors numpy
    PRT_PYTHON=/tmp/prt-pyenv/bin/python cargo test -p prt-formats --test suite python_compat -- --ignored
Usage: check_numpy.py BAKE_FILE
"""

import json
import struct
import sys
import zlib

import numpy as np
from safetensors import safe_open
from safetensors.numpy import load_file

path = sys.argv[1]

# 1. The three-line example from docs/format.md.
tensors = load_file(path)
with safe_open(path, framework="numpy") as f:
    meta = f.metadata()
schema = json.loads(meta["metadata"])

# 2. Values written by the Rust side (see python_compat.rs).
expected = {
    "t0": (np.arange(24, dtype=np.float32) * 0.25 - 3.0).reshape(2, 3, 4),
    "half": np.arange(5, dtype=np.float16) * np.float16(1.5),
    "ids": np.array([0, 1, 2**32 - 1], dtype=np.uint32),
    "small": np.arange(7, dtype=np.uint16) * 1000,
    "mask": np.arange(13, dtype=np.uint8),
    "signed": np.array([[-(2**31), -1], [0, 2**31 - 1]], dtype=np.int32),
}
for name, want in expected.items():
    got = tensors[name]
    assert got.dtype == want.dtype, (name, got.dtype, want.dtype)
    assert got.shape == want.shape, (name, got.shape, want.shape)
    assert np.array_equal(got, want), name
pads = sorted(k for k in tensors if k.startswith("__pad"))
assert set(tensors) == set(expected) | set(pads), sorted(tensors)
assert all(not tensors[p].any() for p in pads), "padding must be zero"
assert meta["format"] == "prt-bake" and meta["schema_version"] == "1", meta
assert schema == {"materials": [{"name": "bunny", "family": "ggx"}]}, schema

# 3. Layout, alignment and checksums, straight from the bytes (docs/format.md).
raw = open(path, "rb").read()
(n,) = struct.unpack("<Q", raw[:8])
header = json.loads(raw[8 : 8 + n])
data = raw[8 + n :]
assert (8 + n) % 16 == 0, "data section must start 16-byte aligned"
crcs = json.loads(meta["crc32"])
for name, info in header.items():
    if name == "__metadata__":
        continue
    b, e = info["data_offsets"]
    if not name.startswith("__pad"):  # padding fills the gaps, so it is not aligned itself
        assert b % 16 == 0, (name, b)
        assert crcs[name] == "%08x" % zlib.crc32(data[b:e]), name


def put_str(s):
    s = s.encode()
    return struct.pack("<Q", len(s)) + s


digest = b"prt-bake header digest v1\0"
m = {k: v for k, v in header["__metadata__"].items() if k != "header_crc32"}
digest += struct.pack("<Q", len(m))
for k in sorted(m):  # UTF-8 byte order; keys here are ASCII
    digest += put_str(k) + put_str(m[k])
names = sorted((k for k in header if k != "__metadata__"), key=lambda s: s.encode())
digest += struct.pack("<Q", len(names))
for k in names:
    t = header[k]
    digest += put_str(k) + put_str(t["dtype"]) + struct.pack("<Q", len(t["shape"]))
    digest += b"".join(struct.pack("<Q", d) for d in t["shape"])
    digest += struct.pack("<QQ", *t["data_offsets"])
assert meta["header_crc32"] == "%08x" % zlib.crc32(digest), "header digest"

print(
    "OK: %d tensors (%d padding), dtypes %s, header %d bytes, crc32 and header_crc32 match"
    % (len(tensors), len(pads), sorted({str(tensors[k].dtype) for k in expected}), n)
)
