#!/bin/sh
# types: u8, u16 (big-endian), i16 and f64 inputs and the single-file
# layout (--steps) encode and report correctly; integer data with at most 256
# values per slice is exact at N = 1.
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
finish
