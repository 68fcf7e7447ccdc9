#!/bin/sh
# generate.sh: writes the tvpal file corpus (tests/files/, see README.md):
# the good-* datasets with today's tvpal-gen and tvpal-encode, the bad-*
# shards and manifests by editing copies of good-1-basic in python3, and
# SHA256SUMS of what today's tvpal-decode makes of every good step and axis.
# Deterministic: a second run gives the same bytes.  The corpus is committed;
# run this only to add a case, then review the diff (a changed good-* file
# means the encoder's output changed, which the corpus does not require).
#
# Usage: tests/files/generate.sh [BUILDDIR [OUTDIR]]
#   BUILDDIR  the built tree (default: the source tree holding this script)
#   OUTDIR    where to write (default: this script's folder); write to a
#             scratch folder and `diff -r` it with tests/files to check
set -eu
here=$(cd "$(dirname "$0")" && pwd)
B=${1:-$(cd "$here/../.." && pwd)}
O=${2:-$here}
GEN=$B/samples/tvpal-gen
ENC=$B/encoder/tvpal-encode
DEC=$B/encoder/tvpal-decode
PY=${PYTHON:-python3}
for p in "$GEN" "$ENC" "$DEC"; do
    [ -x "$p" ] || { echo "generate.sh: $p not built" >&2; exit 1; }
done
mkdir -p "$O"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
# good-6-coded holds the first transform of coded chunks (FORMAT.md 1.8),
# which the encoder no longer writes (1.10 writes T2 and G): the committed
# copy is kept, not regenerated, so readers stay tested on it.
cp -r "$here/good-6-coded" "$tmp/frozen-good-6-coded"
rm -rf "$O"/good-* "$O"/bad-* "$O/SHA256SUMS"

# good NAME FIELD DIMS STEPS ENCODER-OPTIONS...: a dataset from tvpal-gen.
# The manifest's source lines name absolute input paths (of this run's
# scratch folder): they are rewritten to /corpus/input/FILE, the same in
# every manifest copy, so the output does not depend on where it ran.
good() {
    name=$1 field=$2 dims=$3 steps=$4
    shift 4
    "$GEN" --field "$field" --dims "$dims" --steps "$steps" -o "$tmp/in-$name" \
        > /dev/null
    good_encode "$name" "$dims" "$@"
}
# good_encode NAME DIMS ENCODER-OPTIONS...: encodes $tmp/in-NAME/*.f32.
good_encode() {
    name=$1 dims=$2
    shift 2
    "$ENC" -q -j 1 --dims "$dims" "$@" -o "$tmp/$name" "$tmp/in-$name"/*.f32 \
        > /dev/null
    for m in "$tmp/$name/manifest.txt" "$tmp/$name"/node-*/manifest.txt; do
        sed 's|^source = .*/|source = /corpus/input/|' "$m" > "$tmp/m"
        cat "$tmp/m" > "$m"
    done
    cp -r "$tmp/$name" "$O/$name"
}
# slices DIR NX NY EXPR...: a source of T = 3 float32 steps in DIR, NX x NY
# x (one per EXPR) voxels, slice z holding EXPR number z, a python
# expression of x, y, t and r (32 phases, random from seed 7).
slices() {
    mkdir -p "$1"
    "$PY" - "$@" <<'PY'
import math, random, struct, sys
out, nx, ny, exprs = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), sys.argv[4:]
random.seed(7)
r = [random.uniform(0, 6.3) for _ in range(32)]
for t in range(3):
    v = [eval(e) for e in exprs for y in range(ny) for x in range(nx)]
    open("%s/t%d.f32" % (out, t), "wb").write(struct.pack("<%df" % len(v), *v))
PY
}
# f32 tables, one node; N = 2 over T = 3 steps: a short first window
# (odd slices: [0,1)) and a window cut at T (even slices: [2,3)).  --table
# f32 is said since the default became auto (table_format 4).
good good-1-basic blobs 4x3x2 3 --window 2 --table f32 --axes xyz --index-coding none \
    --schedule staggered
# 16-bit tables, two nodes; node 1 of axis z holds one slice (phase 0), so
# its record 1 holds no chunk.
good good-2-u16-nodes turbulence 4x3x3 3 --window 2 --nodes 2 --table u16 --axes xyz --index-coding none \
    --schedule staggered
