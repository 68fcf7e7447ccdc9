#!/bin/sh
# info-histogram: tvpal-info --histogram prints the manifest's 64 bins, one
# line each (bin, value range, count, fraction, bar), with counts equal to
# the manifest's, bins that tile [value_min, value_max], fractions that are
# the counts' shares, and a summary whose count is the voxel count minus
# the missing values (a dataset with and one without missing voxels);
# --histogram with --verify is refused (exit 2).
. "$(dirname "$0")/lib.sh"
D=12x10x8
"$GEN" --field blobs --dims $D --steps 3 -o "$W/in" > /dev/null || fail gen
mkdir -p "$W/nan"
# The same volumes with 7 voxels of each step missing (NaN).
$PY - "$W" <<'PY' || fail "inputs"
import glob, struct, sys
w = sys.argv[1]
for f in sorted(glob.glob(w + "/in/*.f32")):
    b = open(f, "rb").read()
    v = list(struct.unpack("<%df" % (len(b) // 4), b))
    for i in range(0, 7 * 97, 97):
        v[i] = float("nan")
    open(w + "/nan/" + f.rsplit("/", 1)[1], "wb").write(struct.pack("<%df" % len(v), *v))
PY
"$ENC" -q --dims $D -o "$W/ds" "$W"/in/*.f32 > /dev/null || fail encode
"$ENC" -q --dims $D -o "$W/ds-nan" "$W"/nan/*.f32 > /dev/null || fail "encode nan"
for ds in ds:0 ds-nan:21; do
    name=${ds%%:*} missing=${ds#*:}
    "$INFO" "$W/$name" --histogram > "$W/$name.txt" || { fail "$name: exit $?"; continue; }
    $PY - "$W/$name.txt" "$W/$name/manifest.txt" "$missing" <<'PY' \
        && ok "$name: histogram lines match the manifest" || fail "$name: $(cat "$W/$name.txt")"
import sys
lines = open(sys.argv[1]).read().splitlines()
man = dict(l.split(" = ", 1) for l in open(sys.argv[2]).read().splitlines()
           if " = " in l and not l.startswith("#"))
counts = [int(c) for c in man["histogram"].split()]
lo, hi = float(man["value_min"]), float(man["value_max"])
missing, values = int(sys.argv[3]), 12 * 10 * 8 * 3
assert lines[0].startswith("# histogram of ") and lines[1].startswith("# bin"), lines[:2]
bins = [l.split() for l in lines[2:-1]]
assert len(bins) == 64, len(bins)
total = sum(counts)
prev_hi = lo
for i, f in enumerate(bins):
    assert int(f[0]) == i, f
    assert float(f[1]) == prev_hi or abs(float(f[1]) - prev_hi) <= 1e-8 * (hi - lo), (f, prev_hi)
    assert abs(float(f[2]) - float(f[1]) - (hi - lo) / 64) <= 1e-7 * (hi - lo), f
    assert int(f[3]) == counts[i], (f, counts[i])
    assert abs(float(f[4]) - counts[i] / total) <= 5e-7, f
    assert (len(f) == 6 and set(f[5]) == {"*"}) if counts[i] else len(f) == 5, f
    prev_hi = float(f[2])
assert prev_hi == hi, (prev_hi, hi)
assert lines[-1] == "histogram: bins=64 count=%d missing=%d values=%d" % (
    values - missing, missing, values), (lines[-1], total)
assert total == values - missing, (total, values, missing)
PY
done
expect_exit 2 "--histogram: one at a time" "$INFO" "$W/ds" --histogram --verify
expect_exit 2 "manifest" "$INFO" "$W/none" --histogram
finish
