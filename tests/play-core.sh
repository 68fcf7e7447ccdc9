#!/bin/sh
# play-core: the player core on real encoded data (N = 1 and 4): GL vs
# reference on all axes, jumps = sequential = backward playback, in-core =
# io_uring = pread, TF changes upload nothing, ~1/N uploads per step.
. "$(dirname "$0")/lib.sh"
PC=$TVPAL_BUILDDIR/tests/tvpal-playcheck
[ -x "$PC" ] || { echo "built without OSMesa/libpng: skipped"; exit 77; }
D=40x34x28
"$GEN" --field blobs --dims $D --steps 11 -o "$W/in" || fail gen
for N in 1 4; do
    "$ENC" -q --dims $D --window $N -o "$W/d$N" "$W"/in/*.f32 > /dev/null || fail "encode N=$N"
    "$PC" "$W/d$N" > "$W/pc.txt" 2>&1 && ok "N=$N: $(tail -n 1 "$W/pc.txt")" \
        || { fail "N=$N"; cat "$W/pc.txt" >&2; }
done
finish
