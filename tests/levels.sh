#!/bin/sh
# levels: tvpal-encode --levels L and the player's levels of detail.
# Encoder: level k is the 2x2x2 average of level k - 1 (odd dims: the last
# block is shorter), missing values left out of each mean and a block all
# missing decoding as NaN; each level decodes within a stated PSNR of that
# average (floor 30 dB, the level-0 encode's own figure is printed beside
# it); the manifest says format_version 4 (levels, joined) and levels; a run stopped during
# the levels resumes without redoing level 0 and gives the same bytes;
# impossible level counts are refused up front.  Player: the level chosen
# for given zooms and sizes matches the rule computed here (the finest
# level whose voxels are at least half a pixel); --level forces one and
# refuses one the dataset lacks; a coarse level keeps the image's opacity
# (mean brightness within 5% of level 0's); streaming reads only the level
# drawn.  tests/levels-live.sh: a cluster and the window with levels.
. "$(dirname "$0")/lib.sh"
D=41x36x30
"$GEN" --field turbulence --dims $D --steps 5 -o "$W/in" || fail gen
# A block of missing values: voxel (0,0,0) in every step (a partly missing
# 2x2x2 block), and the block x,y,z in 10..11 x 10..11 x 10..11 (wholly
# missing: level 1 voxel (5,5,5)).
$PY - "$W"/in/*.f32 <<'PY' || fail "make missing"
import struct, sys
nx, ny, nz = 41, 36, 30
for p in sys.argv[1:]:
    b = bytearray(open(p, "rb").read())
    nan = struct.pack("<f", float("nan"))
    idx = [0] + [x + nx * (y + ny * z) for z in (10, 11) for y in (10, 11) for x in (10, 11)]
    for i in idx:
        b[4 * i:4 * i + 4] = nan
    open(p, "wb").write(b)
PY
"$ENC" --axes xyz -q --dims $D --window 4 --levels 2 -o "$W/ds" "$W"/in/*.f32 > "$W/enc.txt" 2>&1 || fail "encode: $(cat "$W/enc.txt")"
grep -q "levels=2 levels_bytes=[1-9]" "$W/enc.txt" && ok "summary: $(grep -o 'levels=.*' "$W/enc.txt")" \
    || fail "summary: $(cat "$W/enc.txt")"
grep -q "^format_version = 4$" "$W/ds/manifest.txt" && grep -q "^levels = 2$" "$W/ds/manifest.txt" \
    && grep -q "^schedule = joined$" "$W/ds/manifest.txt" \
    && ok "manifest: format_version 4 (levels and the joined schedule), levels = 2" \
    || fail "manifest: $(head -n 15 "$W/ds/manifest.txt")"
grep -q "^dims = 21x18x15$" "$W/ds/level-1/manifest.txt" && grep -q "^dims = 11x9x8$" "$W/ds/level-2/manifest.txt" \
    && ok "level dims 21x18x15, 11x9x8" || fail "level dims"
[ ! -e "$W/ds/levels.job" ] && [ -z "$(ls -d "$W"/ds/level-*.src 2>/dev/null)" ] \
    && ok "no temporaries left in the dataset" || fail "temporaries: $(ls "$W/ds")"
# Each source step is read once: the levels are made beside level 0's one
# pass (said), in this process (no second tvpal-encode), and the step's
# file is opened once.  (Resumed below, the levels are made after level 0
# from the source read again: the same bytes.)
if command -v strace > /dev/null && strace -f -o /dev/null true 2> /dev/null; then
    # LeakSanitizer cannot run under ptrace: off for this run only.
    ASAN_OPTIONS="${ASAN_OPTIONS:-}${ASAN_OPTIONS:+:}detect_leaks=0" \
        strace -f -e trace=openat,execve -o "$W/st.txt" "$ENC" --axes xyz --dims $D --window 4 --levels 2 \
        -o "$W/one" "$W"/in/*.f32 > /dev/null 2> "$W/one.err" || fail "encode: $(cat "$W/one.err")"
    step2=$(ls "$W"/in/*.f32 | sed -n 3p)
    opens=$(grep -c "openat(.*\"$step2\"" "$W/st.txt")
    execs=$(grep -c "execve(" "$W/st.txt")
    grep -q "level 1 of 2: 21x18x15, beside level 0" "$W/one.err" && [ "$opens" = 1 ] && [ "$execs" = 1 ] \
        && ok "levels beside level 0: step 2 opened once, one process" \
        || fail "levels: step 2 opened $opens times, $execs execs: $(cat "$W/one.err")"
    same=1
    for f in $(cd "$W/ds" && find . -name '*.tvps'); do cmp -s "$W/ds/$f" "$W/one/$f" || same=0; done
    [ $same = 1 ] && ok "the same bytes again" || fail "a second encode differs"
else
    echo "no strace (or ptrace not permitted): the read count is not checked"
fi
"$INFO" "$W/ds/level-1" --verify > /dev/null && "$INFO" "$W/ds/level-2" --verify > /dev/null \
    && ok "levels verify" || fail "level verify"
# tvpal-info's level_K_bytes: every file under level-K, as du counts them.
"$INFO" "$W/ds" > "$W/info.txt" || fail "tvpal-info"
for k in 1 2; do
    want=$(find "$W/ds/level-$k" -type f -printf '%s\n' | awk '{s += $1} END {print s}')
    grep -q "^level_${k}_bytes = $want " "$W/info.txt" && ok "tvpal-info: level $k takes $want bytes" \
        || fail "tvpal-info: level $k: $(grep "^level_${k}_" "$W/info.txt"), $want expected"
done
# Decode every level at step 2 and compare with the averages made here.
for k in 0 1 2; do
    dir=$W/ds; [ $k -gt 0 ] && dir=$W/ds/level-$k
    "$DEC" "$dir" --step 2 --axis z -o "$W/dec$k.f32" || fail "decode level $k"
done
# tvpal-decode --level K of the dataset: the same as the level's own.
"$DEC" "$W/ds" --step 2 --level 2 -o "$W/dl2.f32" && cmp -s "$W/dl2.f32" "$W/dec2.f32" \
    && ok "tvpal-decode --level 2: level 2's step" || fail "tvpal-decode --level 2"
expect_exit 2 'level "3": expected 0..2' "$DEC" "$W/ds" --step 0 --level 3 -o "$W/dl3.f32"
$PY - "$W/in" "$W" <<'PY' > "$W/lv.txt" || fail "compare levels: $(cat "$W/lv.txt")"
import array, glob, math, sys
src = sorted(glob.glob(sys.argv[1] + "/*.f32"))[2]
d = [41, 36, 30]
v = array.array("f"); v.frombytes(open(src, "rb").read())
def down(v, d):
    c = [(n + 1) // 2 for n in d]
    out = array.array("f", [0.0]) * (c[0] * c[1] * c[2])
    for z in range(c[2]):
        for y in range(c[1]):
            for x in range(c[0]):
                s, n = 0.0, 0
                for dz in (0, 1):
                    for dy in (0, 1):
                        for dx in (0, 1):
                            X, Y, Z = 2 * x + dx, 2 * y + dy, 2 * z + dz
                            if X < d[0] and Y < d[1] and Z < d[2]:
                                q = v[X + d[0] * (Y + d[1] * Z)]
                                if q == q:
                                    s += q; n += 1
                out[x + c[0] * (y + c[1] * z)] = s / n if n else float("nan")
    return out, c
ref = [(v, d)]
for k in (1, 2):
    ref.append(down(*ref[-1]))
lo = min(q for q in v if q == q); hi = max(q for q in v if q == q)
for k, (r, c) in enumerate(ref):
    dec = array.array("f"); dec.frombytes(open("%s/dec%d.f32" % (sys.argv[2], k), "rb").read())
    assert len(dec) == len(r), (k, len(dec), len(r))
    nan_ok = all((a != a) == (b != b) for a, b in zip(dec, r))
    e = [(a - b) ** 2 for a, b in zip(dec, r) if b == b]
    psnr = 10 * math.log10((hi - lo) ** 2 / (sum(e) / len(e)))
    print("level %d %dx%dx%d psnr %.2f nan_match %d" % (k, c[0], c[1], c[2], psnr, nan_ok))
PY
cat "$W/lv.txt"
for k in 0 1 2; do
    awk -v k=$k '$2 == k { exit !($5 >= 30 && $7 == 1) }' "$W/lv.txt" \
        && ok "level $k: decodes within the floor of its 2x2x2 average, missing exactly where it should" \
        || fail "level $k: $(grep "level $k" "$W/lv.txt")"
done
# tvpal-report --level K: the same comparison, by the report (every step
# and axis), at least the floor; a level the dataset lacks is refused.
for k in 1 2; do
    "$REP" "$W/ds" -q --level $k > "$W/rep$k.txt" || fail "report --level $k: $(cat "$W/rep$k.txt")"
    p=$(sed 's/^psnr=\([0-9.]*\) .*/\1/' "$W/rep$k.txt")
    awk -v p="$p" 'BEGIN { exit !(p >= 30) }' && grep -q "missing_mismatch=0" "$W/rep$k.txt" \
        && ok "tvpal-report --level $k: psnr=$p, missing values where the average has them" \
        || fail "report --level $k: $(cat "$W/rep$k.txt")"
