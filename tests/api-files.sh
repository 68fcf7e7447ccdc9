#!/bin/sh
# api-files: libtvpal's encode from a source against tvpal-encode, on the
# same raw files.  tests/api-files (tvpal.h and the shared library only)
# reads one file per step, with pread from the encoder's threads or a box
# at a time on its reader thread.  Under a memory limit that takes many
# passes over slabs of every axis, the API makes the plan tvpal-encode
# makes (passes, peak, voxels read: the same sums) and the same shards,
# byte for byte; with --levels (made after level 0 from the files read
# again) the levels' too; uint16 big-endian files as tvpal-encode --type
# u16 --endian big; stopped after a unit of a later pass and run again, it
# continues there, reads none of the steps before, and gives the same
# bytes, with its measured peak memory under the limit.
. "$(dirname "$0")/lib.sh"
API=$TVPAL_BUILDDIR/tests/api-files
CHECK=$TVPAL_BUILDDIR/tests/tvpal-check
D=96x80x64
"$GEN" --field turbulence --dims $D --steps 9 -o "$W/in" > /dev/null || fail gen
set -- "$W"/in/*.f32

# The smallest limit tvpal-encode takes for --window 4, plus 3 MiB.
m=$("$ENC" --axes xyz -j 1 --mem-limit 1M --dims $D --window 4 -o "$W/none" "$@" 2>&1 |
    sed -n 's/.*give --mem-limit \([0-9]*\)K.*/\1/p')
[ -n "$m" ] || { fail "no smallest limit from tvpal-encode"; finish; }
LIM=$(((m + 3 * 1024) * 1024))

# shards_same A B: every shard of A (levels included) is B's, and B has no
# other.
shards_same() {
    (cd "$1" && find . -name '*.tvps' | sort) > "$W/a.list"
    (cd "$2" && find . -name '*.tvps' | sort) > "$W/b.list"
    cmp -s "$W/a.list" "$W/b.list" && [ -s "$W/a.list" ] || return 1
    while read -r f; do cmp -s "$1/$f" "$2/$f" || return 1; done < "$W/a.list"
}

"$ENC" --axes xyz --dry-run -j 1 --mem-limit $LIM --dims $D --window 4 -o "$W/enc" "$@" \
    > "$W/dry.out" || fail "tvpal-encode --dry-run"
"$ENC" --axes xyz -j 1 --mem-limit $LIM --dims $D --window 4 -o "$W/enc" "$@" \
    > "$W/enc.out" 2> "$W/enc.err" || fail "tvpal-encode under $LIM"
for how in "" --whole; do
    "$API" $how --plan --axes 7 --threads 1 --mem-limit $LIM --dims $D --window 4 \
        -o "$W/api$how" "$@" > "$W/plan$how.out" 2>&1 || fail "plan $how: $(cat "$W/plan$how.out")"
    "$CHECK" peakrss "$API" $how --axes 7 --threads 1 --mem-limit $LIM --dims $D --window 4 \
        -o "$W/api$how" "$@" > "$W/api$how.out" 2> "$W/api$how.err" ||
        fail "api-files $how: $(cat "$W/api$how.err")"
    p=$(sed -n 's/^passes=\([0-9]*\) .*/\1/p' "$W/plan$how.out")
    [ "${p:-0}" -gt 3 ] || fail "api-files $how: ${p:-no} passes under $LIM"
    shards_same "$W/enc" "$W/api$how" && ok "api-files $how: $p passes under $LIM, the shards of tvpal-encode" ||
        fail "api-files $how: shards differ from tvpal-encode's"
    kb=$(sed -n 's/^maxrss_kb=//p' "$W/api$how.err")
    if [ -n "${ASAN_OPTIONS:-}" ]; then
        echo "note: peak ${kb:-?} KiB not compared under AddressSanitizer"
    elif [ -n "$kb" ] && [ "$kb" -le $((LIM / 1024)) ]; then
        ok "api-files $how: peak $kb KiB <= $((LIM / 1024)) KiB"
    else
        fail "api-files $how: peak ${kb:-?} KiB over the limit $((LIM / 1024)) KiB"
    fi
done
# The files it recorded (tvpal_encoder_set_provenance) are read again by
# tvpal-report, which finds tvpal-encode's PSNR.
"$REP" "$W/api" > "$W/rep-api.txt" 2>&1 || fail "tvpal-report of the API's dataset: $(cat "$W/rep-api.txt")"
"$REP" "$W/enc" > "$W/rep-enc.txt" 2>&1 || fail "tvpal-report of tvpal-encode's dataset"
pa=$(sed -n 's/^psnr=\([0-9.]*\) .*/\1/p' "$W/rep-api.txt")
pe=$(sed -n 's/^psnr=\([0-9.]*\) .*/\1/p' "$W/rep-enc.txt")
grep -q "^encoder = api-files$" "$W/api/manifest.txt" && [ -n "$pa" ] && [ "$pa" = "$pe" ] &&
    ok "tvpal-report reads the API's recorded sources: PSNR $pa dB, tvpal-encode's" ||
    fail "tvpal-report: PSNR ${pa:-none} against tvpal-encode's ${pe:-none}"
