#!/bin/sh
# axes-agree: a timestep decoded from the x, y and z slices matches the
# original (independent comparison, not the report) and the three decodes
# agree with each other within the quantization error.
. "$(dirname "$0")/lib.sh"
CHK=$TVPAL_BUILDDIR/tests/tvpal-check
D=32x28x24
"$GEN" --field blobs --dims $D --steps 8 -o "$W/in" || fail gen
"$ENC" --axes xyz -q --dims $D --window 4 -o "$W/ds" "$W"/in/*.f32 > /dev/null || fail encode
for t in 0 3 7; do
    ref=$(printf '%s/in/blobs_t%04d.f32' "$W" $t)
    for a in x y z; do
        "$DEC" "$W/ds" --step $t --axis $a -o "$W/$a.f32" || fail "decode $a"
        p=$(kv psnr "$("$CHK" cmp "$ref" "$W/$a.f32")")
        ge "$p" 50 && ok "step $t axis $a vs original: $p dB" \
            || fail "step $t axis $a vs original: $p dB < 50"
    done
    for pair in "x y" "y z" "x z"; do
        set -- $pair
        p=$(kv psnr "$("$CHK" cmp "$W/$1.f32" "$W/$2.f32")")
        ge "$p" 46 && ok "step $t: $1 vs $2 agree ($p dB)" \
            || fail "step $t: $1 vs $2 disagree ($p dB < 46)"
    done
done
finish
