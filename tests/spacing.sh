#!/bin/sh
# spacing: a sphere sampled on a grid with dz = 4 dx (48x48x12 voxels,
# --spacing 1,1,4) is drawn round by both renderers (its silhouette's
# height over width within 6% of 1, seen side-on); without the spacing it
# is the 4:1 pancake its voxel counts make; tvpal-play --scale-z 2
# stretches it to 2:1.  The manifest keeps spacing and origin.
. "$(dirname "$0")/lib.sh"
PLAY=$TVPAL_BUILDDIR/player/app/tvpal-play
[ -x "$PLAY" ] || { echo "built without libpng (no tvpal-play): skipped"; exit 77; }
"$PY" - "$W" <<'PY' || exit 99
import struct, sys
w = sys.argv[1]
nx, ny, nz, dz = 48, 48, 12, 4.0
for t in range(2):
    with open("%s/s_t%d.f32" % (w, t), "wb") as f:
        for z in range(nz):
            for y in range(ny):
                for x in range(nx):
                    r = ((x + 0.5 - 24) ** 2 + (y + 0.5 - 24) ** 2 + ((z + 0.5) * dz - 24) ** 2) ** 0.5
                    f.write(struct.pack("<f", 1.0 if r < 18 else 0.0))
PY
"$ENC" -q --dims 48x48x12 --window 2 --spacing 1,1,4 --origin 10,20,-5 -o "$W/phys" "$W"/s_t*.f32 > /dev/null || fail "encode"
"$ENC" -q --dims 48x48x12 --window 2 -o "$W/flat" "$W"/s_t*.f32 > /dev/null || fail "encode flat"
grep -q "^spacing = 1 1 4$" "$W/phys/manifest.txt" && grep -q "^origin = 10 20 -5$" "$W/phys/manifest.txt" \
    && ok "manifest: spacing and origin" || fail "manifest: $(grep '^spacing\|^origin' "$W/phys/manifest.txt")"
! grep -q "^spacing\|^origin" "$W/flat/manifest.txt" && ok "unit grid: no spacing keys" || fail "flat manifest has spacing"
printf 'domain normalized\n0 0 0 0 0\n0.4 0 0 0 0\n0.6 1 1 1 1\n1 1 1 1 1\n' > "$W/solid.tf"
aspect() { # PNG: height / width of the non-black pixels' bounding box
    "$PY" - "$1" "$TVPAL_SRCDIR/tests/pngdiff.py" <<'PY'
import os, sys
sys.dont_write_bytecode = True
sys.path.insert(0, os.path.dirname(sys.argv[2]))
from pngdiff import load
w, h, bpp, rows = load(sys.argv[1])
xs, ys = [], []
for y, r in enumerate(rows):
    for x in range(w):
        if max(r[x * bpp:x * bpp + 3]) > 40:
            xs.append(x); ys.append(y)
print("%.4f" % ((max(ys) - min(ys) + 1) / (max(xs) - min(xs) + 1)))
PY
}
RENDERERS=cpu
"$PLAY" --version | grep -q "gl: yes" && RENDERERS="cpu gl"
for r in $RENDERERS; do
    # --rotate 90,0: the z axis is the image's vertical.
    "$PLAY" "$W/phys" --headless -q --renderer $r --size 160x160 --rotate 90,0 --annotate none --tf "$W/solid.tf" --steps 0:0 -o "$W/p-$r" > /dev/null \
        || { fail "$r: play"; continue; }
    a=$(aspect "$W/p-$r/t0000.png")
    awk -v a="$a" 'BEGIN { exit !(a > 0.94 && a < 1.06) }' && ok "$r: the sphere is round (aspect $a)" || fail "$r: aspect $a, expected 1"
    "$PLAY" "$W/flat" --headless -q --renderer $r --size 160x160 --rotate 90,0 --annotate none --tf "$W/solid.tf" --steps 0:0 -o "$W/f-$r" > /dev/null || fail "$r: play flat"
    a=$(aspect "$W/f-$r/t0000.png")
    awk -v a="$a" 'BEGIN { exit !(a > 0.22 && a < 0.29) }' && ok "$r: without spacing, the 1:4 pancake (aspect $a)" || fail "$r: flat aspect $a, expected 0.25"
    "$PLAY" "$W/phys" --headless -q --renderer $r --size 160x160 --rotate 90,0 --annotate none --tf "$W/solid.tf" --steps 0:0 --scale-z 2 -o "$W/z-$r" > /dev/null || fail "$r: play --scale-z"
    a=$(aspect "$W/z-$r/t0000.png")
    awk -v a="$a" 'BEGIN { exit !(a > 1.88 && a < 2.12) }' && ok "$r: --scale-z 2 stretches it 2:1 (aspect $a)" || fail "$r: --scale-z 2 aspect $a"
done
expect_exit 2 "--scale-z \"0\": expected a factor" "$PLAY" "$W/phys" --headless --scale-z 0
expect_exit 2 "--spacing \"1,0,1\": expected DX,DY,DZ" "$ENC" -q --dims 48x48x12 --spacing 1,0,1 -o "$W/bad" "$W"/s_t*.f32
finish