# One axis (FORMAT.md 2.2): blobs 4x3x2, T = 3, N = 2, --axes z: node-0 has
# axis-z.tvps only, the manifest format_version 3 and axes = z.
good good-4-axis-z blobs 4x3x2 3 --window 2 --table f32 --axes z --index-coding none \
    --schedule staggered
# Missing values, 16-bit tables (table_format 3): blobs 4x3x2, T = 3, N = 2,
# voxel (1,1,0) missing at every step and voxel (2,0,1) at step 1 only.
"$GEN" --field blobs --dims 4x3x2 --steps 3 -o "$tmp/in-good-3-missing" > /dev/null
"$PY" - "$tmp/in-good-3-missing" <<'PY'
import glob, struct, sys
for t, f in enumerate(sorted(glob.glob(sys.argv[1] + "/*.f32"))):
    b = bytearray(open(f, "rb").read())
    nan = struct.pack("<I", 0x7FC00000)
    for (x, y, z), steps in (((1, 1, 0), (0, 1, 2)), ((2, 0, 1), (1,))):
        if t in steps:
            i = x + 4 * (y + 3 * z)
            b[4 * i:4 * i + 4] = nan
    open(f, "wb").write(b)
PY
good_encode good-3-missing 4x3x2 --window 2 --table u16 --axes xyz --index-coding none \
    --schedule staggered
# The table format per chunk (table_format 4, --table auto): 20x16x3, T = 3,
# N = 2.  Slice z = 0 is smooth (coded with an error: 16-bit table), z = 1
# holds the integers 0, 1, 2 (coded exactly, which a 16-bit table would
# not be: float32), z = 2 is constant (exact in 16 bits too: 16-bit).
slices "$tmp/in-good-5-auto" 20 16 \
    "10 * math.sin(0.3 * x + 0.5 * t) * math.cos(0.2 * y)" \
    "float((x + y + t) % 3)" "5.0"
good_encode good-5-auto 20x16x3 --window 2 --table auto --axes xyz --index-coding none \
    --schedule staggered
# Coded chunks (FORMAT.md 6.11, shard format_version 2, the encoder's default
# since 1.8): blobs 64x64x4, T = 3, N = 2, axis z, written by the encoder of
# 1.8 (kept: see above); --index-coding none above keeps good-1 to good-5
# the plain shards of format_version 1.
cp -r "$tmp/frozen-good-6-coded" "$O/good-6-coded"
# Coded chunks of 1.10 (transform T2 of the tables, G of the indices where
# it codes smaller): 40x32x3, T = 3, N = 2, axis z.  Slice z = 0 is smooth
# along x with a random phase per row (the indices of neighbouring rows
# unrelated: G not chosen, flags 0xE), z = 1 a smooth blob (16-bit table, G:
# 0x1E), z = 2 integers 0, 1, 2 in 8x8 squares (exact: float32 table, G:
# 0x1C).
slices "$tmp/in-good-7-coded-t2" 40 32 "math.sin(x / 6 + t / 3 + r[y])" \
    "math.exp(-((x - 20 - t) ** 2 + (y - 16) ** 2) / 60.0)" \
    "float((x // 8 + y // 8 + t) % 3)"
good_encode good-7-coded-t2 40x32x3 --window 2 --axes z --schedule staggered
# The joined window schedule (FORMAT.md 5, shard format_version 3, manifest
# format_version 4, the encoder's default since 1.11): blobs 4x3x5, T = 5,
# N = 2, all axes, plain: slices of phase 1 have the first window [0, 3)
# (wlen 3 > N), record 1 holds no chunk, every other record one phase.
good good-8-joined blobs 4x3x5 5 --window 2 --table f32 --axes xyz --index-coding none
# Palette groups (FORMAT.md 5.1, shard format_version 4, since 1.12): blobs
# 4x3x6, T = 5, N = 2, groups of G = 2, two nodes, all axes, plain float32
# tables.  z: groups {0,1} {2,3} {4,5} (phases 0, 1, 0); node 0 holds
# slices 0..2, so group {2,3} is cut by the slabs (one chunk per slice)
# and group {0,1} is one chunk of two slices (h = 6).  y: n = 3, the last
# group one slice.
good good-9-group blobs 4x3x6 5 --window 2 --group 2 --nodes 2 --table f32 --axes xyz \
    --index-coding none

# The bad files: each one copy of a good-1-basic file with one fault.
"$PY" - "$O" <<'PY'
import struct, sys
O = sys.argv[1]
base = O + "/good-1-basic/"