done
expect_exit 2 "has 2 coarser levels" "$REP" "$W/ds" -q --level 3
# Refused up front: more levels than halving allows, fewer slices than
# --nodes.
expect_exit 2 "level 7 would be 1x1x1 again" "$ENC" --axes xyz -q --dims $D --levels 7 -o "$W/x" "$W"/in/*.f32
expect_exit 2 "has fewer . slices than --nodes 16" "$ENC" --axes xyz -q --dims $D --nodes 16 --levels 1 -o "$W/x" "$W"/in/*.f32
# A memory limit that holds level 0 but not level 1 beside it (encoded
# in this process after level 0): refused up front, naming the limit that
# works, which works.
expect_exit 2 "too small for --levels 1: the levels are encoded after level 0 in this process" \
    "$ENC" --axes xyz -q --dims $D --levels 1 --mem-limit 20M -o "$W/x" "$W"/in/*.f32
need=$(sed -n 's/.*give --mem-limit \([0-9]*K\) or more.*/\1/p' "$W/err.txt")
[ ! -e "$W/x" ] && [ ! -e "$W/x.partial" ] && ok "nothing written when refused" || fail "refused run wrote output"
if [ -n "${ASAN_OPTIONS:-}" ]; then
    # AddressSanitizer's shadow memory is in this process's resident size,
    # which the level's process must fit beside: not the plan's estimate.
    echo "note: the stated minimum is not tried under AddressSanitizer"
