#!/bin/sh
# play-exact: early termination's bound through the whole player.  PNG
# frames drawn by the cpu renderer with the default early termination
# (a pixel stops at transmittance 1/272) and with --exact differ by at most
# one 8-bit level in every pixel, for views along and between the axes,
# dense and opaque transfer functions, opacity scaled up to saturate
# pixels, K = 1..4, 1 and 2 threads; on the saturated cases the frames
# really differ somewhere (termination is on); and --exact draws the same
# bits for 1 and 2 threads.
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
n=0 differ=0
for view in 0,0 20,30 90,0 0,90 -35,125 170,-60; do
    for case in "" "--opacity 8" "--tf $TFW --opacity 30" "--tf $TFB --opacity 4" \
        "--tf $TFC --opacity 100" "--zoom 4 --opacity 20"; do
        n=$((n + 1))
        th=$((1 + n % 2))   # 1 and 2 threads, alternately
        {
            for m in bounded exact; do
                x=""; [ $m = exact ] && x=--exact
                OMP_NUM_THREADS=$th "$PLAY" "$W/ds" --headless -q --renderer cpu \
                    --size 96x80 --rotate "$view" $case $x -o "$W/$m-$n" > /dev/null 2>&1 \
                    || fail "$view $case $x: play failed"
            done
            for f in "$W/exact-$n"/*.png; do
                b=$(basename "$f")
                r=$($PY "$TVPAL_SRCDIR/tests/pngdiff.py" "$f" "$W/bounded-$n/$b")
                mx=$(echo "$r" | sed 's/max=\([0-9]*\).*/\1/')
                [ "$mx" -le 1 ] || fail "view $view $case, $th threads, $b: $r against --exact"
                [ "$mx" -eq 0 ] || differ=$((differ + 1))
            done
        }
    done
done
ok "$n cases x 3 frames: every pixel within one 8-bit level of --exact"
[ $differ -gt 0 ] && ok "$differ frames differ from --exact (early termination on)" \
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
