#!/bin/sh
# play-stage: the stager prepares each next step off the frame's thread.
# Streamed and in-core, forward and backward: every frame after the first
# installs records prepared ahead (records_staged > 0); a jump (and the return from it)
# is prepared on the frame's thread (records_staged = 0), a frame that
# follows its predecessor is staged; images are bit for bit those of --prefetch 0 (no stager); a
# corrupt record is reported the same way with and without it.
. "$(dirname "$0")/lib.sh"
PLAY=$TVPAL_BUILDDIR/player/app/tvpal-play
[ -x "$PLAY" ] || { echo "built without OSMesa/libpng: skipped"; exit 77; }
D=32x28x24
"$GEN" --field turbulence --dims $D --steps 12 -o "$W/in" || fail gen
# The staggered schedule, so that every step after the first has records to
# stage (the joined one starts no window at steps 1..3).
"$ENC" --axes xyz -q --dims $D --window 4 --schedule staggered -o "$W/ds" \
    "$W"/in/*.f32 > /dev/null || fail encode
col() { # col CSV NAME: the column's values, one per line
    awk -F, -v n="$2" 'NR == 1 { for (i = 1; i <= NF; i++) if ($i == n) c = i; next } { print $c }' "$1"
}
for mode in stream incore; do
    for steps in 0:11 11:0; do
        for pf in 0 4; do
            "$PLAY" "$W/ds" --headless -q --renderer cpu --size 64x56 -m $mode \
                --steps $steps --prefetch $pf -o "$W/$mode-$steps-$pf" > /dev/null 2>&1 \
                || fail "play $mode $steps prefetch $pf"
        done
        a=$W/$mode-$steps-0 b=$W/$mode-$steps-4
        same=1
        for f in "$a"/t*.png; do cmp -s "$f" "$b/$(basename "$f")" || same=0; done
        [ $same = 1 ] && ok "$mode $steps: frames identical with and without the stager" \
            || fail "$mode $steps: the stager changed frames"
        st=$(col "$b/timing.csv" records_staged | tail -n +2 | sort -n | head -n 1)
        [ "$st" -gt 0 ] && ok "$mode $steps: every frame after the first staged (min $st records)" \
            || fail "$mode $steps: a frame without staged records: $(col "$b/timing.csv" records_staged | tr '\n' ' ')"
        z=$(col "$a/timing.csv" records_staged | sort -n | tail -n 1)
        [ "$z" -eq 0 ] && ok "$mode $steps: --prefetch 0 stages nothing" \
            || fail "$mode $steps prefetch 0: staged $z"
    done
done
# Jumps: every 3rd frame jumps to a random step (reproducibly).
for pf in 0 4; do
    "$PLAY" "$W/ds" --headless -q --renderer cpu --size 64x56 --jumps 3 --prefetch $pf \
        -o "$W/j$pf" > /dev/null 2>&1 || fail "jumps prefetch $pf"
done
same=1
for f in "$W/j0"/t*.png; do cmp -s "$f" "$W/j4/$(basename "$f")" || same=0; done
[ $same = 1 ] && ok "jumps: frames identical with and without the stager" || fail "jumps: frames differ"
# A frame is staged exactly when its step follows the previous one: the
# jump frame is not, and neither is the return from it to the sequence.
awk -F, 'NR == 1 { for (i = 1; i <= NF; i++) { if ($i == "jump") j = i; if ($i == "records_staged") s = i } next }
         { seq = NR > 2 && $1 == prev + 1; if ((seq && $s == 0) || (!seq && $s != 0)) bad++; n += $j; prev = $1 }
         END { exit !(n > 0 && !bad) }' "$W/j4/timing.csv" \
    && ok "jumps: prepared on the frame's thread; a frame that follows its predecessor staged" \
    || fail "jumps: steps $(col "$W/j4/timing.csv" step | tr '\n' ' ') / staged $(col "$W/j4/timing.csv" records_staged | tr '\n' ' ')"
# A corrupt record (step 6 of every axis, a byte flipped in its payload):
# the same messages and exit status with and without the stager.
cp -r "$W/ds" "$W/bad"
for ax in x y z; do
    $PY - "$W/bad/node-0/axis-$ax.tvps" 6 <<'PY' || fail "corrupt axis $ax"
import struct, sys
p, r = sys.argv[1], int(sys.argv[2])
b = bytearray(open(p, "rb").read())
idx = struct.unpack_from("<Q", b, 72)[0]
off = struct.unpack_from("<Q", b, idx + 32 * r)[0]
b[off + 64 + 100] ^= 0x20
open(p, "wb").write(b)
PY
done
for pf in 0 4; do
    "$PLAY" "$W/bad" --headless -q --renderer cpu --size 64x56 --prefetch $pf -o "$W/b$pf" > "$W/b$pf.out" 2> "$W/b$pf.err"
    echo $? > "$W/b$pf.rc"
done
cmp -s "$W/b0.err" "$W/b4.err" && cmp -s "$W/b0.rc" "$W/b4.rc" && [ "$(cat "$W/b4.rc")" = 1 ] \
    && grep -q "record 6.*CRC-32C mismatch" "$W/b4.err" \
    && ok "corrupt record: the same report and status 1 with and without the stager: $(head -n 1 "$W/b4.err")" \
    || fail "corrupt record: $(cat "$W/b0.err") [$(cat "$W/b0.rc")] vs $(cat "$W/b4.err") [$(cat "$W/b4.rc")]"
same=1
for f in "$W/b0"/t*.png; do cmp -s "$f" "$W/b4/$(basename "$f")" || same=0; done
[ $same = 1 ] && ok "corrupt record: frames identical (the last good data stays)" || fail "corrupt: frames differ"
# Jumps onto the corrupt record (steps 6..9 need record 6; --jumps 1
# from step 2 goes 7 8 8 6 6 3 9).  A jump is staged and installed on the
# frame's thread with the stager (the CRC summed as the record is staged,
# the bad record's slices unstaged), checked and applied in place without
# it: the same frames, messages and status; reading the records one at a
# time (--read-ahead 1) too.
for pf in "0" "4" "4 --read-ahead 1"; do
    n=$(echo "$pf" | tr -d ' -')
    "$PLAY" "$W/bad" --headless -q --renderer cpu --size 64x56 --steps 2:9 --jumps 1 --prefetch $pf \
        -o "$W/bj$n" > /dev/null 2> "$W/bj$n.err"
    echo $? > "$W/bj$n.rc"
done
same=1
for f in "$W/bj0"/t*.png; do
    cmp -s "$f" "$W/bj4/$(basename "$f")" && cmp -s "$f" "$W/bj4readahead1/$(basename "$f")" || same=0
done
# a jump from before step 6 onto 6..9: the slices of record 6 must keep
# their window from before the jump
into=$(awk -F, 'NR == 1 { for (i = 1; i <= NF; i++) if ($i == "jump") j = i; next }
                $j == 1 && $1 >= 6 && prev < 6 { n++ } { prev = $1 } END { print n + 0 }' "$W/bj4/timing.csv")
cmp -s "$W/bj0.err" "$W/bj4.err" && cmp -s "$W/bj0.err" "$W/bj4readahead1.err" \
    && [ "$(cat "$W/bj0.rc")" = 1 ] && [ "$(cat "$W/bj4.rc")" = 1 ] && [ $same = 1 ] \
    && [ "$into" -ge 1 ] && grep -q "record 6.*CRC-32C mismatch" "$W/bj4.err" \
    && ok "$into jump(s) onto a corrupt record: the same frames, report and status 1 with and without the stager" \
    || fail "jumps onto a corrupt record: frames same=$same, jumps into 6..9: $into; $(cat "$W/bj0.err") vs $(cat "$W/bj4.err")"
finish
