#!/bin/sh
# types: u8, u16 (big-endian), i16 and f64 inputs and the single-file
# layout (--steps) encode and report correctly; integer data with at most 256
# values per slice is exact at N = 1; the same values from float64 and
# float32 files have the same ratio_f32, and ratio and ratio_input count
# the source's and the input files' bytes.
. "$(dirname "$0")/lib.sh"
D=12x10x9
T=5
$PY - "$W" $T <<'PY' || fail "python writer"
import struct, sys, math
w, T = sys.argv[1], int(sys.argv[2])
nx, ny, nz = 12, 10, 9
def val(x, y, z, t):
    return math.sin(0.5 * x + 0.2 * t) * math.cos(0.4 * y) + 0.1 * z
for t in range(T):
    vs = [val(x, y, z, t) for z in range(nz) for y in range(ny) for x in range(nx)]
    open("%s/u8_%d.raw" % (w, t), "wb").write(bytes(int(100 + 60 * v) & 255 for v in vs))
    open("%s/u16be_%d.raw" % (w, t), "wb").write(b"".join(struct.pack(">H", int(30000 + 15000 * v)) for v in vs))
    open("%s/i16_%d.raw" % (w, t), "wb").write(b"".join(struct.pack("<h", int(-500 + 9000 * v)) for v in vs))
    open("%s/f64_%d.raw" % (w, t), "wb").write(b"".join(struct.pack("<d", 1e-3 * v) for v in vs))
    open("%s/f32_%d.raw" % (w, t), "wb").write(b"".join(struct.pack("<f", 1e-3 * v) for v in vs))
    with open("%s/all_f64.raw" % w, "ab") as f:
        f.write(b"".join(struct.pack("<d", 1e-3 * v) for v in vs))
PY
run() { # name type endian N files...
    name=$1 type=$2 endian=$3 N=$4; shift 4
    "$ENC" -q --dims $D --type $type --endian $endian --window $N -o "$W/$name" "$@" > /dev/null \
        || { fail "encode $name"; return; }
    line=$("$REP" -q "$W/$name") || { fail "report $name"; return; }
    echo "$line"
}
p=$(kv psnr "$(run u8-1 u8 little 1 "$W"/u8_*.raw)")
[ "$p" = inf ] && ok "u8 N=1 exact" || fail "u8 N=1 psnr $p, expected exact"
for spec in "u8 little" "u16be big" "i16 little" "f64 little"; do
    set -- $spec
    p=$(kv psnr "$(run "$1-4" "${1%be}" "$2" 4 "$W"/$1_*.raw)")
    ge "$p" 30 && ok "$1 N=4 psnr $p" || fail "$1 N=4 psnr $p < 30"
done
line=$("$ENC" -q --dims $D --type f64 --steps $T --window 4 -o "$W/single" "$W/all_f64.raw") \
    || fail "single-file encode"
for t in 0 4; do
    "$DEC" "$W/single" --step $t -o "$W/s.f32" && "$DEC" "$W/f64-4" --step $t -o "$W/m.f32" \
        && cmp -s "$W/s.f32" "$W/m.f32" && ok "single file = file per step at t=$t" \
        || fail "single-file layout differs at t=$t"
done
p=$(kv psnr "$("$REP" -q "$W/single")")
ge "$p" 30 && ok "single-file report $p" || fail "single-file report $p"
# The same values from float64 and from float32 files: ratio counts the
# source's bytes (twice for float64), ratio_f32 the values as float32 (the
# same), ratio_input the input files' bytes on disk.
l64=$("$ENC" -q --dims $D --type f64 --window 4 -o "$W/r64" "$W"/f64_*.raw) || fail "encode r64"
l32=$("$ENC" -q --dims $D --type f32 --window 4 -o "$W/r32" "$W"/f32_*.raw) || fail "encode r32"
cmp -s "$W/r64/node-0/axis-z.tvps" "$W/r32/node-0/axis-z.tvps" || fail "f64 and f32 of the same values: shards differ"
"$PY" - "$l64" "$l32" $((12 * 10 * 9 * T)) <<'PY' > "$W/ratio.txt" 2>&1 && ok "$(cat "$W/ratio.txt")" || fail "$(cat "$W/ratio.txt")"
import sys
kv = lambda line: dict(f.split("=", 1) for f in line.split() if "=" in f)
a, b, vts = kv(sys.argv[1]), kv(sys.argv[2]), int(sys.argv[3])
bad = []
for k, w, size in (("f64", a, 8), ("f32", b, 4)):
    disk = float(w["bytes"])
    for key, want in (("ratio", vts * size / disk), ("ratio_f32", vts * 4 / disk),
                      ("ratio_input", vts * size / disk)):
        if abs(float(w[key]) - want) > 1e-3 * want + 5e-4:
            bad.append("%s %s=%s, %.4f expected" % (k, key, w[key], want))
if bad:
    sys.exit("; ".join(bad))
print("f64: ratio %s ratio_f32 %s ratio_input %s; f32: ratio %s ratio_f32 %s"
      % (a["ratio"], a["ratio_f32"], a["ratio_input"], b["ratio"], b["ratio_f32"]))
PY
finish
