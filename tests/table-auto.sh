#!/bin/sh
# table-auto: --table auto (the default) chooses each slice-window's table
# format (FORMAT.md 6.7, table_format 4 and 5).  An independent reader
# written from FORMAT.md (tests/shard_decode.py) decodes every step and
# axis to tvpal-decode's bits, and every chunk holds f32's indices and a
# table by the rule (float32 entries exactly f32's; 16-bit ones within the
# error budget against the source, at the coarsest step that keeps it;
# unheld entries copies); PSNR within 0.001 dB of float32 tables, fewer
# bytes than u16; tvpal-report and tvpal-info
# count the chunks; a window with an outlier keeps float32 where the
# outlier is and 16 bits elsewhere; integer data with few distinct values
# decodes exactly; missing values give table_format 5; jumps decode as
# sequential playback; the player draws it; and --table f32 and u16 still
# write the corpus's bytes (tests/files).
. "$(dirname "$0")/lib.sh"
$PY -c "import numpy" 2>/dev/null || { echo "numpy missing (scripts/setup-deps installs python3-numpy)"; exit 99; }
command -v zstd > /dev/null || { echo "zstd missing (scripts/setup-deps installs zstd; tests/shard_decode.py inflates coded chunks with it)"; exit 99; }
CHK=$TVPAL_BUILDDIR/tests/tvpal-check
export PYTHONPATH="$TVPAL_SRCDIR/tests${PYTHONPATH:+:$PYTHONPATH}"
D=40x34x24
T=10
"$GEN" --field turbulence --dims $D --steps $T -o "$W/in" > /dev/null || fail gen
for tf in f32 u16 default; do
    o="--table $tf"
    [ $tf = default ] && o=""
    # shellcheck disable=SC2086
    "$ENC" --axes xyz -q --dims $D --window 4 --nodes 2 $o -o "$W/$tf" "$W"/in/*.f32 > "$W/enc-$tf.txt" \
        || fail "encode $tf"
done
grep -q "^table = auto" "$W/default/manifest.txt" && ok "default: manifest says table = auto" \
    || fail "default table: $(grep '^table' "$W/default/manifest.txt")"
[ "$(od -A n -t u4 -j 64 -N 4 "$W/default/node-1/axis-y.tvps" | tr -d ' ')" = 4 ] \
    && ok "default: shards say table_format 4" || fail "default: table_format"

# Every decoded step against the independent reader; every chunk against
# the forced formats' chunk of the same slice-window.
for a in x y z; do
    t=0
    while [ $t -lt $T ]; do
        echo "$("$DEC" "$W/default" --step $t --axis $a -o - | sha256sum | cut -d' ' -f1)  $t"
        t=$((t + 1))
    done > "$W/dec-$a.txt"
    $PY "$TVPAL_SRCDIR/tests/shard_decode.py" "$W/default" $a > "$W/ref-$a.txt" || fail "shard_decode $a"
    cmp -s "$W/dec-$a.txt" "$W/ref-$a.txt" && ok "axis $a: tvpal-decode = the FORMAT.md reader, $T steps" \
        || fail "axis $a: tvpal-decode differs from tests/shard_decode.py"
done
# same_chunks AUTO F32 U16 OUT DIMS GLOB: every chunk of the dataset AUTO
# (source: the raw float32 files GLOB matches, in order, of DIMS) holds the
# indices of the same slice-window in F32, and a table that follows
# FORMAT.md 6.7's --table auto rule:
#   - an entry no voxel of the chunk holds (unheld) copies the held entry
#     its delta codes in nothing (row 0: the entry to its left, the first
#     held one for index 0; later rows: the one above);
#   - a float32 chunk (flag 0) holds F32's held entries exactly;
#   - a 16-bit chunk (flag 0x2) errs, summed over its voxels and steps
#     against the source, at most 1e-4 of F32's chunk more, with at most
#     65535 steps (q <= 65535).
# OUT gets "N16 16-bit, N32 float32, BAD differ, NC coarser than 65535
# steps".
same_chunks() {
    $PY - "$@" > "$4" <<'PY'
import glob, sys
import numpy as np
from shard_decode import chunks
auto, f32d, u16d, out, dims, pattern = sys.argv[1:7]
nx, ny, nz = (int(v) for v in dims.split("x"))
src = np.stack([np.fromfile(f, "<f4").reshape(nz, ny, nx)
                for f in sorted(glob.glob(pattern))]).astype(np.float64)
def samples(axis, s, ws, wl):
    v = src[ws:ws + wl]
    if axis == 0:                              # (wl, h, w) as in the slice
        return v[:, :, :, s]
    return v[:, :, s, :] if axis == 1 else v[:, s]
def sse(table, idx, x):
    e = x - table[:, idx].astype(np.float64)
    return float(np.nansum(e * e))
bad = n16 = n32 = coarse = 0
for axis in range(3):
    key = lambda c: (c["slice"], c["wstart"])
    f32 = {key(c): c for c in chunks(f32d, axis)}
    for c in chunks(auto, axis):
        want = f32[key(c)]
        t, idx = c["table"], c["idx"]
        held = np.zeros(256, bool)
        held[np.unique(idx)] = True
        ok = (c["flags"] & 2) == (2 if c["u16"] else 0) and np.array_equal(idx, want["idx"])
        first = int(np.argmax(held))
        for i in np.flatnonzero(~held):
            left = t[0, i - 1] if i else t[0, first]
            ok = ok and t[0, i].tobytes() == left.tobytes()
            ok = ok and t[1:, i].tobytes() == t[:-1, i].tobytes()
        if c["u16"]:
            x = samples(axis, c["slice"], c["wstart"], c["wlen"])
            s32, s16 = sse(want["table"], idx, x), sse(t, idx, x)
            ok = ok and s16 - s32 <= 1e-4 * s32 * (1 + 1e-9) + 1e-30
            coarse += c["qmax"] < 65534
        else:
            ok = ok and t[:, held].tobytes() == want["table"][:, held].tobytes()
        bad += not ok
        n16 += c["u16"]
        n32 += not c["u16"]
print("%d 16-bit, %d float32, %d differ, %d coarser than 65535 steps" % (n16, n32, bad, coarse))
sys.exit(1 if bad or not n16 else 0)
PY
}
same_chunks "$W/default" "$W/f32" "$W/u16" "$W/chunks.txt" $D "$W/in/*.f32" \
    && [ "$(cut -d' ' -f7 "$W/chunks.txt")" -gt 0 ] \
    && ok "every chunk holds f32's indices and a table by the auto rule: $(cat "$W/chunks.txt")" \
    || fail "chunks against the auto rule: $(cat "$W/chunks.txt")"
n16=$(cut -d' ' -f1 "$W/chunks.txt") n32=$(cut -d' ' -f3 "$W/chunks.txt")

# The figures: PSNR, bytes, the counts in tvpal-report, -info and -encode.
f=$("$REP" -q "$W/f32") && u=$("$REP" -q "$W/u16") && a=$("$REP" -q "$W/default") || fail report
awk -v a="$(kv psnr "$a")" -v f="$(kv psnr "$f")" 'BEGIN { d = a - f; exit !(d < 0.001 && d > -0.001) }' \
    && ok "psnr auto $(kv psnr "$a"), f32 $(kv psnr "$f"), u16 $(kv psnr "$u")" \
    || fail "psnr auto $(kv psnr "$a") against f32 $(kv psnr "$f")"
bytes() { du -b -c "$1"/node-*/*.tvps | tail -n 1 | cut -f1; }
bf=$(bytes "$W/f32") bu=$(bytes "$W/u16") ba=$(bytes "$W/default")
# auto's 16-bit tables take fewer steps than u16's 65535 and leave unheld
# entries nothing to code, so it is the smallest of the three here.
[ "$ba" -lt "$bu" ] && [ "$bu" -lt "$bf" ] && ok "bytes: f32 $bf > u16 $bu > auto $ba" \
    || fail "bytes: f32 $bf, auto $ba, u16 $bu"