def crc32c(data, crc=0):
    tab = crc32c.tab
    if not tab:
        for i in range(256):
            c = i
            for _ in range(8):
                c = (c >> 1) ^ (0x82F63B78 if c & 1 else 0)
            tab.append(c)
    c = crc ^ 0xFFFFFFFF
    for b in data:
        c = tab[(c ^ b) & 0xFF] ^ (c >> 8)
    return c ^ 0xFFFFFFFF
crc32c.tab = []
assert crc32c(b"123456789") == 0xE3069283

shard = bytearray(open(base + "node-0/axis-z.tvps", "rb").read())
idx = struct.unpack_from("<Q", shard, 72)[0]
steps = struct.unpack_from("<I", shard, 28)[0]
def rec(t):
    return struct.unpack_from("<Q", shard, idx + 32 * t)[0]
def u32(b, off, v):
    struct.pack_into("<I", b, off, v)
def seal_header(b):
    u32(b, 4092, crc32c(b[0:4092]))
def seal_index(b):
    u32(b, 88, crc32c(b[idx:]))
    seal_header(b)
def seal_record(b, t):
    """Recomputes record t's payload CRC (header, index entry) and the
    record header CRC, the index CRC and the shard header CRC."""
    r = rec(t)
    n = struct.unpack_from("<Q", b, r + 16)[0]
    pc = crc32c(b[r + 64:r + 64 + n])
    u32(b, r + 24, pc)
    u32(b, r + 60, crc32c(b[r:r + 60]))
    u32(b, idx + 32 * t + 24, pc)
    seal_index(b)
def write(name, b):
    open(O + "/" + name, "wb").write(bytes(b))

b = bytearray(shard); b[0:4096] = bytes(4096)
write("bad-shard-unfinished.tvps", b)          # header never written
b = bytearray(shard); u32(b, 8, 5)             # CRC left stale on purpose
write("bad-shard-version-5.tvps", b)
b = bytearray(shard); u32(b, 92, 2); seal_header(b)  # a group in version 1
write("bad-shard-group-version.tvps", b)
b = bytearray(shard); u32(b, 8, 3); seal_header(b)   # joined, schedule 0
write("bad-shard-schedule.tvps", b)
b = bytearray(shard); b[2000] ^= 0x01          # a reserved byte
write("bad-shard-header-crc.tvps", b)
b = bytearray(shard); u32(b, 64, 6); seal_header(b)
write("bad-shard-table-format.tvps", b)
write("bad-shard-truncated.tvps", shard[:-4096])
write("bad-shard-extra.tvps", shard + bytes(4096))
b = bytearray(shard); b[idx + 32 * 1 + 20] ^= 0x01  # entry 1 chunk_count
write("bad-shard-index-crc.tvps", b)
b = bytearray(shard)                           # entry 1 one page further
struct.pack_into("<Q", b, idx + 32, rec(1) + 4096); seal_index(b)
write("bad-shard-index-order.tvps", b)
b = bytearray(shard); b[rec(2) + 40] ^= 0x01   # a reserved header byte
write("bad-record-header-crc.tvps", b)
b = bytearray(shard); b[rec(1) + 64 + 64 + 100] ^= 0x01  # a table byte
write("bad-record-payload-crc.tvps", b)
b = bytearray(shard); b[rec(0) + 4000] = 0x5A  # after the payload
assert struct.unpack_from("<Q", b, rec(0) + 16)[0] + 64 < 4000 < rec(1) - rec(0)
write("bad-record-padding.tvps", b)
b = bytearray(shard); u32(b, rec(1) + 4, 2); seal_record(b, 1)
write("bad-record-step.tvps", b)
b = bytearray(shard); u32(b, rec(2) + 64 + 16, 5); seal_record(b, 2)
write("bad-record-chunk.tvps", b)              # chunk w 5, slices are 4x3
b = bytearray(shard); u32(b, rec(1) + 64 + 28, 4); seal_record(b, 1)
write("bad-chunk-flag-reserved.tvps", b)       # flags bit 2: no meaning
b = bytearray(shard)                           # dims 1x1x100000000:
struct.pack_into("<3I", b, 16, 1, 1, 100000000)  # 10^8 slices of 1x1
struct.pack_into("<4I", b, 48, 0, 100000000, 1, 1); seal_header(b)
write("bad-shard-huge-dims.tvps", b)           # records hold 2 slices

def load(path):
    """Makes the shard at path the one rec() and seal_*() work on."""
    global shard, idx
    shard = bytearray(open(path, "rb").read())
    idx = struct.unpack_from("<Q", shard, 72)[0]
