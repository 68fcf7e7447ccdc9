#!/bin/sh
# play-tf: transfer functions as ParaView users know them, through
# tvpal-play: a preset with UseLogScale 1 draws other frames than the same
# preset linear, ColorSpace Diverging other frames than RGB, a text TF with
# "colorspace rgb" the frames it draws without the line; --tf-range MIN:MAX
# on the data range draws what the default does and another range other
# frames; --tf-range preset keeps a preset's values (the frames of
# --tf-range on its own domain); a log TF on a range reaching 0 (pointing
# to --tf-range when it is the data's) and a normalized text TF under
# --tf-range preset are refused (exit 2, the file and the reason), and the
# log TF plays on that data with --tf-range; --steps T writes exactly the
# one frame tT.
. "$(dirname "$0")/lib.sh"
PLAY=$TVPAL_BUILDDIR/player/app/tvpal-play
[ -x "$PLAY" ] || { echo "built without OSMesa/libpng: skipped"; exit 77; }
D=24x20x16
"$GEN" --field blobs --dims $D --steps 3 -o "$W/in" > /dev/null || fail gen
"$ENC" -q --dims $D -o "$W/ds" "$W"/in/*.f32 > /dev/null || fail encode
lo=$(sed -n 's/^value_min = //p' "$W/ds/manifest.txt")
hi=$(sed -n 's/^value_max = //p' "$W/ds/manifest.txt")
ge "$lo" 0 && ! ge 0 "$lo" || fail "blobs should be positive: $lo..$hi"

# preset NAME SPACE LOG X0 X1 X2: a three-point preset (cool, white, warm)
# with an opacity ramp.
preset() {
    cat > "$W/$1.json" <<EOF
[{"Name": "$1", "ColorSpace": "$2", "UseLogScale": $3,
  "RGBPoints": [$4, 0.23, 0.30, 0.75, $5, 0.87, 0.87, 0.87,
                $6, 0.71, 0.02, 0.15],
  "Points": [$4, 0.0, 0.5, 0.0, $6, 0.8, 0.5, 0.0]}]
EOF
}
preset lin RGB 0 0.001 0.03 1
preset log RGB 1 0.001 0.03 1
preset div Diverging 0 0 0.5 2
preset rgb RGB 0 0 0.5 2
printf 'domain normalized\n0 0 0 1 0\n0.5 0 1 0 0.2\n1 1 0 0 0.6\n' > "$W/a.tf"
{ echo "colorspace rgb"; cat "$W/a.tf"; } > "$W/a-rgb.tf"

# play NAME OPTS...: step 1 into $W/NAME (exactly one frame, t0001.png).
play() {
    local name=$1
    shift
    "$PLAY" "$W/ds" --headless -q --size 48x40 --steps 1 -o "$W/$name" "$@" \
        > "$W/$name.txt" 2>&1 || { fail "$name: $(cat "$W/$name.txt")"; return; }
    [ "$(ls "$W/$name"/*.png | xargs -n 1 basename)" = t0001.png ] \
        || fail "$name: --steps 1 wrote $(ls "$W/$name" | tr '\n' ' ')"
}
# same A B / differ A B: the frames of two runs.
same() { cmp -s "$W/$1/t0001.png" "$W/$2/t0001.png" && ok "$1 = $2" || fail "$1 differs from $2"; }
differ() { cmp -s "$W/$1/t0001.png" "$W/$2/t0001.png" && fail "$1 = $2" || ok "$1 differs from $2"; }

play lin --tf "$W/lin.json"
play log --tf "$W/log.json"
differ log lin
play div --tf "$W/div.json"
play rgb --tf "$W/rgb.json"
differ div rgb
play a --tf "$W/a.tf"
play a-rgb --tf "$W/a-rgb.tf"
same a a-rgb
# --tf-range: the data range itself is the default; 20..50-like ranges
# place the TF elsewhere; preset keeps the values (0, 0.5, 2 exactly as
# 0:2 places them).
play range-data --tf "$W/rgb.json" --tf-range "$lo:$hi"
same range-data rgb
play range-data2 --tf "$W/rgb.json" --tf-range data
same range-data2 rgb
play range-02 --tf "$W/rgb.json" --tf-range 0:2
differ range-02 rgb
play keep --tf "$W/rgb.json" --tf-range preset
same keep range-02
play range-a --tf "$W/a.tf" --tf-range 0.2:0.5
differ range-a a
expect_exit 2 "^tvpal-play: .*/log\.json: UseLogScale: the value range -1\.\.2 to rescale onto includes values <= 0; a log scale needs a range above 0" \
    "$PLAY" "$W/ds" --headless -q --size 16x16 --steps 0 -o "$W/no" --tf "$W/log.json" --tf-range -1:2
# Data reaching 0 (here all 0): a log preset asks for --tf-range, and plays
# with one.
"$GEN" --field constant --value 0 --dims 8x8x8 --steps 1 -o "$W/in0" > /dev/null || fail gen0
"$ENC" -q --dims 8x8x8 -o "$W/ds0" "$W"/in0/*.f32 > /dev/null || fail encode0
expect_exit 2 "^tvpal-play: .*/log\.json: UseLogScale: the value range 0\.\.0 to rescale onto includes values <= 0; a log scale needs a range above 0 \(give one with --tf-range MIN:MAX, MIN > 0\)$" \
    "$PLAY" "$W/ds0" --headless -q --size 16x16 -o "$W/no" --tf "$W/log.json"
"$PLAY" "$W/ds0" --headless -q --size 16x16 -o "$W/zero" --tf "$W/log.json" \
    --tf-range 0.001:1 > "$W/zero.txt" 2>&1 && ok "log preset on 0 with --tf-range" \
    || fail "log preset on 0 with --tf-range: $(cat "$W/zero.txt")"
expect_exit 2 "^tvpal-play: .*/a\.tf: domain normalized: no value range to map onto" \
    "$PLAY" "$W/ds" --headless -q --size 16x16 --steps 0 -o "$W/no" --tf "$W/a.tf" --tf-range preset
finish
