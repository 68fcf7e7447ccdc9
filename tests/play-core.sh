#!/bin/sh
# play-core: the player core on real encoded data (N = 1 and 4): GL vs
# reference on all axes, jumps = sequential = backward playback, in-core =
# io_uring = pread, TF changes upload nothing, ~1/N uploads per step; a
# read-ahead round a loop longer than its buffers keeps what they hold.
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
# A read-ahead round a loop longer than its record buffers keeps what
# they hold from one round to the next: a series longer than them, of
# plain records (coded ones keep to the buffers already touched).
D=24x20x16
"$GEN" --field blobs --dims $D --steps 64 -o "$W/in64" || fail gen
for N in 1 4; do
    "$ENC" -q --dims $D --window $N --index-coding none -o "$W/h$N" "$W"/in64/*.f32 > /dev/null \
        || fail "encode N=$N, 64 steps"
    "$PC" --cache "$W/h$N" > "$W/pc.txt" 2>&1 && ok "N=$N, $(grep '^cache:' "$W/pc.txt" | sed 's/^cache: //' | tr '\n' ';') $(tail -n 1 "$W/pc.txt")" \
        || { fail "cache, N=$N"; cat "$W/pc.txt" >&2; }
done
finish
