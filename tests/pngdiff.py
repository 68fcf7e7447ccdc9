# pngdiff.py A B [A2 B2 ...]: the largest per-channel difference of two
# 8-bit RGB/RGBA PNG files (no third-party modules) and the share of
# differing pixels, one line per pair (one start for many frames).  Other
# tests' scripts import its PNG reader: from pngdiff import load.
import struct, sys, zlib

def load(path):
    data = open(path, "rb").read()
    assert data[:8] == b"\x89PNG\r\n\x1a\n", path + ": not a PNG"
    pos, idat, w = 8, b"", None
    while pos < len(data):
        n, kind = struct.unpack(">I4s", data[pos:pos + 8])
        body = data[pos + 8:pos + 8 + n]
        if kind == b"IHDR":
            w, h, depth, ctype = struct.unpack(">IIBB", body[:10])
            assert depth == 8 and ctype in (2, 6), path + ": not 8-bit RGB(A)"
            bpp = 3 if ctype == 2 else 4
        elif kind == b"IDAT":
            idat += body
        pos += 12 + n
    raw, stride = zlib.decompress(idat), w * bpp
    out, prev = [], bytearray(stride)
    for y in range(h):
        f, line = raw[y * (stride + 1)], bytearray(raw[y * (stride + 1) + 1:(y + 1) * (stride + 1)])
        for i in range(stride):
            a = line[i - bpp] if i >= bpp else 0
            b, c = prev[i], prev[i - bpp] if i >= bpp else 0
            if f == 1: line[i] = (line[i] + a) & 255
            elif f == 2: line[i] = (line[i] + b) & 255
            elif f == 3: line[i] = (line[i] + (a + b) // 2) & 255
            elif f == 4:
                p = a + b - c
                pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                line[i] = (line[i] + (a if pa <= pb and pa <= pc else b if pb <= pc else c)) & 255
        out.append(bytes(line))
        prev = line
    return w, h, bpp, out

def compare(a, b):
    wa, ha, ba, A = load(a)
    wb, hb, bb, B = load(b)
    assert (wa, ha, ba) == (wb, hb, bb), "sizes differ"
    mx, diff = 0, 0
    for ra, rb in zip(A, B):
        for p in range(wa):
            d = max(abs(ra[p * ba + k] - rb[p * ba + k]) for k in range(3))
            mx = max(mx, d)
            diff += d > 0
    print("max=%d differing=%.5f" % (mx, diff / (wa * ha)))

if __name__ == "__main__":
    args = sys.argv[1:]
    assert len(args) >= 2 and len(args) % 2 == 0, "usage: pngdiff.py A B [A2 B2 ...]"
    for i in range(0, len(args), 2):
        compare(args[i], args[i + 1])
