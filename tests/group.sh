#!/bin/sh
# group: palette groups (tvpal-encode --group G, FORMAT.md 5.1, shard
# format_version 4).  A group of G z slices under one table is, bit for
# bit, the encoding of the same bytes read as a volume whose slices are
# G times taller (x fastest: z slices 4g .. 4g + 3 of 40x34 are one slice
# of 40x136): every decoded step of both agrees, in both schedules, with
# coded and plain chunks, 16-bit and auto tables.  Groups cut by slabs
# and the end of an axis (G = 3, two nodes, all axes) verify, decode as
# the FORMAT.md reader (tests/shard_decode.py) does, jump as they play and
# store fewer bits than no groups; a memory limit's passes write the
# bytes of one pass; the player draws them (GL = reference,
# jumps = playing, in-core = io_uring = pread, about 1/N uploads a step);
# --group 1 writes what no --group writes; bad values are refused.
. "$(dirname "$0")/lib.sh"
$PY -c "import numpy" 2>/dev/null || { echo "numpy missing (scripts/setup-deps installs python3-numpy)"; exit 99; }
command -v zstd > /dev/null || { echo "zstd missing (scripts/setup-deps installs zstd)"; exit 99; }
export PYTHONPATH="$TVPAL_SRCDIR/tests${PYTHONPATH:+:$PYTHONPATH}"
REPORT=$TVPAL_BUILDDIR/encoder/tvpal-report
CHK=$TVPAL_BUILDDIR/tests/tvpal-check
PC=$TVPAL_BUILDDIR/tests/tvpal-playcheck
T=11
"$GEN" --field turbulence --dims 40x34x24 --steps $T -o "$W/in" > /dev/null || fail gen

# steps DS AXIS: the SHA-256 of every decoded step.
steps() {
    t=0
    while [ $t -lt $T ]; do
        "$DEC" "$1" --step $t --axis "$2" -o - | sha256sum | cut -d' ' -f1
        t=$((t + 1))
    done
}
u32() { od -A n -t u4 -j "$2" -N 4 "$1" | tr -d ' '; }

# 1. Groups of 4 z slices = slices 4 times taller, exactly.
for opts in "" "--schedule staggered" "--table u16 --index-coding none" \
            "--window 2 --table f32"; do
    # shellcheck disable=SC2086
    "$ENC" -q --dims 40x34x24 --axes z --group 4 $opts -o "$W/g" "$W"/in/*.f32 > /dev/null \
        || fail "encode --group 4 $opts"
    # shellcheck disable=SC2086
    "$ENC" -q --dims 40x136x6 --axes z $opts -o "$W/tall" "$W"/in/*.f32 > /dev/null \
        || fail "encode 40x136x6 $opts"
    steps "$W/g" z > "$W/g.txt"
    steps "$W/tall" z > "$W/tall.txt"
    cmp -s "$W/g.txt" "$W/tall.txt" && ok "--group 4 ${opts:-(defaults)}: $T steps = the 40x136x6 encoding" \
        || fail "--group 4 ${opts:-(defaults)}: decoded steps differ from the 40x136x6 encoding"
    rm -rf "$W/g" "$W/tall"
done

# 2. The header says so; --group 1 is no group at all.
"$ENC" -q --dims 40x34x24 --axes z --group 4 -o "$W/g" "$W"/in/*.f32 > /dev/null || fail encode
s=$W/g/node-0/axis-z.tvps
[ "$(u32 "$s" 8)" = 4 ] && [ "$(u32 "$s" 92)" = 4 ] && ok "shard format_version 4, group 4" \
    || fail "header: version $(u32 "$s" 8) group $(u32 "$s" 92)"
grep -q -- '^options = .* --group 4' "$W/g/manifest.txt" && ok "manifest options say --group 4" \
    || fail "options: $(grep '^options' "$W/g/manifest.txt")"
"$REPORT" "$W/g" --json "$W/g.json" > "$W/report.txt" || fail "tvpal-report"
head -n 1 "$W/report.txt" | grep -q ', palette groups: z 4$' && grep -q '"groups": \[0, 0, 4\]' "$W/g.json" \
    && ok "tvpal-report names the groups (text and JSON)" || fail "report: $(head -n 1 "$W/report.txt")"
"$ENC" -q --dims 40x34x24 --axes z -o "$W/g0" "$W"/in/*.f32 > /dev/null || fail encode
"$ENC" -q --dims 40x34x24 --axes z --group 1 -o "$W/g1" "$W"/in/*.f32 > /dev/null || fail encode
cmp -s "$W/g0/node-0/axis-z.tvps" "$W/g1/node-0/axis-z.tvps" && [ "$(u32 "$W/g1/node-0/axis-z.tvps" 92)" = 0 ] \
    && ok "--group 1 writes the shard no --group writes (group field 0)" || fail "--group 1 differs"

# 3. Groups cut by slabs and axis ends: all axes, two nodes, G = 3.
D=40x34x24
"$ENC" -q --dims $D --axes xyz --nodes 2 --group 3 -o "$W/c" "$W"/in/*.f32 > /dev/null \
    || fail "encode --group 3 --nodes 2"
"$INFO" "$W/c" --verify > "$W/v.txt" 2>&1 && ok "--group 3 --nodes 2: tvpal-info --verify" \
    || { fail "verify"; cat "$W/v.txt" >&2; }
for a in x y z; do
    steps "$W/c" $a | awk '{ print $1 "  " NR - 1 }' > "$W/dec-$a.txt"
    $PY "$TVPAL_SRCDIR/tests/shard_decode.py" "$W/c" $a > "$W/ref-$a.txt" || fail "shard_decode $a"
    cmp -s "$W/dec-$a.txt" "$W/ref-$a.txt" && ok "axis $a: tvpal-decode = the FORMAT.md reader" \
        || fail "axis $a: tvpal-decode differs from tests/shard_decode.py"
done
# Chunks of several slices are really there, and cut where the slabs are
# (z: 24 slices, slabs 0..11 and 12..23, groups 0..2, 3..5, ...: group
# 9..11 whole in node 0; x: 40 slices, slabs 0..19 and 20..39: group
# 18..20 cut into 18..19 and 20).
$PY - "$W/c" > "$W/spans.txt" <<'PY' || fail "chunk spans"
import sys, shard_decode as sd
for a in range(3):
    first = [c for c in sd.chunks(sys.argv[1], a) if c["wstart"] == 0]
    print("xyz"[a], " ".join(str(c["slices"]) for c in first
                              if c["part"] == 0))
PY
# Record 0 of each axis, in slice order, node 0 then node 1 (a chunk of
# k slices listed once, as k): z 24 = 8 groups, 4 per slab; x 40: node 0
# six groups and 18..19, node 1 slice 20 then 21..38 and 39.
[ "$(sed -n 's/^z //p' "$W/spans.txt")" = "3 3 3 3 3 3 3 3" ] &&
    [ "$(sed -n 's/^x //p' "$W/spans.txt")" = "3 3 3 3 3 3 2 1 3 3 3 3 3 3 1" ] \
    && ok "record 0's chunks: $(tr '\n' ';' < "$W/spans.txt")" \
    || fail "record 0's chunks: $(tr '\n' ';' < "$W/spans.txt")"
"$CHK" seqjump "$W/c" > "$W/sj.txt" 2>&1 && ok "jumps decode as sequential playback" \
    || { fail "seqjump"; cat "$W/sj.txt" >&2; }
"$ENC" -q --dims $D --axes xyz --nodes 2 -o "$W/c1" "$W"/in/*.f32 > /dev/null || fail encode
b1=$("$REPORT" -q "$W/c1" | tr ' ' '\n' | sed -n 's/^bpv=//p')
b3=$("$REPORT" -q "$W/c" | tr ' ' '\n' | sed -n 's/^bpv=//p')
awk -v a="$b3" -v b="$b1" 'BEGIN { exit !(a < b) }' && ok "bits per voxel-step: $b3 with groups of 3, $b1 without" \
    || fail "groups of 3 store $b3 bits per voxel-step, not fewer than $b1"

# Under a memory limit that makes passes, each pass holds whole groups:
# the bytes of one pass (a group cut by a pass was two chunks, two tables).
m=$("$ENC" --axes xyz -j 1 --mem-limit 1M --dims 40x34x24 --group 4 -o "$W/none" "$W"/in/*.f32 2>&1 |
    sed -n 's/.*give --mem-limit \([0-9]*\)K.*/\1/p')
