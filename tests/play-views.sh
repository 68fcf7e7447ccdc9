#!/bin/sh
# play-views: --view and --up give the axis-aligned images of an asymmetric
# object, a Gaussian blob near the corner (high x, low y, high z) of a
# 24x20x16 volume, with the cpu, gl and reference renderers: the blob's
# centroid lies within 0.25 pixel of where the view's definition puts it
# (+x looks along +x with z up: screen right is -y; -x: right is +y; +z
# with y up: right is -x; +z --up x: right is +y, up +x; -z: right +x, up
# +y; +y: right +x, up z); -x is the mirror image of +x and +z --up x the
# +z image turned by 90 degrees, within one 8-bit level; -z is --rotate
# 0,0 byte for byte (the same matrix).  --view with --rotate, or --up
# along the view, is refused (exit 2).
. "$(dirname "$0")/lib.sh"
PLAY=$TVPAL_BUILDDIR/player/app/tvpal-play
[ -x "$PLAY" ] || { echo "built without OSMesa/libpng: skipped"; exit 77; }
"$PY" -c "import numpy" 2> /dev/null || { echo "no numpy (python3-numpy): skipped"; exit 77; }
command -v ffmpeg > /dev/null || { echo "no ffmpeg (reads the PNG frames here; Debian ffmpeg): skipped"; exit 77; }
D=24x20x16
mkdir -p "$W/in" || exit 99
"$PY" - "$W/in" <<'PY' || fail "writing the volume"
import sys, numpy as np
nx, ny, nz = 24, 20, 16
z, y, x = np.meshgrid(np.arange(nz), np.arange(ny), np.arange(nx), indexing="ij")
blob = np.exp(-((x - 17) ** 2 + (y - 5) ** 2 + (z - 11) ** 2) / (2 * 1.5 ** 2))
for t in range(3):   # x fastest: index x + nx (y + ny z)
    blob.astype("<f4").tofile("%s/t%d.f32" % (sys.argv[1], t))
PY
"$ENC" -q --dims $D -o "$W/ds" "$W"/in/*.f32 > /dev/null || fail encode
cat > "$W/blob.tf" <<'TF'
domain normalized
0.00  0 0 0 0
0.10  0.2 0.4 1.0 0.05
1.00  1.0 0.8 0.2 0.6
TF
S=96
# render NAME RENDERER OPTIONS...: step 0 as $W/NAME.rgb (raw RGB, top row first).
render() {
    local name=$1 r=$2
    shift 2
    frame_rgb ds "$name" $S "$W/blob.tf" --renderer $r "$@"
}
for r in cpu gl ref; do
    if [ $r = gl ] && ! "$PLAY" --version | grep -q "gl: yes"; then
        echo "built without OSMesa: the gl renderer is not checked"
        continue
    fi
    render px-$r $r --view +x
    render nx-$r $r --view -x
    render py-$r $r --view +y
    render pz-$r $r --view +z
    render pzx-$r $r --view +z --up x
    render nz-$r $r --view -z
    render r00-$r $r --rotate 0,0
    cmp -s "$W/nz-$r/t0000.png" "$W/r00-$r/t0000.png" \
        && ok "$r: --view -z = --rotate 0,0 byte for byte" || fail "$r: --view -z differs from --rotate 0,0"
    "$PY" - "$W" $r $S <<'PY' > "$W/check.txt" 2>&1 && rc=0 || rc=$?
import sys, numpy as np
w, r, S = sys.argv[1], sys.argv[2], int(sys.argv[3])
img = lambda n: np.fromfile("%s/%s-%s.rgb" % (w, n, r), np.uint8).reshape(S, S, 3).astype(int)
# Where the view's definition puts the blob: object coordinates as in
# tvpal_view.h (the box centred, the longest side spanning [-1, 1]), the
# screen's right and up axes of each view, the bounding sphere fitting the
# image.  Returns (column, row from the top) of the blob's centre.
dims = np.array([24.0, 20.0, 16.0]); half = dims / dims.max()
p = ((np.array([17.0, 5.0, 11.0]) + 0.5) / dims * 2 - 1) * half
rad = np.sqrt((half ** 2).sum())
E = np.eye(3)
axes = {"px": (-E[1], E[2]), "nx": (E[1], E[2]), "py": (E[0], E[2]),
        "pz": (-E[0], E[1]), "pzx": (E[1], E[0]), "nz": (E[0], E[1])}
bad = 0
for n, (right, up) in axes.items():
    ex, ey = p @ right, p @ up
    want = ((ex / rad + 1) * S / 2, S - (ey / rad + 1) * S / 2)
    a = img(n).sum(axis=2).astype(float)
    if a.sum() < 1000:
        print("%s: the blob is not in the image" % n); bad += 1; continue
    yy, xx = np.mgrid[0:S, 0:S] + 0.5
    got = ((a * xx).sum() / a.sum(), (a * yy).sum() / a.sum())
    d = np.hypot(got[0] - want[0], got[1] - want[1])
    print("%s: centroid (%.2f, %.2f), expected (%.2f, %.2f): %.2f px" % ((n,) + got + want + (d,)))
    bad += d > 0.25
# -x mirrors +x left to right; +z --up x is +z turned: upx[r][c] = upy[S-1-c][r].
m = np.abs(img("nx") - img("px")[:, ::-1]).max()
t = np.abs(img("pzx") - np.transpose(img("pz")[::-1, :], (1, 0, 2))).max()
print("mirror -x/+x: %d levels; +z --up x vs +z turned: %d levels" % (m, t))
sys.exit(1 if bad or m > 1 or t > 1 else 0)
PY
    sed "s/^/    $r: /" "$W/check.txt"
    [ $rc -eq 0 ] && ok "$r: every named view puts the blob where its definition says" \
        || fail "$r: the named views' images (above)"
done
expect_exit 2 "--view and --rotate: choose one" "$PLAY" "$W/ds" --headless -q --view +x --rotate 0,0
expect_exit 2 "--up x: the view -x looks along x" "$PLAY" "$W/ds" --headless -q --view -x --up x
expect_exit 2 "--view \"x\": expected \+x, -x, \+y, -y, \+z, -z or iso" "$PLAY" "$W/ds" --headless -q --view x
expect_exit 2 "--up \"w\": expected x, y or z" "$PLAY" "$W/ds" --headless -q --view iso --up w
"$PLAY" "$W/ds" --headless -q --size 32x32 --view iso --up z --spin 10 -o "$W/iso" > "$W/iso.txt" 2>&1 \
    && grep -q "frames=3 " "$W/iso.txt" && ok "--view iso --up z --spin 10 draws" \
    || fail "iso: $(cat "$W/iso.txt")"
finish
