#!/bin/sh
# play-thin: volumes that are thin along one axis, or whose spacing is
# extreme, in oblique views.
#  - A volume flat in z (96x96x4 voxels, and 32^3 voxels of spacing
#    1,1,1/16: a few model levels under a wide domain) in the iso view is
#    drawn from its z slices (the timing CSV's axis column), which the
#    reference renderer agrees with (PSNR floor 35 dB, which a line of
#    some 15 pixels along the outline sets; the cpu renderer at
#    4 pixels a texel there, so that the sheet's outline is as sharp); the
#    sheet is continuous: the mean |Laplacian| of the cpu frame's luminance
#    inside the sheet is at most half that of the same frame from the x
#    slices (--slice-axis x), which break into stripes at their edges.
#  - --slice-axis forces an axis (the CSV says which), and refuses a word
#    it does not know (exit 2).
#  - Spacings the encoder takes (1e-9 beside 1, 1e6 beside 1) draw every
#    named view and the default rotation, cpu and gl, with no "degenerate
#    view".
. "$(dirname "$0")/lib.sh"
PLAY=$TVPAL_BUILDDIR/player/app/tvpal-play
[ -x "$PLAY" ] || { echo "built without OSMesa/libpng: skipped"; exit 77; }
"$PY" -c "import numpy" 2> /dev/null || { echo "no numpy (python3-numpy): skipped"; exit 77; }
command -v ffmpeg > /dev/null || { echo "no ffmpeg (reads the PNG frames here; Debian ffmpeg): skipped"; exit 77; }
mkdir -p "$W/flat" "$W/aniso" || exit 99
# A smooth field with a blob in it, the same in every z of the slab.
"$PY" - "$W" <<'PY' || fail "writing the volumes"
import sys, numpy as np
w = sys.argv[1]
def series(nx, ny, nz, out):
    z, y, x = np.meshgrid(np.arange(nz), np.arange(ny), np.arange(nx), indexing="ij")
    for t in range(2):
        v = np.exp(-((x / nx - 0.4 - 0.1 * t) ** 2 + (y / ny - 0.55) ** 2) / 0.03) + 0.2
        v.astype("<f4").tofile("%s/t%d.f32" % (out, t))
series(96, 96, 4, w + "/flat")
series(32, 32, 32, w + "/aniso")
PY
"$ENC" -q --dims 96x96x4 -o "$W/flat.ds" "$W"/flat/*.f32 > /dev/null || fail "encode flat"
"$ENC" -q --dims 32x32x32 --spacing 1,1,0.0625 -o "$W/aniso.ds" "$W"/aniso/*.f32 > /dev/null ||
    fail "encode aniso"
cat > "$W/sheet.tf" <<'TF'
domain normalized
0.00  0.1 0.2 0.8 0.5
1.00  1.0 0.8 0.2 0.9
TF
S=160
# render DS NAME OPTIONS...: step 0 as $W/NAME.rgb; prints its CSV row's axis.
render() {
    local ds=$1 name=$2
    shift 2
    frame_rgb "$ds" "$name" $S "$W/sheet.tf" "$@" || return 1
    sed -n 2p "$W/$name.csv" | cut -d, -f2
}
for ds in flat aniso; do
    a=$(render $ds.ds $ds-auto --view iso --renderer cpu)
    [ "$a" = z ] && ok "$ds: the iso view draws the z slices" || fail "$ds: the iso view draws axis '$a', z expected"
    render $ds.ds $ds-ref --view iso --renderer ref > /dev/null
    render $ds.ds $ds-auto4 --view iso --renderer cpu --cpu-scale 4 > /dev/null
    a=$(render $ds.ds $ds-x --view iso --renderer cpu --slice-axis x)
    [ "$a" = x ] && ok "$ds: --slice-axis x draws the x slices" || fail "$ds: --slice-axis x drew '$a'"
    "$PY" - "$W" $ds $S <<'PY' > "$W/$ds.txt" 2>&1 && rc=0 || rc=$?
import sys, numpy as np
w, ds, S = sys.argv[1], sys.argv[2], int(sys.argv[3])
img = lambda n: np.fromfile("%s/%s-%s.rgb" % (w, ds, n), np.uint8).reshape(S, S, 3).astype(float)
auto, ref, xs = img("auto"), img("ref"), img("x")
mse = ((img("auto4") - ref) ** 2).mean()
psnr = 99.0 if mse == 0 else 10 * np.log10(255.0 ** 2 / mse)
def rough(im, inside):
    l = im.mean(axis=2)
    lap = np.abs(4 * l[1:-1, 1:-1] - l[:-2, 1:-1] - l[2:, 1:-1] - l[1:-1, :-2] - l[1:-1, 2:])
    return lap[inside].mean()
# Inside the sheet: pixels whose 5x5 neighbourhood is covered in both
# frames (away from the sheet's outline, which both draw).
cov = (auto.sum(axis=2) > 0) & (xs.sum(axis=2) > 0)
inner = cov.copy()
for dy in range(-2, 3):
    for dx in range(-2, 3):
        inner &= np.roll(np.roll(cov, dy, 0), dx, 1)
inner = inner[1:-1, 1:-1]
ra, rx = rough(auto, inner), rough(xs, inner)
print("psnr %.2f rough_auto %.3f rough_x %.3f pixels %d" % (psnr, ra, rx, inner.sum()))
sys.exit(0 if psnr >= 35 and inner.sum() > 500 and ra <= 0.5 * rx else 1)
PY
    [ $rc = 0 ] && ok "$ds: $(cat "$W/$ds.txt") (PSNR floor 35 dB against ref; auto at most half the x slices' roughness)" ||
        fail "$ds: $(cat "$W/$ds.txt")"
done
"$PLAY" "$W/flat.ds" --headless -q --steps 0:0 --slice-axis w -o "$W/bad" > /dev/null 2>&1
rc=$?
[ $rc = 2 ] && ok "--slice-axis w refused (exit 2)" || fail "--slice-axis w: exit $rc"
# Extreme spacings: every named view and the default rotation draw.
renderers=cpu
"$PLAY" --version | grep -q "gl: yes" && renderers="cpu gl"
for sp in 1e-9,1,1 1,1,1e-9 1e9,1,1 1,1,1e6; do
    rm -rf "$W/sp.ds"
    "$ENC" -q --dims 32x32x32 --spacing $sp -o "$W/sp.ds" "$W"/aniso/*.f32 > /dev/null || { fail "encode --spacing $sp"; continue; }
    bad=
    for r in $renderers; do
        for v in "" "--view iso" "--view +x" "--view -x" "--view +y" "--view -y" "--view +z" "--view -z"; do
            # shellcheck disable=SC2086
            "$PLAY" "$W/sp.ds" --headless -q --size 64x64 --steps 0:0 --renderer $r $v -o "$W/sp" \
                > /dev/null 2> "$W/sp.err" || bad="$bad [$r $v: $(tail -n 1 "$W/sp.err")]"
        done
    done
    [ -z "$bad" ] && ok "--spacing $sp: every view draws ($renderers)" || fail "--spacing $sp:$bad"
done
finish
