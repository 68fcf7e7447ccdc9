#!/bin/sh
# determinism: the same input gives the same bytes out, for 1 and 2 threads
# and across runs; the manifest too (no timestamps); tvpal-gen names sort
# in time order past 10000 steps.
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
# More than 10000 steps: names widen so that a glob sorts in time order.
"$GEN" --field constant --dims 1x1x1 --steps 10001 -o "$W/many" || fail "gen 10001"
first=$(ls "$W/many" | head -n 1); last=$(ls "$W/many" | tail -n 1)
[ "$first" = constant_t00000.f32 ] && [ "$last" = constant_t10000.f32 ] \
    && ok "10001 steps named t00000..t10000" || fail "names: $first .. $last"
finish