def chunks(t):
    """Offsets of record t's chunks (walked by each one's own size)."""
    r, tf = rec(t), struct.unpack_from("<I", shard, 64)[0]
    n, pos, out = struct.unpack_from("<II", shard, r + 8)[0], r + 64, []
    for _ in range(n):
        wlen, w, h, flags = struct.unpack_from("<3I4xI", shard, pos + 12)
        e = 2 if tf in (1, 3) or (tf >= 4 and flags & 2) else 4
        out.append(pos)
        if flags & 4:   # coded (FORMAT.md 6.11): header, frame, padding
            pos += 64 + (struct.unpack_from("<I", shard, pos + 56)[0] + 63) // 64 * 64
        else:
            pos += 64 + wlen * 256 * e + (w * h + 63) // 64 * 64
    return out
# Bad files planted in place of another good dataset's node-0/axis-z.tvps
# (README.md: bad-u16-* in good-2-u16-nodes, bad-auto-* in good-5-auto).
load(O + "/good-2-u16-nodes/node-0/axis-z.tvps")
b = bytearray(shard); u32(b, chunks(1)[0] + 28, 2); seal_record(b, 1)
write("bad-u16-chunk-flag.tvps", b)            # flags bit 1, table_format 1
load(O + "/good-9-group/node-0/axis-z.tvps")
b = bytearray(shard); u32(b, 92, 1); seal_header(b)  # version 4, group 1
write("bad-group-shard-1.tvps", b)
c = chunks(0)                                  # slices 0-1 (h 6), 2 (h 3)
assert [struct.unpack_from("<I", shard, o + 20)[0] for o in c] == [6, 3]
b = bytearray(shard); u32(b, c[0] + 20, 9); seal_record(b, 0)
write("bad-group-chunk-rows.tvps", b)          # 3 slices, G = 2
load(O + "/good-5-auto/node-0/axis-z.tvps")
c = chunks(0)                                  # slices 0 (u16), 1 (f32), 2 (u16)
assert [struct.unpack_from("<I", shard, o + 28)[0] for o in c] == [2, 0, 2]
b = bytearray(shard); u32(b, c[2] + 28, 0); seal_record(b, 0)
write("bad-auto-chunk-size.tvps", b)           # a 16-bit chunk said float32
b = bytearray(shard); u32(b, c[0] + 28, 3); seal_record(b, 0)
write("bad-auto-chunk-missing.tvps", b)        # missing flag, table_format 4
# Coded chunks (README.md: bad-coded-* in good-6-coded): record 1's first
# chunk is coded.
load(O + "/good-6-coded/node-0/axis-z.tvps")
assert struct.unpack_from("<I", shard, 8)[0] == 2
c = chunks(1)[0]
assert struct.unpack_from("<I", shard, c + 28)[0] & 4
b = bytearray(shard); b[c + 64] ^= 0x01; seal_record(b, 1)
write("bad-coded-frame.tvps", b)               # zstd magic broken, CRCs valid
b = bytearray(shard); u32(b, c + 56, 1 << 20); seal_record(b, 1)
write("bad-coded-bytes.tvps", b)               # a frame larger than the chunk
b = bytearray(shard); u32(b, idx + 32 + 28, struct.unpack_from("<I", shard, idx + 32 + 28)[0] + 1)
seal_index(b)
write("bad-coded-plain.tvps", b)               # plain_pages one page more
b = bytearray(shard); u32(b, 8, 1); seal_header(b)
write("bad-coded-version-1.tvps", b)           # coded records, version 1
# Transform bits (README.md: bad-coded-t2-* in good-7-coded-t2): record 0's
# first chunk (slice 0) is coded with T2 and without G.
load(O + "/good-7-coded-t2/node-0/axis-z.tvps")
c = chunks(0)[0]
assert struct.unpack_from("<I", shard, c + 28)[0] == 0xE
b = bytearray(shard); u32(b, c + 28, 0xA); seal_record(b, 0)
write("bad-coded-t2-uncoded.tvps", b)          # bit 3 without bit 2

# Manifests: good-1-basic's with one change each.
text = open(base + "manifest.txt").read()
lines = text.split("\n")
def edit(key, value):
    """The manifest with key's line set to value (None: removed)."""
    out = []
    for l in lines:
        if l.startswith(key + " = "):
            if value is None:
                continue
            l = key + " = " + value
        out.append(l)
    return "\n".join(out)
