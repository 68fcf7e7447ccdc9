#!/bin/sh
# input-order: numbered inputs out of natural order (a shell glob puts
# d_10 before d_2) are encoded as given with a warning naming the first pair
# out of order; --sort natural encodes them in numeric order (the same
# shards as the files listed in that order); inputs in order give no
# warning.
. "$(dirname "$0")/lib.sh"
for i in 1 2 10 11; do
    "$GEN" --field turbulence --dims 8x6x5 --steps 1 --seed $i -o "$W/g$i" > /dev/null || exit 99
    cp "$W"/g$i/*.f32 "$W/d_$i.f32"
done
"$ENC" --axes xyz -q --dims 8x6x5 --window 2 -o "$W/glob" "$W"/d_*.f32 > /dev/null 2> "$W/e.txt" || fail "glob encode"
grep -q "d_11.f32 comes before .*d_2.f32.*--sort natural" "$W/e.txt" \
    && ok "warning names d_11 before d_2" || fail "no warning: $(cat "$W/e.txt")"
"$ENC" --axes xyz -q --dims 8x6x5 --window 2 -o "$W/ordered" "$W/d_1.f32" "$W/d_2.f32" "$W/d_10.f32" "$W/d_11.f32" \
    > /dev/null 2> "$W/e.txt" || fail "ordered encode"
[ ! -s "$W/e.txt" ] && ok "in order: no warning" || fail "warning for ordered input: $(cat "$W/e.txt")"
"$ENC" --axes xyz -q --sort natural --dims 8x6x5 --window 2 -o "$W/sorted" "$W"/d_*.f32 > /dev/null 2> "$W/e.txt" \
    || fail "--sort natural encode"
[ ! -s "$W/e.txt" ] && ok "--sort natural: no warning" || fail "--sort natural warned: $(cat "$W/e.txt")"
same=1
for a in x y z; do cmp -s "$W/ordered/node-0/axis-$a.tvps" "$W/sorted/node-0/axis-$a.tvps" || same=0; done
[ $same = 1 ] && ok "--sort natural: the shards of the ordered list" || fail "--sort natural: shards differ"
sed -n 's/^source = .*\///p' "$W/sorted/manifest.txt" | tr '\n' ' ' | grep -q "^d_1.f32 d_2.f32 d_10.f32 d_11.f32 $" \
    && ok "manifest lists the sorted order" || fail "manifest order: $(grep '^source =' "$W/sorted/manifest.txt")"
cmp -s "$W/glob/node-0/axis-z.tvps" "$W/sorted/node-0/axis-z.tvps" && fail "glob order and sorted order gave the same shards" \
    || ok "the glob order was encoded as given"
expect_exit 2 "--sort.*none or natural" "$ENC" --axes xyz -q --sort bogus --dims 8x6x5 -o "$W/bad" "$W/d_1.f32"
finish