[ "$(kv tables_u16 "$a")" = "$n16" ] && [ "$(kv tables_f32 "$a")" = "$n32" ] \
    && [ "$(kv tables_f32 "$f")" = "$((n16 + n32))" ] && [ "$(kv tables_u16 "$u")" = "$((n16 + n32))" ] \
    && ok "tvpal-report counts the tables ($n16 16-bit, $n32 float32)" \
    || fail "report counts: $(kv tables_u16 "$a")/$(kv tables_f32 "$a"), expected $n16/$n32"
awk -v a="$(kv table_bpv "$a")" -v f="$(kv table_bpv "$f")" -v n="$n16" -v m="$n32" \
    'BEGIN { want = f * (n / 2 + m) / (n + m); exit !(a > want - 1e-3 && a < want + 1e-3) }' \
    && ok "table_bpv $(kv table_bpv "$a"): the chunks' own entry sizes" || fail "table_bpv $(kv table_bpv "$a")"
"$INFO" "$W/default" > "$W/info.txt" || fail "tvpal-info"
grep -q "^tables_u16 = $n16 " "$W/info.txt" && grep -q "^tables_f32 = $n32 " "$W/info.txt" \
    && ok "tvpal-info counts the tables" || fail "tvpal-info: $(grep tables "$W/info.txt")"
