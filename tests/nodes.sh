#!/bin/sh
# nodes: --nodes K splits every axis into K slabs (node-R/ directories, each
# with its manifest); slices are coded independently, so decoding gives
# exactly the same volumes for K = 1, 3 and K = the smallest axis.
. "$(dirname "$0")/lib.sh"
D=16x13x7
"$GEN" --field front --dims $D --steps 6 -o "$W/in" || fail gen
for K in 1 3 7; do
    "$ENC" --axes xyz -q --dims $D --window 4 --nodes $K -o "$W/k$K" "$W"/in/*.f32 \
        > /dev/null || fail "encode K=$K"
    n=$(ls -d "$W/k$K"/node-* | wc -l)
    [ "$n" -eq $K ] && ok "K=$K: $n node directories" || fail "K=$K: $n dirs"
    for r in $(seq 0 $((K - 1))); do
        for a in x y z; do
            [ -s "$W/k$K/node-$r/axis-$a.tvps" ] || fail "missing node-$r axis-$a"
        done
        [ -s "$W/k$K/node-$r/manifest.txt" ] || fail "missing node-$r manifest"
    done
    for t in 0 3 5; do
        for a in x y z; do
            "$DEC" "$W/k$K" --step $t --axis $a -o "$W/k$K-$t-$a.f32" \
                || fail "decode K=$K t=$t $a"
            [ $K -eq 1 ] || cmp -s "$W/k1-$t-$a.f32" "$W/k$K-$t-$a.f32" \
                || fail "K=$K t=$t axis $a differs from K=1"
        done
    done
    [ $K -eq 1 ] || ok "K=$K decodes identically to K=1"
done
"$INFO" "$W/k3" --verify > /dev/null && ok "K=3 verifies" || fail "K=3 verify"
expect_exit 2 "nodes 8.*z axis" "$ENC" --axes xyz -q --dims $D --nodes 8 -o "$W/k8" "$W"/in/*.f32
[ ! -e "$W/k8" ] && [ ! -e "$W/k8.partial" ] && ok "nothing left for K=8" \
    || fail "output left behind for K=8"
finish
