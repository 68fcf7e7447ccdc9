#!/bin/sh
# play-io: the streamed reads really use io_uring and O_DIRECT where the
# kernel and the file system offer them (probed here with the system
# calls themselves, not through tvpal), and say so: the summary's io= and
# direct=, the start line.  --io uring and --direct refuse a fallback
# (exit 1, naming why); without them a fallback is a warning.  Where the
# kernel or file system lacks a feature, that part is skipped out loud,
# and the test exits 77 when it could check neither.
. "$(dirname "$0")/lib.sh"
PLAY=$TVPAL_BUILDDIR/player/app/tvpal-play
[ -x "$PLAY" ] || { echo "built without OSMesa/libpng: skipped"; exit 77; }
"$PLAY" --version | grep -q "uring: yes" || URING_BUILT=no
D=16x16x16
"$GEN" --field blobs --dims $D --steps 6 -o "$W/in" > /dev/null || fail gen
"$ENC" -q --dims $D --window 2 -o "$W/ds" "$W"/in/*.f32 > /dev/null || fail encode
# io_uring_setup(2) and open(O_DIRECT) asked directly of the kernel.
probe=$("$PY" - "$W/ds/node-0/axis-z.tvps" <<'PY'
import ctypes, errno, os, sys
libc = ctypes.CDLL(None, use_errno=True)
params = ctypes.create_string_buffer(120)
fd = libc.syscall(425, 4, params)        # __NR_io_uring_setup on x86-64 and arm64
uring = "yes" if fd >= 0 else "no:" + errno.errorcode.get(ctypes.get_errno(), "?")
if fd >= 0:
    os.close(fd)
try:
    os.close(os.open(sys.argv[1], os.O_RDONLY | os.O_DIRECT))
    direct = "yes"
except OSError as e:
    direct = "no:" + errno.errorcode.get(e.errno, "?")
print(uring, direct)
PY
) || { echo "probe failed"; exit 99; }
uring=${probe% *}
direct=${probe#* }
echo "kernel: io_uring $uring; file system of $W: O_DIRECT $direct"
[ "$(uname -m)" = x86_64 ] || [ "$(uname -m)" = aarch64 ] || uring="no:unknown-arch"
checked=0
# 16 steps of 2 MiB records (N = 4), for the reads of jumps and buffers.
"$GEN" --field turbulence --dims 256x256x32 --steps 16 -o "$W/big" > /dev/null || fail "gen big"
"$ENC" -q --dims 256x256x32 --window 4 -o "$W/dsb" "$W"/big/*.f32 > /dev/null || fail "encode big"
run() { "$PLAY" "$W/ds" --headless -q --size 16x16 "$@" -o "$W/f" 2> "$W/e.txt"; }
if [ "$uring" = yes ] && [ "${URING_BUILT:-yes}" = yes ]; then
    line=$(run --io uring) && [ "$(kv io "$line")" = uring ] \
        && ok "io_uring in use (--io uring)" || fail "--io uring: $line $(cat "$W/e.txt")"
    line=$(run) && [ "$(kv io "$line")" = uring ] && [ "$(kv mode "$line")" = uring ] \
        && ok "io_uring by default" || fail "default: $line"
    # A jump's reads (the N records it needs, then the prefetch, 2 MiB
    # records in 1 MiB pieces) go to the kernel in one submission.
    line=$("$PLAY" "$W/dsb" --headless -q --size 32x32 --rotate 0,0 --io uring --jumps 1 \
        --steps 0:15 --renderer none 2> "$W/e.txt")
    n=$(kv io_submits "$line")
    [ -n "$n" ] && [ "$n" -le 16 ] && ok "16 jumps: $n submissions, at most one a frame (batched)" \
        || fail "16 jumps: ${n:-?} submissions: $line $(cat "$W/e.txt")"
    # --read-ahead 1 (MiB, under one 2 MiB record): a jump's records go
    # to the device one at a time, each as the one before it lands, so a
    # jump needing several makes several submissions.
    line=$("$PLAY" "$W/dsb" --headless -q --size 32x32 --rotate 0,0 --io uring --jumps 1 \
        --steps 0:15 --renderer none --read-ahead 1 2> "$W/e.txt")
    n1=$(kv io_submits "$line")
    [ -n "$n1" ] && [ "$n1" -gt "$n" ] \
        && ok "--read-ahead 1: 16 jumps in $n1 submissions (records in turn), against $n" \
        || fail "--read-ahead 1: ${n1:-?} submissions, not more than $n: $line $(cat "$W/e.txt")"
    # A jump reads only the records its frame needs (at most the N whose
    # windows hold step t, FORMAT.md 5: with the joined schedule, the
    # shard's header field at 68, record 0 for t < 2N - 1): the prefetch
    # goes to the device after them, from the
    # stager, so that it does not share the device with the reads the
    # frame waits for.
    "$PLAY" "$W/dsb" --headless -q --size 32x32 --rotate 0,0 --jumps 3 --renderer none \
        --csv "$W/jumps.csv" > /dev/null 2> "$W/e.txt" || fail "jumps every 3rd frame"
    r=$("$PY" - "$W/dsb/node-0/axis-z.tvps" "$W/jumps.csv" 4 <<'PY'
import csv, struct, sys
b = open(sys.argv[1], "rb").read()
idx, n = struct.unpack_from("<Q", b, 72)[0], int(sys.argv[3])
joined = struct.unpack_from("<I", b, 68)[0] == 1
def start(r, t):  # the window of a slice of phase r holding t
    first = n + r if joined else r
    return 0 if t < first else t - (t - r) % n
sizes = []
while idx + 32 * (len(sizes) + 1) <= len(b):
    size = struct.unpack_from("<Q", b, idx + 32 * len(sizes) + 8)[0]
    if size == 0:
        break
    sizes.append(size)
jumps, over = 0, []
for row in csv.DictReader(open(sys.argv[2])):
    if row["jump"] == "1":
        jumps += 1
        t = int(row["step"])
        bound = sum(sizes[q] for q in set(start(r, t) for r in range(n)))
        if int(row["bytes_read"]) > bound:
            over.append("step %d: %s > %d" % (t, row["bytes_read"], bound))
print(jumps, len(over), "; ".join(over[:3]))
PY
)
    set -- $r
    [ "${1:-0}" -gt 0 ] && [ "$2" = 0 ] && ok "$1 jumps: none read more than its N records" \
        || fail "jumps reading the prefetch too: $r"
    # The record buffers are registered with io_uring (fixed buffers): the
    # stager's reads then skip pinning pages per read.  Root (or any user
    # whose RLIMIT_MEMLOCK allows it) gets them; others are told why on the
    # start line, and read as before.
    line=$(run) && fx=$(kv fixed "$line") && nfx=$(kv fixed_reads "$line")
    if [ "$(id -u)" = 0 ] || [ "$(ulimit -l)" = unlimited ]; then
        [ "$fx" = yes ] && [ "${nfx:-0}" -gt 0 ] \
            && ok "fixed buffers: fixed=yes, $nfx reads into them" \
            || fail "fixed buffers: $line $(cat "$W/e.txt")"
        "$PLAY" "$W/ds" --headless --size 16x16 -o "$W/f" 2>&1 >/dev/null | grep -q "O_DIRECT [a-z]*, fixed buffers yes)" \
            && ok "the start line says fixed buffers yes" || fail "start line: no fixed buffers"
    else
        [ "$fx" = yes ] || "$PLAY" "$W/ds" --headless --size 16x16 -o "$W/f" 2>&1 >/dev/null \
            | grep -q "fixed buffers no (io_uring_register_buffers" \
            && ok "fixed buffers: $fx (not root), said" || fail "fixed buffers refused, not said: $line"
    fi
    line=$(run --mode incore) && [ "$(kv fixed "$line")" = no ] && [ "$(kv fixed_reads "$line")" = 0 ] \
        && ok "in-core: no record buffers, fixed=no" || fail "in-core fixed: $line"
    checked=$((checked + 1))
else
    echo "io_uring not offered here ($uring): its checks are skipped"
    expect_exit 1 "io_uring unavailable" "$PLAY" "$W/ds" --headless -q --size 16x16 --io uring -o "$W/f"
    line=$(run) && [ "$(kv io "$line")" = pread ] && grep -q "warning: io_uring unavailable" "$W/e.txt" \
        && ok "fallback to pread, with a warning" || fail "fallback: $line $(cat "$W/e.txt")"
fi
if [ "$direct" = yes ]; then
    line=$(run --direct) && [ "$(kv direct "$line")" = yes ] \
        && ok "O_DIRECT on every shard (--direct)" || fail "--direct: $line $(cat "$W/e.txt")"
    line=$(run) && [ "$(kv direct "$line")" = yes ] && ! grep -q warning "$W/e.txt" \
        && ok "O_DIRECT by default, no warning" || fail "default direct: $line $(cat "$W/e.txt")"
    checked=$((checked + 1))
else
    echo "O_DIRECT not offered by this file system ($direct): its checks are skipped"
    expect_exit 1 "refuses O_DIRECT" "$PLAY" "$W/ds" --headless -q --size 16x16 --direct -o "$W/f"
    line=$(run) && [ "$(kv direct "$line")" = no ] && grep -q "warning: O_DIRECT refused" "$W/e.txt" \
        && ok "fallback to the page cache, with a warning" || fail "direct fallback: $line $(cat "$W/e.txt")"
fi
line=$(run --no-direct) && [ "$(kv direct "$line")" = no ] && ok "--no-direct: direct=no" || fail "--no-direct: $line"
line=$(run --io pread) && [ "$(kv io "$line")" = pread ] && ok "--io pread: io=pread" || fail "--io pread: $line"
# Playing forward, a stream reads into the buffers of the N records shown,
# the P prefetched and the one staged, N + P + 1, and no more: a buffer's
# first read faults in its pages (the others are for jumps).  Jumps may
# use them all, 2N + 2P + 1.
for io in uring pread; do
    [ $io = uring ] && { [ "$uring" = yes ] && [ "${URING_BUILT:-yes}" = yes ] || continue; }
    for pf in 4 8; do
        line=$("$PLAY" "$W/dsb" --headless -q --size 32x32 --renderer none --io $io \
            --prefetch $pf 2> "$W/e.txt") && nb=$(kv buffers "$line") \
            && [ "$nb" -gt 0 ] && [ "$nb" -le $((4 + pf + 1)) ] \
            && ok "$io, prefetch $pf: 16 steps forward in $nb buffers (N + P + 1 = $((4 + pf + 1)))" \
            || fail "$io, prefetch $pf: ${nb:-?} buffers: $line $(cat "$W/e.txt")"
    done
done
line=$("$PLAY" "$W/dsb" --headless -q --size 32x32 --renderer none --jumps 1 2> "$W/e.txt") \
    && nb=$(kv buffers "$line") && [ "$nb" -gt 9 ] && [ "$nb" -le 17 ] \
    && ok "16 jumps: $nb buffers (at most 2N + 2P + 1 = 17)" \
    || fail "16 jumps: ${nb:-?} buffers: $line $(cat "$W/e.txt")"
line=$(run --mode incore) && [ "$(kv buffers "$line")" = 0 ] \
    && ok "in-core: no record buffers (buffers=0)" || fail "in-core buffers: $line"
expect_exit 2 "choose one" "$PLAY" "$W/ds" --headless -q --direct --no-direct -o "$W/f"
"$PLAY" "$W/ds" --headless --size 16x16 -o "$W/f" 2>&1 >/dev/null | grep -Eq "data streamed \((uring|pread), O_DIRECT (yes|no|some), fixed buffers (yes|no|some)" \
    && ok "the start line names the I/O path" || fail "start line"
# A read that fails (EIO, injected by tvpal_io's test hook at a byte of
# record 2 of the z shard): every mode and backend reports the real cause
# for that record, plays on with the slices' previous data, and exits 1.
off=$("$PY" - "$W/ds/node-0/axis-z.tvps" <<'PY'
import struct, sys
b = open(sys.argv[1], "rb").read()
idx = struct.unpack_from("<Q", b, 72)[0]
print(struct.unpack_from("<Q", b, idx + 32 * 2)[0] + 100)
PY
)
for mode in stream incore; do
    for io in auto pread; do
        TVPAL_IO_FAULT_OFFSET=$off "$PLAY" "$W/ds" --headless -q --size 16x16 --rotate 0,0 \
            --mode $mode --io $io -o "$W/fe" > "$W/o.txt" 2> "$W/e.txt"
        rc=$?
        frames=$(ls "$W/fe" | grep -c png)
        if [ $rc -eq 1 ] && grep -q "axis-z.tvps: record 2: Input/output error" "$W/e.txt" \
            && ! grep -q "CRC" "$W/e.txt" && [ "$frames" -eq 6 ]; then
            ok "EIO in record 2, $mode/$io: reported as such, 6 frames, exit 1"
        else
            fail "EIO, $mode/$io: exit $rc, $frames frames: $(cat "$W/e.txt")"
        fi
        mv "$W/fe" "$W/fe-$mode-$io"
    done
done
same=1
for f in "$W"/fe-stream-auto/*.png; do
    for d in fe-stream-pread fe-incore-auto fe-incore-pread; do
        cmp -s "$f" "$W/$d/$(basename "$f")" || same=0
    done
done
[ $same = 1 ] && ok "EIO: the four runs draw the same frames (one policy)" || fail "EIO: the modes draw different frames"
[ $failures -eq 0 ] && [ $checked -eq 0 ] && { echo "neither io_uring nor O_DIRECT offered here: skipped"; exit 77; }
finish
