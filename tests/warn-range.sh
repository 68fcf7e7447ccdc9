#!/bin/sh
# warn-range: a fill value left in the data (40 voxels of 1e35) or a few
# values far outside the rest is named in a warning with its count, since it
# would set the quantizers' and the colours' range and flatter the PSNR;
# real-looking data (turbulence) gives no warning.
. "$(dirname "$0")/lib.sh"
"$PY" - "$W" <<'PY' || exit 99
import struct, sys
w = sys.argv[1]
for name, big, n in (("fill", 1e35, 20), ("far", 5e20, 3)):
    for t in range(2):
        with open("%s/%s_t%d.f32" % (w, name, t), "wb") as f:
            for i in range(16 * 16 * 16):
                f.write(struct.pack("<f", big if i < n else (i % 97) * 0.1))
PY
"$ENC" -q --dims 16x16x16 -o "$W/fill" "$W"/fill_t*.f32 > /dev/null 2> "$W/e.txt" || fail "fill encode"
grep -q "warning: 40 values beyond +-1e30" "$W/e.txt" && ok "fill value: 40 values named" || fail "fill: $(cat "$W/e.txt")"
"$ENC" -q --dims 16x16x16 -o "$W/far" "$W"/far_t*.f32 > /dev/null 2> "$W/e.txt" || fail "far encode"
grep -q "warning: 6 values (0.0732%) lie far outside the bulk" "$W/e.txt" && ok "6 far values named" || fail "far: $(cat "$W/e.txt")"
"$GEN" --field turbulence --dims 16x16x16 --steps 2 -o "$W/t" > /dev/null || exit 99
"$ENC" -q --dims 16x16x16 -o "$W/turb" "$W"/t/*.f32 > /dev/null 2> "$W/e.txt" || fail "turbulence encode"
[ ! -s "$W/e.txt" ] && ok "turbulence: no warning" || fail "turbulence warned: $(cat "$W/e.txt")"
S=${TVPAL_SHARED:-$TVPAL_SRCDIR/../shared}/data/viscous-fingers-run01
if [ -r "$S/density_t001.f32" ]; then
    "$ENC" -q --dims 64x64x64 -o "$W/vf" "$S"/density_t00[1-4].f32 > /dev/null 2> "$W/e.txt" || fail "vf encode"
    [ ! -s "$W/e.txt" ] && ok "viscous fingers: no warning" || fail "viscous fingers warned: $(cat "$W/e.txt")"
fi
finish