else
    "$ENC" --axes xyz -q --dims $D --levels 1 --mem-limit "$need" -o "$W/x" "$W"/in/*.f32 > /dev/null 2> "$W/need.err" \
        && ok "the stated minimum, --mem-limit $need, encodes every level" || fail "--mem-limit $need: $(cat "$W/need.err")"
fi
# A run that stops before level 2 resumes: level 0 is kept (its shard is
# not rewritten), and the bytes equal the uninterrupted run's.
TVPAL_ENCODE_FAULT_LEVEL=2 "$ENC" --axes xyz -q --dims $D --window 4 --levels 2 -o "$W/r" "$W"/in/*.f32 > /dev/null 2> "$W/r.err"
[ $? -eq 1 ] && [ -e "$W/r.partial/levels.job" ] && [ -e "$W/r.partial/level-1/manifest.txt" ] && [ ! -e "$W/r" ] \
    && ok "stopped before level 2: partial output with level 0 and 1, nothing final" || fail "fault: $(cat "$W/r.err")"
touch -d '2000-01-01' "$W/r.partial/node-0/axis-z.tvps"
m0=$(stat -c %Y "$W/r.partial/node-0/axis-z.tvps")
"$ENC" --axes xyz -q --dims $D --window 4 --levels 2 -o "$W/r" "$W"/in/*.f32 > /dev/null || fail "resume"
[ "$(stat -c %Y "$W/r/node-0/axis-z.tvps")" = "$m0" ] \
    && ok "resumed: level 0 kept" || fail "resumed: level 0 rewritten"
same=1
for f in $(cd "$W/ds" && find . -name '*.tvps'); do cmp -s "$W/ds/$f" "$W/r/$f" || same=0; done
[ $same = 1 ] && ok "resumed dataset byte-identical to the uninterrupted one" || fail "resumed bytes differ"
# Resumed with another --levels (1: fewer than the earlier run asked for):
# level 0 kept, the manifests name the levels on disk, and tvpal-info
# --verify checks every level the manifest names (it said ok for a
# manifest naming a level that was not there).
rm -rf "$W/r1" "$W/r1.partial"
TVPAL_ENCODE_FAULT_LEVEL=2 "$ENC" --axes xyz -q --dims $D --window 4 --levels 2 -o "$W/r1" "$W"/in/*.f32 > /dev/null 2>&1
"$ENC" --axes xyz --dims $D --window 4 --levels 1 -o "$W/r1" "$W"/in/*.f32 > /dev/null 2> "$W/r1.err" \
    && grep -q "resuming with --levels 1 (the earlier run asked for 2): level 0 kept" "$W/r1.err" \
    && [ "$(grep -c '^levels = 1$' "$W/r1/manifest.txt" "$W/r1/node-0/manifest.txt" | grep -c ':1$')" = 2 ] \
    && [ ! -e "$W/r1/level-2" ] && "$INFO" "$W/r1" --verify > /dev/null \
    && ok "resumed with --levels 1 after 2: manifests name 1 level, it verifies" \
    || fail "resumed with other --levels: $(cat "$W/r1.err")"
sed 's/^levels = 1$/levels = 2/' "$W/r1/manifest.txt" > "$W/m.txt" && cp "$W/m.txt" "$W/r1/manifest.txt"
"$INFO" "$W/r1" --verify > "$W/v.txt" 2>&1
[ $? -eq 1 ] && grep -q "CORRUPT .*level-2: level 2 of the 2 the manifest names" "$W/v.txt" \
    && ok "verify: a level the manifest names but the disk lacks is a problem" \
    || fail "verify with a missing level: $(cat "$W/v.txt")"
PLAY=$TVPAL_BUILDDIR/player/app/tvpal-play
if [ ! -x "$PLAY" ]; then
    echo "built without OSMesa/libpng: player part skipped"
    finish
fi
# The level chosen: the rule, computed here from the view's geometry.
for case in "40x40 1" "80x80 1" "40x40 0.5" "20x20 1" "64x48 2" "160x160 0.3" "40x40 0.2"; do
    set -- $case
    size=$1 zoom=$2
    want=$($PY -c "
import math
d = [41, 36, 30]; m = max(d); half = [n / m for n in d]
r = math.sqrt(sum(h * h for h in half))
W, H = map(int, '$size'.split('x')); a = W / H; z = $zoom
sx = r / z * (a if a > 1 else 1); sy = r / z / (a if a < 1 else 1)
pix = min(2 * sx / W, 2 * sy / H)
vox = (math.prod(2 * h / n for h, n in zip(half, d))) ** (1 / 3)
ppv, k = vox / pix, 0
while k < 2 and ppv * 2 ** k < 0.5: k += 1
print(k)")
    "$PLAY" "$W/ds" --headless -q --renderer cpu --size $size --zoom $zoom --steps 0:1 --csv "$W/l.csv" > /dev/null 2>&1 || fail "play $case"
    got=$(awk -F, 'NR == 1 { for (i = 1; i <= NF; i++) if ($i == "level") c = i } NR == 2 { print $c }' "$W/l.csv")
    [ "$got" = "$want" ] && ok "size $size zoom $zoom: level $got" || fail "size $size zoom $zoom: level $got, rule says $want"
done
"$PLAY" "$W/ds" --headless -q --renderer cpu --size 80x80 --level 1 --steps 0:1 --csv "$W/f.csv" > /dev/null 2>&1 \
    && [ "$(awk -F, 'NR == 1 { for (i = 1; i <= NF; i++) if ($i == "level") c = i } NR > 1 { print $c }' "$W/f.csv" | sort -u)" = 1 ] \
    && ok "--level 1 forces level 1" || fail "--level 1: $(cat "$W/f.csv")"
expect_exit 2 "^tvpal-play: --level 3: expected 0..2" "$PLAY" "$W/ds" --headless -q --level 3
expect_exit 2 '^tvpal-play: --level "9": expected 0..8' "$PLAY" "$W/ds" --headless -q --level 9
# Opacity kept: mean brightness of levels 1 and 2 within 5% of level 0's.
for k in 0 1 2; do
    "$PLAY" "$W/ds" --headless -q --renderer cpu --size 96x96 --level $k --steps 2:2 -o "$W/img$k" > /dev/null 2>&1 || fail "play level $k"
done
$PY - "$W" <<'PY' > "$W/bright.txt" || fail "brightness"
import os, sys
sys.dont_write_bytecode = True
sys.path.insert(0, os.path.join(os.environ["TVPAL_SRCDIR"], "tests"))
from pngdiff import load
m = []
for k in range(3):
    w, h, b, A = load("%s/img%d/t0002.png" % (sys.argv[1], k))
    m.append(sum(sum(r) for r in A) / (w * h * b))
print(" ".join("%.2f" % x for x in m))
PY
[ "$(wc -w < "$W/bright.txt")" -eq 3 ] && awk '{ exit !($1 > 0 && ($2 - $1) / $1 < 0.05 && ($1 - $2) / $1 < 0.05 && ($3 - $1) / $1 < 0.05 && ($1 - $3) / $1 < 0.05) }' "$W/bright.txt" \
    && ok "mean brightness of levels 0, 1, 2: $(cat "$W/bright.txt")" || fail "brightness: $(cat "$W/bright.txt")"
# Streaming reads only the level drawn.
b0=$("$PLAY" "$W/ds" --headless -q --renderer cpu --size 64x64 --level 0 | sed 's/.*bytes_read=\([0-9]*\).*/\1/')
b1=$("$PLAY" "$W/ds" --headless -q --renderer cpu --size 64x64 --level 1 | sed 's/.*bytes_read=\([0-9]*\).*/\1/')
awk -v a="$b0" -v b="$b1" 'BEGIN { exit !(b > 0 && b * 2 < a) }' \
    && ok "streamed: level 1 reads $b1 bytes, level 0 $b0" || fail "bytes read: level 0 $b0, level 1 $b1"
finish