grep -q " tables_u16=$n16 tables_f32=$n32" "$W/enc-default.txt" && ok "tvpal-encode's summary counts them" \
    || fail "encode summary: $(cat "$W/enc-default.txt")"
"$INFO" "$W/default" --verify > /dev/null && ok "auto verifies" || fail "verify auto"
"$CHK" seqjump "$W/default" > "$W/sj.txt" 2>&1 && ok "auto: jumps = sequential" \
    || { fail "seqjump auto"; cat "$W/sj.txt" >&2; }

# An outlier: a smooth field with one voxel of 1e6 at step 5.  On each axis
# the window of the slice through it that holds step 5 keeps float32 (16
# bits would coarsen all its entries: u16 loses about 10 dB); the other
# windows of two steps or more are 16-bit.  (A window of one step, 256
# levels for one sample per voxel, is coded almost exactly and may keep
# float32.)
$PY - "$W" <<'PY' || fail "outlier input"
import sys, numpy as np
w = sys.argv[1]; nx, ny, nz = 24, 20, 16
z, y, x = np.meshgrid(np.arange(nz), np.arange(ny), np.arange(nx), indexing="ij")
for t in range(8):
    v = np.sin(0.4 * x + 0.3 * t) * np.cos(0.3 * y) + 0.1 * z
    if t == 5:
        v[5, 4, 3] = 1e6
    v.astype("<f4").tofile("%s/out_t%d.f32" % (w, t))
PY
for tf in f32 u16 auto; do
    "$ENC" --axes xyz -q --dims 24x20x16 --window 4 --table $tf --schedule staggered \
        -o "$W/out-$tf" "$W"/out_t*.f32 > /dev/null \
        || fail "encode outlier $tf"
done
$PY - "$W/out-auto" > "$W/out.txt" <<'PY' || fail "outlier chunks: $(cat "$W/out.txt")"
import sys
from shard_decode import chunks
at = (3, 4, 5)                     # x, y, z of the outlier, at step 5
bad, n, n32 = [], 0, 0
for axis in range(3):
    for c in chunks(sys.argv[1], axis):
        holds = c["slice"] == at[axis] and c["wstart"] <= 5 < c["wstart"] + c["wlen"]
        n += 1
        n32 += not c["u16"]
        if (c["u16"] and holds) or (not c["u16"] and not holds and c["wlen"] > 1):
            bad.append(("xyz"[axis], c["slice"], c["wstart"], c["wlen"], c["u16"]))
print("%d chunks, %d float32, %d not as expected %s" % (n, n32, len(bad), bad[:5]))
sys.exit(1 if bad else 0)
PY
ok "outlier: float32 where it is, 16-bit in every other window of 2+ steps ($(cat "$W/out.txt"))"
same_chunks "$W/out-auto" "$W/out-f32" "$W/out-u16" "$W/chunks.txt" 24x20x16 "$W/out_t*.f32" \
    && ok "outlier: every chunk holds a table by the auto rule: $(cat "$W/chunks.txt")" \
    || fail "outlier chunks against the auto rule: $(cat "$W/chunks.txt")"
f=$("$REP" -q "$W/out-f32") && u=$("$REP" -q "$W/out-u16") && a=$("$REP" -q "$W/out-auto") || fail "report outlier"
awk -v a="$(kv psnr "$a")" -v f="$(kv psnr "$f")" 'BEGIN { d = a - f; exit !(d < 0.001 && d > -0.001) }' \
    && ok "outlier: psnr auto $(kv psnr "$a"), f32 $(kv psnr "$f"), u16 $(kv psnr "$u")" \
    || fail "outlier: psnr auto $(kv psnr "$a"), f32 $(kv psnr "$f")"

# Integer data with few distinct values (u8: 0, 50, 100, 250 per voxel,
# flipped to 250 - v every third step) is coded exactly, and auto keeps it
# exact (16-bit tables would round it).
$PY - "$W" <<'PY' || fail "integer input"
import sys, numpy as np
rng = np.random.default_rng(3)
base = rng.choice([0, 50, 100, 250], size=(12, 14, 16))
for t in range(6):
    (base if t % 3 else 250 - base).astype(np.uint8).tofile("%s/int_t%d.u8" % (sys.argv[1], t))
PY
for tf in auto u16; do
    "$ENC" --axes xyz -q --dims 16x14x12 --type u8 --window 4 --table $tf -o "$W/int-$tf" "$W"/int_t*.u8 > /dev/null \
        || fail "encode integers $tf"
