#!/bin/sh
# play-exact: early termination's bound through the whole player.  PNG
# frames drawn by the cpu renderer with the default early termination
# (a pixel stops at transmittance 1/272) and with --exact differ by at most
# one 8-bit level in every pixel, for views along and between the axes
# (eight, in three sweeps), dense and opaque transfer functions, opacity
# scaled up to saturate pixels, K = 1..4, 1 and 2 threads; on the
# saturated cases the frames really differ somewhere (termination is on);
# and --exact draws the same bits for 1 and 2 threads.
. "$(dirname "$0")/lib.sh"
PLAY=$TVPAL_BUILDDIR/player/app/tvpal-play
[ -x "$PLAY" ] || { echo "built without OSMesa/libpng: skipped"; exit 77; }
PY=$(command -v python3) || { echo "no python3 (pngdiff): skipped"; exit 77; }
D=40x36x32
"$GEN" --field turbulence --dims $D --steps 3 -o "$W/in" || fail gen
"$ENC" -q --dims $D --window 2 -o "$W/ds" "$W"/in/*.f32 > /dev/null || fail encode
TFW=$TVPAL_SRCDIR/samples/tf/warm.tf
TFB=$TVPAL_SRCDIR/samples/tf/band.tf
TFC=$TVPAL_SRCDIR/samples/tf/cool-to-warm.json
# Views as sweeps (--spin turns the view about the screen's y each frame,
# a frame per step): from 0,0 along +z, x and -z; from 90,0 along +y and
# -y; from 20,30 three views between the axes.  Each run draws a sweep.
SWEEPS="0,0/90/0:2 90,0/180/0:1 20,30/120/0:2"
n=0 frames=0
: > "$W/pairs"
for sw in $SWEEPS; do
    view=$(sweep_opts "$sw")
    for case in "" "--opacity 8" "--tf $TFW --opacity 30" "--tf $TFB --opacity 4" \
        "--tf $TFC --opacity 100" "--zoom 4 --opacity 20"; do
        n=$((n + 1)) frames=$((frames + $(echo "$sw" | awk -F/ '{ split($3, s, ":"); print s[2] - s[1] + 1 }')))
        th=$((1 + n % 2))   # 1 and 2 threads, alternately
        for m in bounded exact; do
            x=""; [ $m = exact ] && x=--exact
            OMP_NUM_THREADS=$th "$PLAY" "$W/ds" --headless -q --renderer cpu \
                --size 96x80 $view $case $x -o "$W/$m-$n" > /dev/null 2>&1 \
                || fail "$view $case $x: play failed"
        done
        for f in "$W/exact-$n"/*.png; do
            echo "$f $W/bounded-$n/$(basename "$f") sweep $sw $case, $th threads" >> "$W/pairs"
        done
    done
done
# One start of pngdiff.py for every pair; a line per pair, in order.
$PY "$TVPAL_SRCDIR/tests/pngdiff.py" $(cut -d' ' -f1,2 "$W/pairs") > "$W/diffs" || fail "pngdiff"
[ "$(wc -l < "$W/diffs")" -eq "$(wc -l < "$W/pairs")" ] && [ "$(wc -l < "$W/pairs")" -eq $frames ] \
    || fail "$(wc -l < "$W/diffs") comparisons of $(wc -l < "$W/pairs") pairs; $n runs should draw $frames frames"
paste -d' ' "$W/diffs" "$W/pairs" | awk '{ split($1, a, "="); if (a[2] > 1) { print "FAIL: " $0 > "/dev/stderr"; bad++ }
                                       else if (a[2] > 0) differ++ }
                                 END { print differ + 0, bad + 0 }' > "$W/counts"
read differ bad < "$W/counts"
[ "$bad" -eq 0 ] && ok "$n cases, $frames frames: every pixel within one 8-bit level of --exact" \
    || fail "$bad frames more than one level from --exact"
[ "$differ" -gt 0 ] && ok "$differ frames differ from --exact (early termination on)" \
    || fail "no frame differs from --exact: early termination is off"
# The saturated case alone must differ: opacity 100 stops most pixels early.
OMP_NUM_THREADS=2 "$PLAY" "$W/ds" --headless -q --renderer cpu --size 96x80 \
    --opacity 100 -o "$W/sat" > /dev/null 2>&1 || fail "play sat"
OMP_NUM_THREADS=2 "$PLAY" "$W/ds" --headless -q --renderer cpu --size 96x80 \
    --opacity 100 --exact -o "$W/sat-x" > /dev/null 2>&1 || fail "play sat exact"
r=$($PY "$TVPAL_SRCDIR/tests/pngdiff.py" "$W/sat/t0001.png" "$W/sat-x/t0001.png")
echo "$r" | grep -q "^max=1 " && ok "opacity 100: $r" || fail "opacity 100: $r (expected max=1)"
# --exact: thread count changes no bit.
OMP_NUM_THREADS=1 "$PLAY" "$W/ds" --headless -q --renderer cpu --size 96x80 \
    --opacity 100 --exact -o "$W/sat-x1" > /dev/null 2>&1 || fail "play exact 1 thread"
cmp -s "$W/sat-x/t0001.png" "$W/sat-x1/t0001.png" && ok "--exact: 1 and 2 threads identical" \
    || fail "--exact: 1 and 2 threads differ"
finish