# A concurrent source's plan is tvpal-encode's raw plan: the same sums.
for k in passes passes_x passes_y passes_z peak_bytes; do
    a=$(tr ' ' '\n' < "$W/plan.out" | sed -n "s/^$k=//p")
    e=$(tr ' ' '\n' < "$W/dry.out" | sed -n "s/^$k=//p")
    [ -n "$a" ] && [ "$a" = "$e" ] || fail "plan: $k $a, tvpal-encode's $e"
done
rv=$(tr ' ' '\n' < "$W/plan.out" | sed -n 's/^read_voxels=//p')
rb=$(tr ' ' '\n' < "$W/dry.out" | sed -n 's/^read_bytes=//p')
[ "$((rv * 4))" = "$rb" ] && ok "plan: tvpal-encode's ($(cat "$W/plan.out"))" ||
    fail "plan: read_voxels $rv, tvpal-encode reads $rb bytes"
# The ring of one pass, as tvpal-encode's plan line words it.
ring=$(tr ' ' '\n' < "$W/plan.out" | sed -n 's/^ring_bytes=//p')
mib=$(awk -v b="$ring" 'BEGIN { printf "%.1f MiB", b / 1048576 }')
grep -q "would need $mib," "$W/enc.err" && ok "one pass would need $mib, as tvpal-encode says" ||
    fail "ring_bytes $ring ($mib): tvpal-encode says $(cat "$W/enc.err")"

# Levels after level 0 (the plan cannot hold them beside its passes),
# under the smallest limit tvpal-encode takes for them, plus 1 MiB.
m=$("$ENC" --axes xyz -j 1 --levels 2 --mem-limit $LIM --dims $D --window 4 -o "$W/none" "$@" 2>&1 |
    sed -n 's/.*give --mem-limit \([0-9]*\)K.*/\1/p')
LLIM=$(((${m:-0} + 1024) * 1024))
"$ENC" --axes xyz -q -j 1 --levels 2 --mem-limit $LLIM --dims $D --window 4 -o "$W/lv-enc" "$@" \
    > /dev/null || fail "tvpal-encode --levels 2 under $LLIM"
"$API" --whole --axes 7 --threads 1 --levels 2 --mem-limit $LLIM --dims $D --window 4 \
    -o "$W/lv-api" "$@" > "$W/lv.out" 2>&1 || fail "api-files --levels 2: $(cat "$W/lv.out")"
grep -q "levels_inline=0" "$W/lv.out" && shards_same "$W/lv-enc" "$W/lv-api" &&
    ok "levels after level 0 ($(sed -n 's/^passes=\([0-9]*\).*/\1/p' "$W/lv.out") passes under $LLIM): tvpal-encode's shards" || fail "levels differ: $(cat "$W/lv.out")"

# uint16, big-endian.
i=0
for f in "$@"; do
    $PY -c "import sys, numpy as np; np.clip(np.fromfile(sys.argv[1], '<f4') * 2000 + 30000, 0, 65535).astype('>u2').tofile(sys.argv[2])" \
        "$f" "$W/in/u$i.u16" || fail "u16 file"
    i=$((i + 1))
done
"$ENC" --axes z -q -j 1 --type u16 --endian big --dims $D --window 4 -o "$W/u-enc" "$W"/in/u?.u16 \
    > /dev/null || fail "tvpal-encode --type u16 --endian big"
"$API" --type u16 --big-endian --axes 4 --threads 1 --dims $D --window 4 -o "$W/u-api" "$W"/in/u?.u16 \
    > "$W/u.out" 2>&1 || fail "api-files u16: $(cat "$W/u.out")"
shards_same "$W/u-enc" "$W/u-api" && ok "uint16 big-endian: tvpal-encode's shards" ||
    fail "uint16 big-endian: shards differ"

# Stopped after unit 30 (the fourth pass or later), run again: it
# continues at unit 30 and ends with the bytes of the run without a stop.
"$API" --stop-after 30 --axes 7 --threads 1 --mem-limit $LIM --dims $D --window 4 \
    -o "$W/res" "$@" > "$W/res1.out" 2>&1
rc=$?
[ $rc -eq 3 ] && [ -d "$W/res.partial" ] && [ ! -e "$W/res" ] ||
    fail "stopped: exit $rc, $(ls -d "$W"/res* 2>/dev/null): $(cat "$W/res1.out")"
"$API" --axes 7 --threads 1 --mem-limit $LIM --dims $D --window 4 -o "$W/res" "$@" \
    > "$W/res2.out" 2>&1 || fail "continued: $(cat "$W/res2.out")"
grep -q "^first_unit=30$" "$W/res2.out" && shards_same "$W/enc" "$W/res" &&
    ok "stopped after unit 30, continued there, the same shards" ||
    fail "continue: $(cat "$W/res2.out")"
finish
