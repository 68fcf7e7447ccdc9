#!/bin/sh
# convert-paths: the encoder's two conversions of float32 input agree.
# Host-order float32 with no --missing takes a one-pass vector path
# (encode_source.c, convert_f32_plain); --missing with a value the data
# lack takes the general one.  Both give the same shards and the same
# statistics (value_min, value_max, histogram), also where the extreme is
# a zero of either sign (the first in reading order is kept, as the
# general path keeps it), where rows are not a multiple of 4 values, and
# for big-endian input (always the general path) against its byte-swapped
# little-endian copy.  A value beyond 1e37 or an infinity is still refused
# naming the voxel.
. "$(dirname "$0")/lib.sh"
D=13x7x5
$PY - "$W" <<'PY' || exit 99
import sys, numpy as np
w = sys.argv[1]; n = 13 * 7 * 5
rng = np.random.default_rng(3)
def series(name, first, second):
    for t in range(3):
        v = rng.normal(size=n).astype(np.float32)
        if second is None:
            v = -np.abs(v)
        else:
            v = np.abs(v)
        # Both zeros in one row, in lanes whose order a vector's
        # reduction would swap (x = 1: lane 1; x = 4: lane 0).
        v[1] = first; v[4] = second if second is not None else -first
        v.astype("<f4").tofile(f"{w}/{name}_{t}.f32")
        v.astype(">f4").tofile(f"{w}/{name}_{t}.be")
series("negfirst", np.float32(-0.0), np.float32(0.0))
series("posfirst", np.float32(0.0), np.float32(-0.0))
series("maxzero", np.float32(-0.0), None)   # -0 then +0, the rest < 0
v = rng.normal(size=n).astype(np.float32); v[77] = 2e37
v.astype("<f4").tofile(f"{w}/big_0.f32")
v[77] = np.inf
v.astype("<f4").tofile(f"{w}/inf_0.f32")
PY
stats() { grep -E "^(value_min|value_max|histogram) " "$1/manifest.txt"; }
for c in negfirst posfirst maxzero; do
    "$ENC" -q -j 1 --dims $D --window 2 -o "$W/$c-fast" "$W"/${c}_*.f32 > /dev/null || fail "$c: fast encode"
    "$ENC" -q -j 1 --dims $D --window 2 --missing 7777 -o "$W/$c-gen" "$W"/${c}_*.f32 > /dev/null || fail "$c: general encode"
    "$ENC" -q -j 1 --dims $D --window 2 --endian big -o "$W/$c-be" "$W"/${c}_*.be > /dev/null || fail "$c: big-endian encode"
    stats "$W/$c-fast" > "$W/s1"; stats "$W/$c-gen" > "$W/s2"; stats "$W/$c-be" > "$W/s3"
    cmp -s "$W/s1" "$W/s2" && cmp -s "$W/s1" "$W/s3" \
        && cmp -s "$W/$c-fast/node-0/axis-z.tvps" "$W/$c-gen/node-0/axis-z.tvps" \
        && cmp -s "$W/$c-fast/node-0/axis-z.tvps" "$W/$c-be/node-0/axis-z.tvps" \
        && ok "$c: both paths give the same shards and statistics" \
        || fail "$c: paths differ: $(cat "$W/s1" "$W/s2" "$W/s3" | grep value_)"
done
grep -q "^value_min = -0$" "$W/negfirst-fast/manifest.txt" && grep -q "^value_min = 0$" "$W/posfirst-fast/manifest.txt" \
    && grep -q "^value_max = -0$" "$W/maxzero-fast/manifest.txt" \
    && ok "a zero extreme is the first zero read" || fail "zero extremes: $(grep -h value_ "$W"/*-fast/manifest.txt)"
expect_exit 2 "big_0.f32.*voxel \\(12,5,0\\).*exceeds" "$ENC" -q --dims $D -o "$W/big" "$W/big_0.f32"
expect_exit 2 "inf_0.f32.*infinite value at voxel \\(12,5,0\\)" "$ENC" -q --dims $D -o "$W/inf" "$W/inf_0.f32"
finish
