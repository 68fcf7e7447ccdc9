#!/bin/sh
# play-slowdisk: tvpal-play --progressive on with a clock (--fps) on a disk
# slowed to two thirds of the rate the playback needs (the block layer's
# throttle, scripts/with-read-limit; skipped where it cannot be set: it
# needs root and a cgroup io or blkio controller).  The reads fall behind,
# so some frames are drawn from level 1 and the full level comes back
# (full_ms on its first frame); every frame is the frame of its level,
# bit for bit (level 0: the run without --progressive, level 1: --level
# 1).  With --progressive off under the same limit every frame is level
# 0's, as without the limit.
. "$(dirname "$0")/lib.sh"
PLAY=$TVPAL_BUILDDIR/player/app/tvpal-play
LIMIT=$TVPAL_SRCDIR/scripts/with-read-limit
[ -x "$PLAY" ] || { echo "built without OSMesa/libpng: skipped"; exit 77; }
"$LIMIT" 1000000 "$W" true 2> "$W/limit.err"
rc=$?
[ $rc = 77 ] && { echo "skipped: $(cat "$W/limit.err")"; exit 77; }
[ $rc = 0 ] || { fail "with-read-limit: exit $rc: $(cat "$W/limit.err")"; finish; }
D=64x64x64
levels_dataset $D 60 1
rm -rf "$W/in"
run() { # NAME OPTIONS...: frames in $W/NAME, CSV $W/NAME.csv
    name=$1; shift
    "$@" --headless -q --renderer cpu --size 64x64 --csv "$W/$name.csv" -o "$W/$name" \
        > "$W/$name.out" 2>&1 || fail "$name: $(cat "$W/$name.out")"
}
col() { awk -F, -v n="$2" 'NR == 1 { for (i = 1; i <= NF; i++) if ($i == n) c = i; next } { print $c }' "$1"; }
run plain "$PLAY" "$W/ds"
run lv1 "$PLAY" "$W/ds" --level 1
# A steady frame reads about a quarter of level 0 (N = 4): 64 KiB; at 20
# fps that is 1.3 MB/s.  The limit: two thirds of it; the 60 steps are
# played twice (more than the stream's record buffers hold, so the
# second time reads them again).
bps=$(col "$W/plain.csv" bytes_read | awk 'NR > 2 { b += $1; n++ } END { printf "%d", n ? b / n * 20 * 2 / 3 : 0 }')
[ "$bps" -gt 0 ] || fail "no bytes read by steady frames"
run prog "$LIMIT" "$bps" "$W" "$PLAY" "$W/ds" --fps 20 --loop 2 --progressive on
run off "$LIMIT" "$bps" "$W" "$PLAY" "$W/ds" --fps 20 --progressive off
col "$W/prog.csv" step > "$W/s"; col "$W/prog.csv" level > "$W/l"; col "$W/prog.csv" full_ms > "$W/f"
paste -d' ' "$W/s" "$W/l" "$W/f" > "$W/rows"
below=$(awk '$2 > 0' "$W/rows" | wc -l)
back=$(awk 'NR > 1 && $2 == 0 && $3 > 0' "$W/rows" | wc -l)
full=$(awk 'NR > 1 && $2 == 0' "$W/rows" | wc -l)
[ "$below" -gt 0 ] && [ "$back" -gt 0 ] && [ "$full" -gt 0 ] \
    && ok "at ${bps} B/s: $below of 120 frames at level 1, $full at level 0, $back returns with full_ms ($(grep progressive: "$W/prog.out"))" \
    || fail "at ${bps} B/s: $below frames below, $full full, $back returns: $(awk '{ printf "%s", $2 }' "$W/rows")"
# Each step's PNG is its last frame's (the second time round).
awk '{ l[$1] = $2 } END { for (t in l) print t, l[t] }' "$W/rows" > "$W/last"
same=1
while read -r t lv; do
    p=$(printf 't%04u.png' "$t")
    if [ "$lv" = 0 ]; then ref=plain; else ref=lv1; fi
    cmp -s "$W/prog/$p" "$W/$ref/$p" || { same=0; echo "step $t (level $lv) differs from $ref"; }
done < "$W/last"
[ $same = 1 ] && ok "every frame is its level's, bit for bit" || fail "frames differ from their level's"
[ "$(col "$W/off.csv" level | sort -u)" = 0 ] && diff -r "$W/off" "$W/plain" > /dev/null \
    && ok "--progressive off under the limit: every frame level 0's, as without it" \
    || fail "--progressive off: $(col "$W/off.csv" level | tr -d '\n')"
finish
