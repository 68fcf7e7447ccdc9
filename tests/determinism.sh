#!/bin/sh
# determinism: the same input gives the same bytes out, for 1 and 2 threads
# and across runs; the manifest too (no timestamps).
. "$(dirname "$0")/lib.sh"
D=24x20x16
"$GEN" --field turbulence --dims $D --steps 9 -o "$W/in" || fail gen
"$ENC" -q --dims $D --window 4 -j 1 -o "$W/a" "$W"/in/*.f32 > /dev/null || fail "encode a"
"$ENC" -q --dims $D --window 4 -j 2 -o "$W/b" "$W"/in/*.f32 > /dev/null || fail "encode b"
"$ENC" -q --dims $D --window 4 -o "$W/c" "$W"/in/*.f32 > /dev/null || fail "encode c"
for d in b c; do
    diff -r "$W/a" "$W/$d" > /dev/null && ok "run $d identical to run a" \
        || fail "run $d differs from run a"
done
"$GEN" --field turbulence --dims $D --steps 9 -o "$W/in2" || fail gen2
cmp -s "$W/in/turbulence_t0004.f32" "$W/in2/turbulence_t0004.f32" \
    && ok "tvpal-gen deterministic" || fail "tvpal-gen output differs"
finish