def mwrite(name, t):
    open(O + "/" + name, "w", newline="").write(t)
mwrite("bad-manifest-no-window.txt", edit("window", None))
mwrite("bad-manifest-format.txt", edit("format", "tvpal-dataset-2"))
mwrite("bad-manifest-version-5.txt", edit("format_version", "5"))
mwrite("bad-manifest-schedule-version.txt", edit("window", "2\nschedule = joined"))
mwrite("bad-manifest-schedule-mismatch.txt",
       edit("format_version", "4").replace("window = 2", "window = 2\nschedule = joined"))
mwrite("bad-manifest-schedule.txt", edit("window", "2\nschedule = aligned"))
mwrite("bad-manifest-levels-9.txt", edit("table", "f32\nlevels = 9"))
mwrite("bad-manifest-window-17.txt", edit("window", "17"))
mwrite("bad-manifest-dims.txt", edit("dims", "4x3"))
mwrite("bad-manifest-endian.txt", edit("endian", "middle"))
mwrite("bad-manifest-table.txt", edit("table", "f16"))
mwrite("bad-manifest-nodes.txt", edit("nodes", "3"))
mwrite("bad-manifest-window-mismatch.txt", edit("window", "3"))
mwrite("bad-manifest-table-mismatch.txt", edit("table", "u16"))  # f32 shards
mwrite("bad-manifest-table-auto.txt", edit("table", "auto"))  # f32 shards
mwrite("bad-manifest-max-nan.txt", edit("value_max", "nan"))
mwrite("bad-manifest-min-inf.txt", edit("value_min", "inf"))
mwrite("bad-manifest-min-above-max.txt", edit("value_min", "2"))
hist = [l for l in lines if l.startswith("histogram = ")][0].split()[2:]
mwrite("bad-manifest-histogram-short.txt",
       edit("histogram", " ".join(hist[:63])))
mwrite("bad-manifest-histogram-negative.txt",
       edit("histogram", " ".join(["-1"] + hist[1:])))
mwrite("bad-manifest-no-equals.txt", text.replace("table = f32", "table f32"))
# The axes key (FORMAT.md 2.2, 3.2): format_version 3 and a bad value, or a
# good subset under a version that cannot have one.
def axes(value, version="3"):
    t = edit("format_version", version)
    return t.replace("table = f32\n", "axes = " + value + "\ntable = f32\n")
mwrite("bad-manifest-axes-letter.txt", axes("q"))
mwrite("bad-manifest-axes-empty.txt", axes(""))
mwrite("bad-manifest-axes-repeat.txt", axes("zz"))
mwrite("bad-manifest-axes-version.txt", axes("z", "1"))
src = [l for l in lines if l.startswith("source = ")]
mwrite("bad-manifest-sources.txt", text.replace(src[-1] + "\n", ""))
# Accepted variants of the syntax (Section 3.1): CRLF ends, blank and
# comment lines, blanks around keys and values, a '#' inside a value, no
# format_version, unknown keys, a key given twice (the last one counts),
# and the axes key as writers before FORMAT.md 1.6 wrote it.
v = []
for l in lines:
    if l.startswith("format_version"):
        continue
    if l.startswith("table = "):
        v.append("axes = x y z")
    if l.startswith("window = "):
        v += ["window = 9", "\t window\t=  " + l.split(" = ")[1] + "  "]
        continue
    if l.startswith("encoder = "):
        l = "encoder = tvpal-encode #1"
    v.append(l)
v[1:1] = ["", "   # a comment after blanks", "future_key = a later version's key",
          "future.key-2 = x = y"]
mwrite("good-manifest-variants.txt", "\r\n".join(v))
PY

# Expected decoder output: one line per good dataset, axis and step.
for ds in "$O"/good-*/; do
    ds=${ds%/}
    name=$(basename "$ds")
    steps=$(sed -n 's/^steps = //p' "$ds/manifest.txt")
    # The stored axes (FORMAT.md 2.2): the axes key's letters, else x y z.
    axes=$(sed -n 's/^axes = //p' "$ds/manifest.txt" | sed 's/[^xyz]//g; s/./& /g')
    for a in ${axes:-x y z}; do
        t=0
        while [ "$t" -lt "$steps" ]; do
            "$DEC" "$ds" --step $t --axis $a -o - | sha256sum |
                sed "s|-\$|$name/$a/$t|"
            t=$((t + 1))
        done
    done
done > "$O/SHA256SUMS"
