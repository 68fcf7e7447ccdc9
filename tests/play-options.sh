#!/bin/sh
# play-options: every numeric option of tvpal-play is bounded: values out of
# range, NaN, infinite, overflowing (wrapping past 2^32), signed, empty or
# with trailing text are refused with the option, the value and the range
# (exit 2), never taken wrapped nor crashing the player; the bounds
# themselves are accepted.  --tf-range refuses what is not MIN:MAX with
# MIN < MAX, data or preset.
. "$(dirname "$0")/lib.sh"
PLAY=$TVPAL_BUILDDIR/player/app/tvpal-play
[ -x "$PLAY" ] || { echo "built without OSMesa/libpng: skipped"; exit 77; }
D=12x10x8
"$GEN" --field blobs --dims $D --steps 3 -o "$W/in" || fail gen
"$ENC" -q --dims $D -o "$W/ds" "$W"/in/*.f32 > /dev/null || fail encode
# re TEXT: TEXT as a literal grep -E pattern.
re() { printf '%s' "$1" | sed 's/[][\.*^$+?(){}|]/\\&/g'; }
# refuse OPTION "EXPECTED" VALUE...: each VALUE is refused with EXPECTED.
refuse() {
    local opt=$1 want=$2 v
    shift 2
    for v in "$@"; do
        expect_exit 2 "^tvpal-play: --$opt \"$(re "$v")\": expected $want$" \
            "$PLAY" "$W/ds" --headless -q --size 16x16 "--$opt" "$v"
    done
}
refuse zoom "a number in 0\.001\.\.1000" 1e-20 0 -1 0.0009 1001 nan inf -inf 1e999 "" 1x
refuse rotate "AX,AY in degrees, each -360\.\.360" 1e308,0 0,1e308 nan,0 0,inf \
    361,0 0,-361 1 1, ,1 1,2,3 "1,2 "
refuse spin "degrees in -360\.\.360" 1e308 -1e308 nan inf 360.5 ""
refuse opacity "a number in 0\.\.1000" -0.1 1001 nan inf
refuse scale-z "a factor in 0\.001\.\.1000" 0 1e-300 1001 nan inf
refuse size "WxH, each 1\.\.16384" 4294967297x1 1x4294967297 18446744073709551617x1 \
    0x1 16385x1 -1x1 +1x1 1x x1 1x1x 1 "1x1 " " 1x1" 1X1
refuse prefetch "0\.\.64" 65 -1 4294967296 1.5 ""
refuse mem "MiB in 1\.\.16777216" 0 16777217 4294967297 -1
refuse repeat "1\.\.100000" 0 100001 4294967297
refuse jumps "1\.\.1000000" 0 1000001 4294967297
refuse cpu-scale "auto or 1\.\.8" 0 9 4294967297 -1
refuse fb "8, 16 or 32" 4294967304 24 -8
refuse tf-range "MIN:MAX \(finite numbers, MIN < MAX\), data or preset" \
    5:5 5:1 1 1: :1 a:b nan:1 0:nan -inf:1 0:inf 1e999:2e999 "0:1 " Preset ""
# --steps is checked against the dataset (3 timesteps: 0..2).
for v in 4294967296:0 0:4294967296 4294967298:1 -1:2 +0:1 1: :1 1:2: "0:1 " 0:3 \
    3 -1 +1 4294967296 "" " 1" x; do
    expect_exit 2 "^tvpal-play: --steps \"$(re "$v")\": expected T or A:B within 0\.\.2$" \
        "$PLAY" "$W/ds" --headless -q --steps "$v"
done
# The bounds are accepted and draw (no crash at the extremes).
for opts in "--zoom 0.001" "--zoom 1000" "--rotate -360,360" "--rotate 90,0" \
    "--spin 360 --steps 2:0" "--spin -360" "--opacity 0" "--opacity 1000" \
    "--scale-z 0.001" "--scale-z 1000" "--size 1x1" "--prefetch 64" \
    "--repeat 2 --jumps 1000000" "--mem 16777216"; do
    "$PLAY" "$W/ds" --headless -q --size 24x20 $opts -o "$W/ok" > "$W/ok.txt" 2>&1 \
        && grep -q "^fps=.* frames=3 " "$W/ok.txt" && ok "accepted: $opts" \
        || fail "$opts: $(cat "$W/ok.txt")"
done
finish