done
a=$("$REP" -q "$W/int-auto") && u=$("$REP" -q "$W/int-u16") || fail "report integers"
[ "$(kv psnr "$a")" = inf ] && [ "$(kv max_abs_error "$a")" = 0 ] \
    && ok "integers: auto exact ($(kv tables_f32 "$a") float32, $(kv tables_u16 "$a") 16-bit tables; u16: psnr $(kv psnr "$u"))" \
    || fail "integers: auto psnr $(kv psnr "$a"), max error $(kv max_abs_error "$a")"

# Missing values: table_format 5; NaN exactly where the source has it.
$PY - "$W" <<'PY' || fail "missing input"
import sys, numpy as np
w = sys.argv[1]
for t in range(10):
    a = np.fromfile("%s/in/turbulence_t%04d.f32" % (w, t), "<f4").reshape(24, 34, 40)
    a[2, 3, 4] = np.nan
    if t == 6:
        a[7, 1, 9] = np.nan
    a.tofile("%s/miss_t%d.f32" % (w, t))
PY
"$ENC" --axes xyz -q --dims $D --window 4 -o "$W/miss" "$W"/miss_t*.f32 > /dev/null || fail "encode missing"
[ "$(od -A n -t u4 -j 64 -N 4 "$W/miss/node-0/axis-z.tvps" | tr -d ' ')" = 5 ] \
    && ok "missing: table_format 5" || fail "missing: table_format"
nan_exactly "$W/miss" 6 $D "4,3,2 9,1,7"
nan_exactly "$W/miss" 5 $D "4,3,2"
for a in x y z; do
    t=0
    while [ $t -lt $T ]; do
        echo "$("$DEC" "$W/miss" --step $t --axis $a -o - | sha256sum | cut -d' ' -f1)  $t"
        t=$((t + 1))
    done > "$W/mdec-$a.txt"
    $PY "$TVPAL_SRCDIR/tests/shard_decode.py" "$W/miss" $a > "$W/mref-$a.txt" || fail "shard_decode missing $a"
    cmp -s "$W/mdec-$a.txt" "$W/mref-$a.txt" || fail "missing: axis $a differs from tests/shard_decode.py"
done
ok "missing: tvpal-decode = the FORMAT.md reader"

# The player draws a per-chunk dataset as it draws float32 tables.
PLAY=$TVPAL_BUILDDIR/player/app/tvpal-play
if [ -x "$PLAY" ]; then
    for tf in f32 default; do
        "$PLAY" "$W/$tf" --headless -q --size 64x64 -o "$W/p-$tf" --steps 4:4 > /dev/null || fail "play $tf"
    done
    r=$($PY "$TVPAL_SRCDIR/tests/pngdiff.py" "$W/p-f32/t0004.png" "$W/p-default/t0004.png")
    echo "$r" | grep -q "^max=[01] " && ok "player: auto frame within 1 level of f32 ($r)" || fail "player auto: $r"
fi

# --table f32 and --table u16 write what they wrote before the table format
# per chunk: the shards of tests/files/good-1-basic and good-2-u16-nodes
# (plain chunks, --index-coding none, the staggered schedule, as the corpus
# was written).
F=$TVPAL_SRCDIR/tests/files
"$GEN" --field blobs --dims 4x3x2 --steps 3 -o "$W/g1" > /dev/null \
    && "$ENC" --axes xyz -q -j 1 --dims 4x3x2 --window 2 --table f32 --index-coding none --schedule staggered -o "$W/g1ds" "$W"/g1/*.f32 > /dev/null || fail "good-1"
"$GEN" --field turbulence --dims 4x3x3 --steps 3 -o "$W/g2" > /dev/null \
    && "$ENC" --axes xyz -q -j 1 --dims 4x3x3 --window 2 --nodes 2 --table u16 --index-coding none --schedule staggered -o "$W/g2ds" "$W"/g2/*.f32 > /dev/null || fail "good-2"
same=1
for s in node-0/axis-x node-0/axis-y node-0/axis-z; do
    cmp -s "$W/g1ds/$s.tvps" "$F/good-1-basic/$s.tvps" || { same=0; fail "--table f32: $s.tvps differs from the corpus"; }
done
for s in node-0/axis-x node-0/axis-z node-1/axis-y node-1/axis-z; do
    cmp -s "$W/g2ds/$s.tvps" "$F/good-2-u16-nodes/$s.tvps" || { same=0; fail "--table u16: $s.tvps differs from the corpus"; }
done
[ $same = 1 ] && ok "--table f32 and u16: the corpus's shards byte for byte"
finish