"$ENC" -q --axes xyz -j 1 --dims 40x34x24 --group 4 -o "$W/one" "$W"/in/*.f32 > /dev/null || fail "encode one pass"
"$ENC" --axes xyz -j 1 --mem-limit "$((${m:-0} + 256))K" --dims 40x34x24 --group 4 -o "$W/lim" "$W"/in/*.f32 \
    > "$W/lim.out" 2> "$W/lim.err" || fail "encode under the limit: $(cat "$W/lim.err")"
p=$(sed -n 's/.* passes=\([0-9]*\).*/\1/p' "$W/lim.out")
[ "${p:-1}" -gt 3 ] && diff -r "$W/one" "$W/lim" > /dev/null \
    && ok "$p passes under --mem-limit $((${m:-0} + 256))K: the one-pass dataset" \
    || fail "under the limit: ${p:-?} passes, $(diff -rq "$W/one" "$W/lim" | head -n 2)"

# 4. The player on groups (GL vs reference, jumps, backward, I/O paths,
#    uploads per step; on
#    play-core's smooth blobs: GL matches the reference within its
#    tolerance there, not on turbulence, groups or not.)
if [ -x "$PC" ]; then
    "$GEN" --field blobs --dims 40x34x28 --steps $T -o "$W/blobs" > /dev/null || fail gen
    "$ENC" -q --dims 40x34x28 --group 4 -o "$W/p" "$W"/blobs/*.f32 > /dev/null || fail encode
    "$PC" "$W/p" > "$W/pc.txt" 2>&1 && ok "player: $(tail -n 1 "$W/pc.txt")" \
        || { fail "tvpal-playcheck on groups"; cat "$W/pc.txt" >&2; }
    "$TVPAL_BUILDDIR/player/app/tvpal-play" "$W/p" --headless --size 64x64 --steps 0:1 \
        > /dev/null 2> "$W/start.txt" || fail "tvpal-play"
    grep -q 'window 4 joined, palette groups of 4[;,]' "$W/start.txt" \
        && ok "tvpal-play's start-up line names the groups" || fail "start-up line: $(cat "$W/start.txt")"
else
    echo "built without OSMesa/libpng: the player's part skipped"
fi

# 5. Bad values.
for g in 0 1025 x; do
    "$ENC" -q --dims $D --group $g -o "$W/bad" "$W"/in/*.f32 > "$W/out.txt" 2>&1
    rc=$?
    [ $rc -eq 2 ] && grep -q -- '--group' "$W/out.txt" && [ ! -e "$W/bad" ] \
        && ok "--group $g refused (exit 2)" || fail "--group $g: exit $rc: $(cat "$W/out.txt")"
done
finish
