#!/usr/bin/env python3
"""shard_decode: an independent reader of tvpal datasets for the tests,
written from common/format/FORMAT.md alone (numpy, no tvpal code): it walks
every record of a shard by the chunk headers, stores each chunk's decoder
table as the chunk says it is stored (6.7: float32, or 16-bit decoded as
float32(tmin + float32(q * tscale)); table_format 4 and 5 by the chunk's
flags bit 1), inflates a coded chunk (6.11: flags bit 2, a zstd frame,
decompressed by the zstd command-line tool, then the transforms its
flags name undone) and rebuilds the volume of every step.

    shard_decode.py DATASET AXIS     prints, per step, the SHA-256 of the
                                     decoded float32 volume (x fastest), as
                                     tvpal-decode's output would hash

As a module: chunks(dataset, axis) and volumes(dataset, axis).  Checks only
what it needs to walk the records (no CRCs): the readers under test do the
checking.
"""
import hashlib
import struct
import subprocess
import sys

import numpy as np


def manifest(ds):
    m = {}
    for line in open(ds + "/manifest.txt"):
        if "=" in line and not line.lstrip().startswith("#"):
            k, v = line.split("=", 1)
            m[k.strip()] = v.strip()
    nx, ny, nz = (int(v) for v in m["dims"].lower().split("x"))
    return (nx, ny, nz), int(m["steps"]), int(m["window"]), int(m["nodes"])


def entry_bytes(tf, flags):
    """E of a chunk (FORMAT.md 6.5)."""
    if tf in (1, 3) or (tf in (4, 5) and flags & 2):
        return 2
    return 4


def inflate(frame, n, e, w, h, flags):
    """A coded chunk's table bytes (n entries of e bytes, little-endian) and
    indices (w x h bytes) from its zstd frame (FORMAT.md 6.11), undoing
    the transforms its flags name (bit 3: T2, bit 4: G)."""
    wh = w * h
    raw = subprocess.run(["zstd", "-d", "-c", "-q"], input=frame,
                         stdout=subprocess.PIPE, check=True).stdout
    assert len(raw) == n * e + wh, (len(raw), n * e + wh)
    planes = np.frombuffer(raw[:n * e], np.uint8).reshape(e, n).astype(np.uint64)
    d = sum(planes[b] << np.uint64(8 * b) for b in range(e))
    mod = np.uint64(1 << (8 * e))
    rows = n // 256
    if flags & 8:   # T2: zigzagged, index-major
        z = d.reshape(256, rows).T.copy()
        d = np.where(z & np.uint64(1), mod - np.uint64(1) - (z >> np.uint64(1)),
                     z >> np.uint64(1))
    d = d.reshape(rows, 256)
    d[0] = np.cumsum(d[0]) % mod               # row 0: along the index
    ent = np.cumsum(d, axis=0) % mod           # rows: along time
    table = ent.astype("<u4" if e == 4 else "<u2").tobytes()
    x = np.frombuffer(raw[n * e:], np.uint8).astype(np.uint64)
    if flags & 16:  # G: row 0 from the left, later rows gradients
        x = x.reshape(h, w)
        x[0] = np.cumsum(x[0]) % 256           # row 0: along the row
        u = np.cumsum(x[1:], axis=1) % 256     # later rows: u = x - x above
        x[1:] = np.cumsum(np.vstack([x[:1], u]), axis=0)[1:] % 256
        idx = x.astype(np.uint8).tobytes()
    else:
        idx = (np.cumsum(x) % 256).astype(np.uint8).tobytes()
    return table, idx


