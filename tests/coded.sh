#!/bin/sh
# coded: coded chunks end to end (FORMAT.md 6.11, tvpal-encode
# --index-coding).  The same series encoded with the default (zstd) and
# with none, in the staggered schedule: the coded shards are format_version
# 2 and smaller, the plain ones version 1 (in the joined schedule, the
# default, both are version 3); every step of every axis and level decodes to the same
# bits; tvpal-info counts the coded chunks; tvpal-report's split of the
# bits on disk adds up and names what coding saves; tvpal-play draws the same
# frames streamed and in-core, through jumps, from both, and streaming
# reads fewer bytes from the coded one; --index-level 19 is no larger;
# bad option values are refused; a coded frame damaged under a valid CRC
# is reported (file, record, slice) by tvpal-info --verify, tvpal-decode
# and tvpal-play, which draws every frame and exits 1.
. "$(dirname "$0")/lib.sh"
PLAY=$TVPAL_BUILDDIR/player/app/tvpal-play
D=48x40x24
T=10
"$GEN" --field turbulence --dims $D --steps $T -o "$W/in" > /dev/null || fail gen
enc() { # NAME OPTIONS...
    name=$1; shift
    "$ENC" -q --dims $D --window 4 --axes xyz --nodes 2 --levels 1 --schedule staggered "$@" \
        -o "$W/$name" "$W"/in/*.f32 \
        > "$W/enc-$name.txt" 2>&1 || fail "encode $name: $(cat "$W/enc-$name.txt")"
}
enc coded
enc plain --index-coding none
enc l19 --index-level 19
ver() { od -A n -t u4 -j 8 -N 4 "$1" | tr -d ' '; }
v2=0 v1=0
for f in "$W"/coded/node-*/axis-*.tvps "$W"/coded/level-1/node-*/axis-*.tvps; do
    [ "$(ver "$f")" = 2 ] && v2=$((v2 + 1))
done
for f in "$W"/plain/node-*/axis-*.tvps "$W"/plain/level-1/node-*/axis-*.tvps; do
    [ "$(ver "$f")" = 1 ] && v1=$((v1 + 1))
done
[ $v2 = 12 ] && [ $v1 = 12 ] && ok "12 coded shards of format_version 2, 12 plain of 1" \
    || fail "format versions: $v2 coded shards of version 2, $v1 plain of 1 (12 each expected)"
"$ENC" -q --dims $D --window 4 --axes xyz --levels 1 -o "$W/joined" "$W"/in/*.f32 > /dev/null \
    || fail "encode joined"
v3=0
for f in "$W"/joined/node-*/axis-*.tvps "$W"/joined/level-1/node-*/axis-*.tvps; do
    [ "$(ver "$f")" = 3 ] && v3=$((v3 + 1))
done
[ $v3 = 6 ] && "$INFO" "$W/joined" --verify > /dev/null && ok "joined schedule (the default): 6 shards of format_version 3, coded, verify" \
    || fail "joined: $v3 shards of version 3 (6 expected)"
bytes() { du -b -c "$1"/node-*/*.tvps | tail -n 1 | cut -f1; }
bc=$(bytes "$W/coded") bp=$(bytes "$W/plain") b19=$(bytes "$W/l19")
[ "$bc" -lt "$bp" ] && [ "$b19" -le "$bc" ] \
    && ok "shards: $bc bytes coded (level 19: $b19), $bp plain" \
    || fail "shards: $bc bytes coded, $b19 at level 19, $bp plain"
grep -q -- "--index-coding none" "$W/plain/manifest.txt" && grep -q -- "--index-level 19" "$W/l19/manifest.txt" \
    && ok "the manifests' options say --index-coding none and --index-level 19" \
    || fail "options lines: $(grep '^options' "$W/plain/manifest.txt" "$W/l19/manifest.txt")"
nc=$("$INFO" "$W/coded" | sed -n 's/^chunks_coded = \([0-9]*\).*/\1/p')
np=$("$INFO" "$W/plain" | sed -n 's/^chunks_coded = \([0-9]*\).*/\1/p')
[ "${nc:-0}" -gt 0 ] && [ "$np" = 0 ] && ok "tvpal-info: chunks_coded $nc coded, 0 plain" \
    || fail "tvpal-info chunks_coded: coded '$nc', plain '$np'"
# tvpal-report's split of the bits on disk: the plain indices and tables
# (the same in both), minus what coding saves (coded only), plus a rest
# that is not negative, add up to the total.
for name in coded plain; do
    "$REP" "$W/$name" > "$W/rep-$name.txt" 2>&1 || fail "tvpal-report $name: $(tail -n 3 "$W/rep-$name.txt")"
    sed -n 's/^bits per voxel-timestep on disk: //p' "$W/rep-$name.txt" > "$W/split-$name.txt"
done
awk -v c="$(cat "$W/split-coded.txt")" -v p="$(cat "$W/split-plain.txt")" 'BEGIN {
        nc = split(c, a, " "); np = split(p, b, " ")
        # coded: T = indices I + tables B - saved by coding them S + headers, padding and manifests and levels R
        sum = a[4] + a[7] - a[13] + a[nc]
        psum = b[4] + b[7] + b[np]
        ok = a[9] == "saved" && a[nc] >= 0 && b[np] >= 0 && p !~ /saved/ && a[13] > 0
        ok = ok && a[4] == b[4] && a[7] == b[7]
        ok = ok && sum - a[1] < 5e-4 && a[1] - sum < 5e-4 && psum - b[1] < 5e-4 && b[1] - psum < 5e-4
        exit !ok }' \
    && ok "tvpal-report: bits on disk = indices + tables - saved by coding + rest ($(cat "$W/split-coded.txt"))" \
    || fail "tvpal-report split: coded '$(cat "$W/split-coded.txt")', plain '$(cat "$W/split-plain.txt")'"
"$INFO" "$W/coded" --verify > "$W/verify.txt" 2>&1 && grep -q "^verify: ok" "$W/verify.txt" \
    && ok "the coded dataset verifies" || fail "verify: $(cat "$W/verify.txt")"

# Every step of every axis, both levels: the same bits.
same=1
for lv in 0 1; do
    for a in x y z; do
        t=0
        while [ $t -lt $T ]; do
            "$DEC" "$W/coded" --step $t --axis $a --level $lv -o "$W/c.f32" 2> "$W/dec.err" || { same=0; fail "decode coded: $(cat "$W/dec.err")"; }
            "$DEC" "$W/plain" --step $t --axis $a --level $lv -o "$W/p.f32" 2> "$W/dec.err" || { same=0; fail "decode plain: $(cat "$W/dec.err")"; }
            cmp -s "$W/c.f32" "$W/p.f32" || { same=0; fail "level $lv axis $a step $t: coded decodes differently"; }
            t=$((t + 1))
        done
    done
done
[ $same = 1 ] && ok "coded = plain, bit for bit: $T steps x 3 axes x 2 levels"

# The player: the same frames from both, streamed and in-core, with jumps.
if [ -x "$PLAY" ]; then
    play() { # NAME DATASET MODE
        "$PLAY" "$2" -m $3 --headless --renderer cpu --size 64x48 --view +x --jumps 3 --loop 2 \
            -o "$W/f-$1" > "$W/$1.out" 2>&1 || fail "play $1: $(cat "$W/$1.out")"
        rm -f "$W/f-$1/timing.csv"
    }
    for m in stream incore; do
        play c-$m "$W/coded" $m
        play p-$m "$W/plain" $m
    done
    n=$(ls "$W/f-c-stream" | wc -l)
    if [ "$n" -gt 0 ] && diff -r "$W/f-c-stream" "$W/f-p-stream" > /dev/null &&
        diff -r "$W/f-c-incore" "$W/f-p-incore" > /dev/null &&
        diff -r "$W/f-c-stream" "$W/f-c-incore" > /dev/null; then
        ok "tvpal-play: $n frames alike, coded and plain, streamed and in-core"
    else
        fail "tvpal-play: frames differ between coded and plain or stream and in-core"
    fi
    rc=$(sed -n 's/.*bytes_read=\([0-9]*\).*/\1/p' "$W/c-stream.out")
    rp=$(sed -n 's/.*bytes_read=\([0-9]*\).*/\1/p' "$W/p-stream.out")
    [ -n "$rc" ] && [ -n "$rp" ] && [ "$rc" -lt "$rp" ] \
        && ok "streaming read $rc bytes coded, $rp plain" || fail "bytes_read: coded '$rc', plain '$rp'"
else
    echo "tvpal-play not built (no libpng): its checks skipped"
fi

# Bad values.
expect_exit 2 "index-coding.*zstd or none" "$ENC" -q --dims $D --index-coding lz4 -o "$W/bad" "$W"/in/*.f32
expect_exit 2 "index-level.*1\.\.19" "$ENC" -q --dims $D --index-level 20 -o "$W/bad" "$W"/in/*.f32
expect_exit 2 "index-level.*1\.\.19" "$ENC" -q --dims $D --index-level 0 -o "$W/bad" "$W"/in/*.f32
expect_exit 2 "schedule \"aligned\": expected joined or staggered" \
    "$ENC" -q --dims $D --schedule aligned -o "$W/bad" "$W"/in/*.f32

# A coded frame damaged, the record's CRCs made valid again (a forger's or
# a bug's, not the disk's): record 2 of node-0's z shard, its first coded
# chunk's zstd magic.
cp -R "$W/coded" "$W/bad"
$PY - "$W/bad/node-0/axis-z.tvps" <<'PY' || fail "could not plant the bad frame"
import struct, sys
p = sys.argv[1]
b = bytearray(open(p, "rb").read())
def crc32c(data):
    c = 0xFFFFFFFF
    for x in data:
        c ^= x
        for _ in range(8):
            c = (c >> 1) ^ (0x82F63B78 if c & 1 else 0)
    return c ^ 0xFFFFFFFF
idx, = struct.unpack_from("<Q", b, 72)
off, _ = struct.unpack_from("<QQ", b, idx + 64)
count, = struct.unpack_from("<I", b, off + 8)
pay, = struct.unpack_from("<Q", b, off + 16)
pos = off + 64
for _ in range(count):
    flags, = struct.unpack_from("<I", b, pos + 28)
    coded, = struct.unpack_from("<I", b, pos + 56)
    if flags & 4:
        slice_, = struct.unpack_from("<I", b, pos + 4)
        b[pos + 64] ^= 1
        break
    wl, w, h = struct.unpack_from("<3I", b, pos + 12)
    e = 2 if flags & 2 else 4
    pos += 64 + wl * 256 * e + (w * h + 63) // 64 * 64
else:
    sys.exit("no coded chunk in record 2")
c = crc32c(b[off + 64:off + 64 + pay])
struct.pack_into("<I", b, off + 24, c)
struct.pack_into("<I", b, off + 60, crc32c(b[off:off + 60]))
struct.pack_into("<I", b, idx + 64 + 24, c)
struct.pack_into("<I", b, 88, crc32c(b[idx:]))
struct.pack_into("<I", b, 4092, crc32c(b[:4092]))
open(p, "wb").write(b)
print(slice_)
PY
"$INFO" "$W/bad" --verify > "$W/v.txt" 2>&1
[ $? = 1 ] && grep -q "axis-z.tvps.*record 2: slice [0-9]*: coded chunk" "$W/v.txt" \
    && ok "tvpal-info --verify names the bad frame: $(grep -o 'record 2: slice [0-9]*: coded chunk[^(]*' "$W/v.txt" | head -1)" \
    || fail "tvpal-info --verify: $(cat "$W/v.txt")"
expect_exit 2 "node-0/axis-z.tvps: record 2: slice [0-9]+: coded chunk" "$DEC" "$W/bad" --step 3 --axis z -o "$W/x.f32"
if [ -x "$PLAY" ]; then
    for m in stream incore; do
        "$PLAY" "$W/bad" -m $m --headless --renderer cpu --size 64x48 --steps 0:$((T - 1)) \
            -o "$W/f-bad-$m" > "$W/bad-$m.out" 2>&1
        rc=$?
        n=$(ls "$W/f-bad-$m"/*.png 2>/dev/null | wc -l)
        [ $rc = 1 ] && [ "$n" = $T ] && grep -q "record 2: slice [0-9]*: coded chunk" "$W/bad-$m.out" \
            && ok "tvpal-play -m $m: the bad frame reported, $n frames drawn, exit 1" \
            || fail "tvpal-play -m $m on the bad frame: exit $rc, $n frames: $(cat "$W/bad-$m.out")"
    done
fi
finish
