"""Minimal OpenEXR I/O for the reference images (numpy only).

write_exr() writes a single-part scanline EXR, NO_COMPRESSION, FLOAT (32-bit;
HALF with half=True)
channels (R, G, B unless named otherwise; EXR stores them sorted by name), one
scanline per block.
read_exr() reads back such files (uncompressed, FLOAT or HALF channels).
"""
import struct

import numpy as np


def _attr(name, typ, data):
    return name.encode() + b"\0" + typ.encode() + b"\0" + struct.pack("<i", len(data)) + data


def write_exr(path, img, names=("R", "G", "B"), half=False):
    """img: HxWxC; names: the C channel names (e.g. R, G, B, S1.R, ...);
    half: 16-bit channels (for standard errors, which need no more)."""
    ptype, nbytes, fmt = (1, 2, "<f2") if half else (2, 4, "<f4")
    img = np.asarray(img, dtype=np.float32)
    if img.ndim != 3 or img.shape[2] != len(names):
        raise ValueError("expected an HxWx%d array" % len(names))
    h, w, _ = img.shape
    chans = sorted((n, i) for i, n in enumerate(names))
    chlist = b"".join(n.encode() + b"\0" + struct.pack("<iB3xii", ptype, 0, 1, 1)
                      for n, _ in chans) + b"\0"
    box = struct.pack("<iiii", 0, 0, w - 1, h - 1)
    header = b"".join([
        struct.pack("<ii", 20000630, 2),
        _attr("channels", "chlist", chlist),
        _attr("compression", "compression", b"\0"),
        _attr("dataWindow", "box2i", box),
        _attr("displayWindow", "box2i", box),
        _attr("lineOrder", "lineOrder", b"\0"),
        _attr("pixelAspectRatio", "float", struct.pack("<f", 1.0)),
        _attr("screenWindowCenter", "v2f", struct.pack("<ff", 0.0, 0.0)),
        _attr("screenWindowWidth", "float", struct.pack("<f", 1.0)),
        b"\0",
    ])
    line_bytes = w * len(chans) * nbytes
    first = len(header) + 8 * h
    offsets = [first + y * (8 + line_bytes) for y in range(h)]
    with open(path, "wb") as f:
        f.write(header)
        f.write(struct.pack("<%dQ" % h, *offsets))
        for y in range(h):
            f.write(struct.pack("<ii", y, line_bytes))
            for _, c in chans:
                f.write(np.ascontiguousarray(img[y, :, c]).astype(fmt).tobytes())


def read_exr(path, names=("R", "G", "B")):
    data = open(path, "rb").read()
    magic, version = struct.unpack_from("<ii", data, 0)
    if magic != 20000630:
        raise ValueError("not an EXR file")
    pos, attrs = 8, {}
    while data[pos] != 0:
        end = data.index(b"\0", pos)
        name = data[pos:end].decode()
        end2 = data.index(b"\0", end + 1)
        typ = data[end + 1:end2].decode()
        (size,) = struct.unpack_from("<i", data, end2 + 1)
        attrs[name] = (typ, data[end2 + 5:end2 + 5 + size])
        pos = end2 + 5 + size
    pos += 1
    if attrs["compression"][1] != b"\0":
        raise ValueError("only uncompressed EXR is supported")
    chans, raw, p = [], attrs["channels"][1], 0
    while raw[p] != 0:
        e = raw.index(b"\0", p)
        (ptype,) = struct.unpack_from("<i", raw, e + 1)
        chans.append((raw[p:e].decode(), ptype))
        p = e + 17
    x0, y0, x1, y1 = struct.unpack("<iiii", attrs["dataWindow"][1])
    w, h = x1 - x0 + 1, y1 - y0 + 1
    offsets = struct.unpack_from("<%dQ" % h, data, pos)
    out = {n: np.zeros((h, w), np.float32) for n, _ in chans}
    for off in offsets:
        y, _ = struct.unpack_from("<ii", data, off)
        q = off + 8
        for n, ptype in chans:
            dt, sz = ("<f4", 4) if ptype == 2 else ("<f2", 2)
            out[n][y - y0] = np.frombuffer(data, dt, w, q).astype(np.float32)
            q += w * sz
    return np.stack([out[n] for n in names], axis=-1)
