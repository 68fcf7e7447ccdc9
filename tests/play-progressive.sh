#!/bin/sh
# play-progressive: tvpal-play --headless --progressive on.  Every jump
# frame draws a coarser level at once (CSV level above 0, the image that
# level draws at that step, bit for bit), reading nothing (the coarser
# levels are in RAM from the start), the full level comes back before the
# next jump (full_ms on that frame; how many frames it takes is planned
# from the measured read rate, a figure bench-play (j) prints), and the
# frames at the full level are those of a run without --progressive, bit
# for bit.  A dataset without levels plays exactly as without the option.
. "$(dirname "$0")/lib.sh"
PLAY=$TVPAL_BUILDDIR/player/app/tvpal-play
[ -x "$PLAY" ] || { echo "built without OSMesa/libpng: skipped"; exit 77; }
D=48x40x36
levels_dataset $D 32 2
"$ENC" -q --dims $D --window 4 -o "$W/flat" "$W"/in/*.f32 > /dev/null || fail "encode without levels"
run() { # NAME DATASET OPTIONS...: frames in $W/NAME, CSV $W/NAME.csv
    name=$1 ds=$2; shift 2
    "$PLAY" "$ds" --headless -q --renderer cpu --size 96x80 --jumps 8 --csv "$W/$name.csv" \
        -o "$W/$name" "$@" > "$W/$name.out" 2>&1 || fail "$name: $(cat "$W/$name.out")"
}
run prog "$W/ds" --progressive on
run plain "$W/ds"
run lv1 "$W/ds" --level 1
run lv2 "$W/ds" --level 2
# col FILE NAME: the values of CSV column NAME, one per frame.
col() { awk -F, -v n="$2" 'NR == 1 { for (i = 1; i <= NF; i++) if ($i == n) c = i; next } { print $c }' "$1"; }
col "$W/prog.csv" step > "$W/steps"
col "$W/prog.csv" jump > "$W/jumps"
col "$W/prog.csv" level > "$W/levels"
col "$W/prog.csv" full_ms > "$W/full"
col "$W/prog.csv" bytes_read > "$W/bytes"
paste -d' ' "$W/steps" "$W/jumps" "$W/levels" "$W/full" "$W/bytes" > "$W/rows"
# The coarser levels were loaded before the first frame (in RAM within
# --mem): a jump drawn from one reads nothing.
awk '$2 == 1 && $5 != 0 { print "jump to " $1 " read " $5 " bytes"; bad = 1 } END { exit bad }' "$W/rows" \
    && ok "jump frames read nothing (the coarse levels are in RAM)" \
    || fail "coarse jump frames read: $(awk '$2 == 1' "$W/rows" | tr '\n' ';')"
# Every jump draws level 1 or 2, the frames after it too until one comes
# back to level 0 with its time from the jump, before the next jump.
awk '{ n++ }
     $2 == 1 { if ($3 == 0) { print "jump at frame " n " drew level 0"; bad = 1 }
               if (open_) { print "no level 0 between the jumps at frames " open_ " and " n; bad = 1 }
               open_ = n; jumps++; next }
     open_ && $3 != 0 { next }
     open_ { if ($4 <= 0) { print "no full_ms at frame " n; bad = 1 } open_ = 0; back++ }
     END { if (jumps < 3 || back != jumps) { print jumps " jumps, " back " refined"; bad = 1 } exit bad }' "$W/rows" \
    && ok "every jump draws a coarser level at once, level 0 before the next ($(awk '$2 == 1' "$W/rows" | wc -l) jumps, back after $(awk '$2 == 1 { j = NR } $2 == 0 && $3 == 0 && j { printf "%s%d", s, NR - j; s = ","; j = 0 }' "$W/rows") frames)" \
    || fail "progressive levels: $(cat "$W/rows" | tr '\n' ';')"
# The images: the last frame of each step (the PNGs are named by step) is
# the full-level frame of the plain run at level 0, else the --level run's.
same=1 n0=0 nc=0
for t in $(sort -u "$W/steps"); do
    lv=$(awk -v t="$t" '$1 == t { l = $3 } END { print l }' "$W/rows")
    f=$(printf 't%04u.png' "$t")
    [ -f "$W/prog/$f" ] || f=$(printf 't%02u.png' "$t")
    if [ "$lv" = 0 ]; then ref=plain; n0=$((n0 + 1)); else ref=lv$lv; nc=$((nc + 1)); fi
    cmp -s "$W/prog/$f" "$W/$ref/$f" || { same=0; echo "step $t (level $lv): differs from $ref"; }
done
[ $same = 1 ] && [ $n0 -gt 0 ] && [ $nc -gt 0 ] \
    && ok "images bit for bit: $n0 steps at level 0 as without --progressive, $nc coarse as --level" \
    || fail "progressive images differ ($n0 full, $nc coarse)"
# Without levels the option changes nothing.
run fprog "$W/flat" --progressive on
run fplain "$W/flat"
[ "$(col "$W/fprog.csv" level | sort -u)" = 0 ] && diff -r "$W/fprog" "$W/fplain" > /dev/null \
    && ok "a dataset without levels: the same frames, all at level 0" || fail "without levels: frames differ"
# Read errors while refining: a record of level 0 corrupted (a window
# that jumps prepare off the frame's thread) is reported as without
# --progressive (the file and record, keeping the last good data), the
# run goes on to its last frame and exits 1, and every frame is written.
cp -r "$W/ds" "$W/bad"
ls "$W"/bad/node-0/axis-*.tvps | while read -r f; do
    $PY - "$f" <<'PY'
import struct, sys
p = sys.argv[1]; b = bytearray(open(p, "rb").read())
idx = struct.unpack_from("<Q", b, 72)[0]
for r in (5, 9):
    off = struct.unpack_from("<Q", b, idx + 32 * r)[0]
    b[off + 64 + 10] ^= 0x40
open(p, "wb").write(b)
PY
done
for pr in on off; do
    "$PLAY" "$W/bad" --headless -q --renderer cpu --size 96x80 --jumps 8 --progressive $pr \
        --csv "$W/bad-$pr.csv" -o "$W/bad-$pr" > "$W/bad-$pr.out" 2>&1
    echo $? > "$W/bad-$pr.rc"
done
grep -o "axis-.\.tvps: record [0-9]*: payload CRC-32C mismatch (keeping the last good data)" "$W/bad-on.out" | sort -u > "$W/bad-on.msgs"
grep -o "axis-.\.tvps: record [0-9]*: payload CRC-32C mismatch (keeping the last good data)" "$W/bad-off.out" | sort -u > "$W/bad-off.msgs"
[ "$(cat "$W/bad-on.rc")" = 1 ] && [ "$(cat "$W/bad-off.rc")" = 1 ] && [ -s "$W/bad-on.msgs" ] \
    && cmp -s "$W/bad-on.msgs" "$W/bad-off.msgs" \
    && [ "$(ls "$W/bad-on" | grep -c png)" = "$(ls "$W/prog" | grep -c png)" ] \
    && [ "$(wc -l < "$W/bad-on.csv")" = "$(wc -l < "$W/prog.csv")" ] \
    && ok "read errors while refining: reported as without --progressive ($(tr '\n' ';' < "$W/bad-on.msgs")), every frame written, exit 1" \
    || fail "read errors: exit $(cat "$W/bad-on.rc")/$(cat "$W/bad-off.rc"); on: $(cat "$W/bad-on.out" | tr '\n' ';'); off: $(cat "$W/bad-off.out" | tr '\n' ';')"
# --loop 2: the range twice over, the same frames (a step drawn again
# overwrites its PNG with the same image).
run loop "$W/ds" --steps 3:8 --loop 2 --jumps 1000
run once "$W/ds" --steps 3:8 --jumps 1000
[ "$(col "$W/loop.csv" step | tr '\n' ' ')" = "3 4 5 6 7 8 3 4 5 6 7 8 " ] && diff -r "$W/loop" "$W/once" > /dev/null \
    && ok "--loop 2: steps 3..8 twice, the same frames" || fail "--loop 2: steps $(col "$W/loop.csv" step | tr '\n' ' ')"
expect_exit 2 "progressive" "$PLAY" "$W/ds" --headless --progressive maybe
finish
