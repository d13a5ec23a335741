#!/usr/bin/env python3
"""Cross-checks geodrive's .npy reader/writer against numpy itself (used by npy_test.cc).

  npy_numpy_crosscheck.py write DIR   numpy writes every case into DIR plus DIR/manifest.txt
  npy_numpy_crosscheck.py check DIR   loads the files geodrive wrote (listed in DIR/manifest.txt)
                                      with np.load, checks dtype, shape and every value; for v1
                                      little-endian C-order files also checks that np.save writes
                                      byte-identical files. Exits 1 on the first mismatch.

Each case's values are a fixed function of the C-order element index i (see expected()), which
npy_test.cc computes the same way. Manifest line: NAME DESCR ORDER VERSION SHAPE, e.g.
`f4_C_le_v1_3x4.npy <f4 C 1 3x4` (SHAPE "scalar" for 0-d arrays).
"""
import io
import os
import sys

import numpy as np

DTYPES = ["f4", "f8", "u1", "b1", "i4", "i8", "u2"]
SHAPES = [(), (0,), (0, 3), (7,), (3, 4), (2, 3, 4)]


def expected(code, n):
    i = np.arange(n, dtype=np.int64)
    if code in ("f2", "f4", "f8"):
        return (i * 0.25 - 7.0).astype(code)
    if code == "u1":
        return (i % 251).astype(np.uint8)
    if code == "b1":
        return i % 3 == 0
    if code == "i4":
        return (i * 1000 - 123456).astype(np.int32)
    if code == "i8":
        return (i * (1 << 33) - 5).astype(np.int64)
    if code == "u2":
        return ((i * 257) % 65536).astype(np.uint16)
    raise ValueError(code)


def shape_text(shape):
    return "scalar" if len(shape) == 0 else "x".join(str(d) for d in shape)


def parse_shape(text):
    return () if text == "scalar" else tuple(int(d) for d in text.split("x"))


def cases():
    for code in DTYPES:
        for shape in SHAPES:
            for order in ("C", "F"):
                if order == "F" and len(shape) < 2:
                    continue
                for endian in ("le", "be"):
                    if endian == "be" and code in ("u1", "b1"):
                        continue
                    for version in (1, 2, 3):
                        yield code, shape, order, endian, version


def write(directory):
    lines = []
    for code, shape, order, endian, version in cases():
        n = int(np.prod(shape)) if shape else 1
        a = expected(code, n).reshape(shape)
        if endian == "be":
            a = a.astype(a.dtype.newbyteorder(">"))
        if order == "F":
            a = np.asfortranarray(a)
        name = "%s_%s_%s_v%d_%s.npy" % (code, order, endian, version, shape_text(shape))
        with open(os.path.join(directory, name), "wb") as f:
            np.lib.format.write_array(f, a, version=(version, 0))
        lines.append("%s %s %s %d %s" % (name, a.dtype.str, order, version, shape_text(shape)))
    with open(os.path.join(directory, "manifest.txt"), "w") as f:
        f.write("\n".join(lines) + "\n")
    print("numpy %s wrote %d files" % (np.__version__, len(lines)))


def check(directory):
    count = 0
    with open(os.path.join(directory, "manifest.txt")) as f:
        entries = [line.split() for line in f if line.strip()]
    for name, descr, order, version, shape_str in entries:
        path = os.path.join(directory, name)
        shape = parse_shape(shape_str)
        with open(path, "rb") as f:
            raw = f.read()
        if raw[6] != int(version):
            sys.exit("%s: format version %d, expected %s" % (name, raw[6], version))
        header_len = int.from_bytes(raw[8:10] if raw[6] == 1 else raw[8:12], "little")
        prefix = 10 if raw[6] == 1 else 12
        if (prefix + header_len) % 64 != 0:
            sys.exit("%s: data offset %d is not a multiple of 64" % (name, prefix + header_len))
        a = np.load(path)
        if a.dtype.str != descr:
            sys.exit("%s: dtype %s, expected %s" % (name, a.dtype.str, descr))
        if a.shape != shape:
            sys.exit("%s: shape %s, expected %s" % (name, a.shape, shape))
        if order == "F" and not a.flags.f_contiguous:
            sys.exit("%s: expected a Fortran-ordered array" % name)
        n = int(np.prod(shape)) if shape else 1
        want = expected(descr[1:], n).reshape(shape)
        if not np.array_equal(a, want):
            sys.exit("%s: values differ from the expected pattern" % name)
        if version == "1" and order == "C" and descr[0] != ">":
            buffer = io.BytesIO()
            np.save(buffer, want)
            if buffer.getvalue() != raw:
                sys.exit("%s: not byte-identical to np.save's output" % name)
        count += 1
    print("numpy %s checked %d files" % (np.__version__, count))


if __name__ == "__main__":
    if len(sys.argv) != 3 or sys.argv[1] not in ("write", "check"):
        sys.exit(__doc__)
    (write if sys.argv[1] == "write" else check)(sys.argv[2])
