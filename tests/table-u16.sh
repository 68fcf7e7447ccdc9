#!/bin/sh
# table-u16: --table u16 stores the decoder tables in 16 bits scaled per
# slice-window: table bits per voxel-timestep halve, PSNR moves by less
# than 0.01 dB, every reader (decode, report, random access, the player)
# handles it, and the choice is in the manifest.
. "$(dirname "$0")/lib.sh"
CHK=$TVPAL_BUILDDIR/tests/tvpal-check
D=30x26x20
"$GEN" --field turbulence --dims $D --steps 9 -o "$W/in" || fail gen
for tf in f32 u16; do
    "$ENC" -q --dims $D --window 4 --table $tf -o "$W/$tf" "$W"/in/*.f32 > /dev/null || fail "encode $tf"
done
grep -q "^table = u16" "$W/u16/manifest.txt" && grep -q "^table = f32" "$W/f32/manifest.txt" \
    && ok "manifest names the table format" || fail "manifest table key"
a=$("$REP" -q "$W/f32") || fail "report f32"
b=$("$REP" -q "$W/u16") || fail "report u16"
awk -v a="$(kv table_bpv "$a")" -v b="$(kv table_bpv "$b")" 'BEGIN { exit !(b > 0 && (a / b) > 1.99 && (a / b) < 2.01) }' \
    && ok "table bits $(kv table_bpv "$a") -> $(kv table_bpv "$b")" || fail "table bits: $a / $b"
awk -v a="$(kv psnr "$a")" -v b="$(kv psnr "$b")" 'BEGIN { d = a - b; exit !(d < 0.01 && d > -0.01) }' \
    && ok "psnr $(kv psnr "$a") -> $(kv psnr "$b")" || fail "psnr changed: $(kv psnr "$a") -> $(kv psnr "$b")"
"$CHK" seqjump "$W/u16" > "$W/sj.txt" 2>&1 && ok "u16: jumps = sequential" || { fail "seqjump u16"; cat "$W/sj.txt" >&2; }
"$INFO" "$W/u16" --verify > /dev/null && ok "u16 verifies" || fail "verify u16"
PLAY=$TVPAL_BUILDDIR/player/app/tvpal-play
if [ -x "$PLAY" ]; then
    for tf in f32 u16; do
        "$PLAY" "$W/$tf" --headless -q --size 64x64 -o "$W/p-$tf" --steps 4:4 > /dev/null || fail "play $tf"
    done
    r=$($PY "$TVPAL_SRCDIR/tests/pngdiff.py" "$W/p-f32/t0004.png" "$W/p-u16/t0004.png")
    echo "$r" | grep -q "^max=[01] " && ok "player: u16 frame within 1 level of f32 ($r)" || fail "player u16: $r"
fi
expect_exit 2 "--table \"f16\": expected f32, u16 or auto" "$ENC" --dims $D --table f16 -o "$W/x" "$W"/in/*.f32
finish