def chunks(ds, axis):
    """Every chunk of the axis, in file order: dicts with slice, wstart,
    wlen, flags, table_format (the shard's), u16 (bool), table (wlen x 256
    float32), idx (h x w uint8) and qmax (a 16-bit table's largest q, else
    0); a chunk of k slices of a palette group (FORMAT.md 5.1) as k dicts,
    one per slice, with slices = k and part = 0 .. k - 1."""
    dims, steps, window, nodes = manifest(ds)
    out = []
    for r in range(nodes):
        b = open("%s/node-%d/axis-%s.tvps" % (ds, r, "xyz"[axis]), "rb").read()
        tf, = struct.unpack_from("<I", b, 64)
        w, h = struct.unpack_from("<II", b, 56)
        index, = struct.unpack_from("<Q", b, 72)
        for t in range(steps):
            off, _ = struct.unpack_from("<QQ", b, index + 32 * t)
            count, = struct.unpack_from("<I", b, off + 8)
            pos = off + 64
            for _ in range(count):
                s, ws, wl, cw, ch, used, flags = struct.unpack_from("<7I", b, pos + 4)
                tmin, tscale = struct.unpack_from("<ff", b, pos + 48)
                e = entry_bytes(tf, flags)
                n = wl * 256
                raw = b[pos + 64:pos + 64 + n * e]
                ia = pos + 64 + n * e
                # A chunk of k slices of a palette group (FORMAT.md 6.5):
                # ch = k h rows of indices under one table.
                ib = b[ia:ia + w * ch]
                if flags & 4:
                    coded, = struct.unpack_from("<I", b, pos + 56)
                    raw, ib = inflate(b[pos + 64:pos + 64 + coded], n, e, w, ch,
                                      flags)
                qmax = 0
                if e == 4:
                    table = np.frombuffer(raw, "<f4").astype(np.float32)
                else:
                    q = np.frombuffer(raw, "<u2")
                    qmax = int(q.max())
                    # Two roundings in binary32, never a fused multiply-add.
                    p = q.astype(np.float32) * np.float32(tscale)
                    table = (np.float32(tmin) + p).astype(np.float32)
                    if tf in (3, 5) and flags & 1:
                        table[q == 65535] = np.float32(np.nan)
                idx = np.frombuffer(ib, np.uint8).reshape(ch, w)
                # flags: the plain chunk's (bits 2-4, coding, cleared);
                # coded: whether it was stored coded; slices: the k
                # slices of the chunk (one entry each, sharing the table;
                # part: which of them).
                for j in range(ch // h):
                    out.append(dict(slice=s + j, wstart=ws, wlen=wl,
                                    flags=flags & ~28, coded=bool(flags & 4),
                                    table_format=tf, u16=(e == 2),
                                    table=table.reshape(wl, 256),
                                    idx=idx[j * h:(j + 1) * h], qmax=qmax,
                                    slices=ch // h, part=j))
                if flags & 4:
                    pos += 64 + (coded + 63) // 64 * 64
                else:
                    pos += 64 + n * e + (w * ch + 63) // 64 * 64
    return out


def volumes(ds, axis):
    """The decoded volume of every step (nz x ny x nx float32), in order."""
    (nx, ny, nz), steps, window, nodes = manifest(ds)
    by_start = {}
    for c in chunks(ds, axis):
        by_start.setdefault(c["wstart"], []).append(c)
    current = {}
    for t in range(steps):
        # Record t's chunks begin the windows of their slices at t; every
        # other slice keeps the window it has (FORMAT.md 7.2).
        for c in by_start.get(t, []):
            current[c["slice"]] = c
        vol = np.zeros((nz, ny, nx), np.float32)
        for s, c in current.items():
            assert c["wstart"] <= t < c["wstart"] + c["wlen"], (s, t)
            v = c["table"][t - c["wstart"]][c["idx"]]
            if axis == 0:
                vol[:, :, s] = v        # in-slice (y, z)
            elif axis == 1:
                vol[:, s, :] = v        # (x, z)
            else:
                vol[s] = v              # (x, y)
        yield vol


if __name__ == "__main__":
    ds, axis = sys.argv[1], "xyz".index(sys.argv[2])
    for t, vol in enumerate(volumes(ds, axis)):
        print("%s  %d" % (hashlib.sha256(vol.astype("<f4").tobytes()).hexdigest(), t))
