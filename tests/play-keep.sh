#!/bin/sh
# play-keep: tvpal-play --progressive with a coarser level that does not
# fit in --mem.  Level 1 is then streamed, keeping the records of the
# steps around the playhead (both ways, within its share of --mem), read
# off the frame's thread as playback moves: a jump near the slider
# (--jump-span) draws level 1 at once without reading any of its records
# (bytes_needed 0), and its frames are those of --level 1, bit for bit;
# the frames at level 0 those of a run without --progressive.  A bad
# record of level 1 is reported as any record is, and the run goes on.
. "$(dirname "$0")/lib.sh"
PLAY=$TVPAL_BUILDDIR/player/app/tvpal-play
[ -x "$PLAY" ] || { echo "built without OSMesa/libpng: skipped"; exit 77; }
D=128x128x64
levels_dataset $D 32 2
SPAN=3
run() { # NAME DATASET OPTIONS...: frames in $W/NAME, CSV $W/NAME.csv
    name=$1 ds=$2; shift 2
    "$PLAY" "$ds" --headless --renderer cpu --size 96x80 --level 0 --csv "$W/$name.csv" \
        -o "$W/$name" "$@" > "$W/$name.out" 2>&1 || fail "$name: $(cat "$W/$name.out")"
}
# --mem 3: level 1 (about 1.7 MiB) gets 1.5 MiB, level 2 0.75.
run keep "$W/ds" --progressive on --mem 3 --jumps 5 --jump-span $SPAN --loop 2
run plain "$W/ds"
run lv1 "$W/ds" --level 1
kept=$(sed -n 's/.*level 1 streamed (\([0-9]*\) steps each way kept).*/\1/p' "$W/keep.out")
[ -n "$kept" ] && [ "$kept" -ge $SPAN ] \
    && ok "level 1 does not fit in --mem 3: streamed, $kept steps kept each way ($(grep -o "progressive: level.*" "$W/keep.out"))" \
    || fail "--mem 3 should stream level 1 with at least $SPAN steps kept: $(grep progressive "$W/keep.out")"
col() { awk -F, -v n="$2" 'NR == 1 { for (i = 1; i <= NF; i++) if ($i == n) c = i; next } { print $c }' "$1"; }
for c in step jump level bytes_needed; do col "$W/keep.csv" $c > "$W/c.$c"; done
paste -d' ' "$W/c.step" "$W/c.jump" "$W/c.level" "$W/c.bytes_needed" > "$W/rows"
# Every jump is within SPAN of the step before it; those drawn at level 1
# read none of their records.
awk -v span=$SPAN 'NR > 1 && $2 == 1 { d = $1 - prev; if (d < 0) d = -d
                                        if (d < 1 || d > span) { print "jump " prev " -> " $1; bad = 1 } }
                   { prev = $1 }
                   $2 == 1 && $3 == 1 { coarse++; if ($4 != 0) { print "jump to " $1 " read " $4; bad = 1 } }
                   END { if (coarse < 3) { print coarse " jumps at level 1"; bad = 1 } exit bad }' "$W/rows" \
    && ok "$(awk '$2 == 1 && $3 == 1' "$W/rows" | wc -l) jumps within $SPAN steps drawn at level 1 with none of its records read" \
    || fail "kept jumps: $(tr '\n' ';' < "$W/rows")"
# The images: each step's last frame is level 0's without --progressive,
# or level 1's as --level 1 draws it.
same=1 n0=0 n1=0
for t in $(cut -d' ' -f1 "$W/rows" | sort -u); do
    lv=$(awk -v t="$t" '$1 == t { l = $3 } END { print l }' "$W/rows")
    f=$(printf 't%04u.png' "$t")
    [ -f "$W/keep/$f" ] || f=$(printf 't%02u.png' "$t")
    case $lv in 0) ref=plain n0=$((n0 + 1)) ;; 1) ref=lv1 n1=$((n1 + 1)) ;; *) ref=none ;; esac
    cmp -s "$W/keep/$f" "$W/$ref/$f" || { same=0; echo "step $t (level $lv): differs from $ref"; }
done
[ $same = 1 ] && [ $n0 -gt 0 ] && [ $n1 -gt 0 ] \
    && ok "images bit for bit: $n0 steps at level 0 as without --progressive, $n1 at level 1 as --level 1" \
    || fail "images differ ($n0 at level 0, $n1 at level 1)"
# Every level-1 record after record 0 damaged: the kept records fail
# their check off the frame's thread, are read again by the frame that
# needs them and reported there (file and record), the run draws every
# frame and exits 1.
cp -r "$W/ds" "$W/bad"
$PY - "$W"/bad/level-1/node-0/axis-z.tvps <<'PY'
import struct, sys
p = sys.argv[1]; b = bytearray(open(p, "rb").read())
idx = struct.unpack_from("<Q", b, 72)[0]
for r in range(1, 32):
    off = struct.unpack_from("<Q", b, idx + 32 * r)[0]
    b[off + 64 + 10] ^= 0x40
open(p, "wb").write(b)
PY
"$PLAY" "$W/bad" --headless -q --renderer cpu --size 96x80 --level 0 --progressive on --mem 3 \
    --jumps 5 --jump-span $SPAN --loop 2 --csv "$W/bad.csv" -o "$W/bad-frames" > "$W/bad.out" 2>&1
rc=$?
[ $rc = 1 ] && grep -q "level-1/node-0/axis-z.tvps: record [0-9]*: payload CRC-32C mismatch" "$W/bad.out" \
    && [ "$(wc -l < "$W/bad.csv")" = "$(wc -l < "$W/keep.csv")" ] \
    && ok "damaged level-1 records: reported ($(grep -o 'level-1[^ ]* record [0-9]*' "$W/bad.out" | sort -u | wc -l) distinct), every frame drawn, exit 1" \
    || fail "damaged level 1: exit $rc: $(head -5 "$W/bad.out" | tr '\n' ';')"
expect_exit 2 "jump-span" "$PLAY" "$W/ds" --headless --jumps 5 --jump-span 0
finish
