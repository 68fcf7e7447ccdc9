#!/bin/sh
# bad-input: each bad input gets exit 2, a message naming the file or option
# and what was expected, and leaves no output (nor OUTDIR.partial) behind;
# inputs are never modified.
. "$(dirname "$0")/lib.sh"
D=8x6x5
"$GEN" --field blobs --dims $D --steps 4 -o "$W/in" || fail gen
IN="$W/in/blobs_t0000.f32 $W/in/blobs_t0001.f32 $W/in/blobs_t0002.f32 $W/in/blobs_t0003.f32"
sum_before=$(cat $IN | cksum)
O=$W/out
none_left() {
    if [ -e "$O" ] || [ -e "$O.partial" ]; then
        fail "output left behind after: $1"; rm -rf "$O" "$O.partial"
    fi
}
expect_exit 2 "blobs_t0000.f32: size is 960 bytes; expected 1200 \\(one 10x6x5 f32 timestep\\)" \
    "$ENC" --axes xyz --dims 10x6x5 -o "$O" $IN; none_left "wrong size"
expect_exit 2 "nope.f32: cannot read input" "$ENC" --axes xyz --dims $D -o "$O" "$W/nope.f32"; none_left missing
expect_exit 2 "not a regular file" "$ENC" --axes xyz --dims $D -o "$O" "$W/in"; none_left directory
expect_exit 2 "every dimension must be at least 1" "$ENC" --axes xyz --dims 0x6x5 -o "$O" $IN; none_left zero
expect_exit 2 "too large|overflows" "$ENC" --axes xyz --dims 99999999999x2x2 -o "$O" $IN; none_left overflow
expect_exit 2 "overflows" "$ENC" --axes xyz --dims 2000000000x2000000000x2000000000 -o "$O" $IN; none_left overflow2
expect_exit 2 "expected NXxNYxNZ" "$ENC" --axes xyz --dims 8x6 -o "$O" $IN; none_left malformed
expect_exit 2 "window \"0\".*1 to 16" "$ENC" --axes xyz --dims $D --window 0 -o "$O" $IN; none_left N0
expect_exit 2 "window \"17\".*1 to 16" "$ENC" --axes xyz --dims $D --window 17 -o "$O" $IN; none_left N17
expect_exit 2 "nodes 6: larger than the z axis \(5 slices\)" "$ENC" --axes xyz --dims $D --nodes 6 -o "$O" $IN; none_left K
expect_exit 2 "type \"f16\"" "$ENC" --axes xyz --dims $D --type f16 -o "$O" $IN; none_left type
expect_exit 2 "no INPUT" "$ENC" --axes xyz --dims $D -o "$O"; none_left noinput
expect_exit 2 "-o OUTDIR is required" "$ENC" --axes xyz --dims $D $IN
expect_exit 2 "--steps T takes exactly one INPUT" "$ENC" --axes xyz --dims $D --steps 4 -o "$O" $IN; none_left steps
cat $IN > "$W/all.f32"
expect_exit 2 "all.f32: size is 3840 bytes; expected 4800 \\(5 timesteps of 8x6x5 f32\\)" "$ENC" --axes xyz --dims $D --steps 5 -o "$O" "$W/all.f32"; none_left steps-size
# NaN and infinity at a known voxel of timestep 2.
$PY - "$W" <<'PY'
import struct, sys
w = sys.argv[1]
for name, bad in (("nan", float("nan")), ("inf", float("-inf"))):
    data = bytearray(open(w + "/in/blobs_t0002.f32", "rb").read())
    i = 3 + 8 * (2 + 6 * 4)          # voxel (3,2,4)
    data[4 * i:4 * i + 4] = struct.pack("<f", bad)
    open(w + "/" + name + ".f32", "wb").write(data)
PY
A="$W/in/blobs_t0000.f32 $W/in/blobs_t0001.f32"
# NaN is a missing value: encoded, decoding to NaN there and only there.
"$ENC" --axes xyz -q --dims $D -o "$O" $A "$W/nan.f32" "$W/in/blobs_t0003.f32" > /dev/null \
    && grep -q "^missing = 1$" "$O/manifest.txt" && ok "NaN encoded as missing" \
    || fail "NaN as missing"
nan_exactly "$O" 2 $D "3,2,4"
nan_exactly "$O" 3 $D ""
rm -rf "$O"
expect_exit 2 "inf.f32: timestep 2: infinite value at voxel \(3,2,4\).*--nan-as" \
    "$ENC" --axes xyz --dims $D -o "$O" $A "$W/inf.f32" "$W/in/blobs_t0003.f32"; none_left inf
# Infinity late in the run (after checkpoints): still nothing left behind.
expect_exit 2 "inf.f32: timestep 5" \
    "$ENC" --axes xyz -q --dims $D --window 2 -o "$O" $IN "$W/in/blobs_t0000.f32" "$W/inf.f32"; none_left late-inf
# Every value missing: nothing to encode.
$PY -c "import struct,sys; open(sys.argv[1],'wb').write(struct.pack('<f',float('nan'))*240)" "$W/allnan.f32"
expect_exit 2 "allnan.f32: every value is missing" "$ENC" --axes xyz -q --dims $D -o "$O" "$W/allnan.f32" "$W/allnan.f32"
none_left all-missing
# --missing V: the value is missing wherever it occurs.
"$ENC" --axes xyz -q --dims $D --missing 0 -o "$O" $IN > /dev/null 2>&1 && grep -q "^missing_values = 0$" "$O/manifest.txt" \
    && ok "--missing 0 recorded" || fail "--missing 0"
rm -rf "$O"
expect_exit 2 "--missing" "$ENC" --axes xyz -q --dims $D --missing nan -o "$O" $IN; none_left missing-nan
"$ENC" --axes xyz -q --dims $D --nan-as -1 -o "$O" $A "$W/nan.f32" "$W/in/blobs_t0003.f32" > /dev/null \
    && grep -q "nonfinite_replaced = 1" "$O/manifest.txt" && ok "--nan-as replaces" \
    || fail "--nan-as"
expect_exit 2 "output already exists" "$ENC" --axes xyz --dims $D -o "$O" $IN
"$ENC" --axes xyz -q --dims $D --force -o "$O" $IN > /dev/null && "$INFO" "$O" > /dev/null \
    && ok "--force replaces" || fail "--force"
rm -rf "$O"
# Unwritable output: a path below a regular file.
expect_exit 2 "cannot create" "$ENC" --axes xyz --dims $D -o "$W/in/blobs_t0000.f32/sub" $IN
expect_exit 2 "is or lies inside" "$ENC" --axes xyz --dims $D --force -o "$W/in" $IN
expect_exit 2 "is or lies inside" "$ENC" --axes xyz --dims $D --force -o "$W/in/blobs_t0000.f32" $IN
mkdir -p "$W/notds" && echo keep > "$W/notds/file"
expect_exit 2 "notds: exists and is not a tvpal dataset" "$ENC" --axes xyz --dims $D --force -o "$W/notds" $IN
[ "$(cat "$W/notds/file")" = keep ] && ok "non-dataset directory kept" || fail "notds replaced"
[ "$(cat $IN | cksum)" = "$sum_before" ] && ok "inputs unchanged" || fail "inputs modified"
# --spacing and --origin: exactly three finite numbers.
for bad in 1,2 1,2,3,4 1,,3 ,1,2 1,2,3x 1e999,1,1 nan,1,1 ""; do
    expect_exit 2 "--spacing \"$bad\": expected DX,DY,DZ, three numbers > 0" \
        "$ENC" --axes xyz --dims $D --spacing "$bad" -o "$W/sp" $IN
done
expect_exit 2 "--origin \"0,inf,0\": expected OX,OY,OZ" "$ENC" --axes xyz --dims $D --origin 0,inf,0 -o "$W/sp" $IN
# The manifest's range, said: a subnormal is refused, 1e308 is a spacing.
expect_exit 2 "--spacing \"1e-310,1,1\": expected .* from 2.2250738585072014e-308 to 1.7976931348623157e\+308" \
    "$ENC" --axes xyz --dims $D --spacing 1e-310,1,1 -o "$W/sp" $IN
"$ENC" --axes xyz -q --dims $D --spacing 1e308,1,1 -o "$W/sp" $IN > /dev/null && "$INFO" "$W/sp" --verify > /dev/null \
    && ok "--spacing 1e308,1,1 encodes and verifies" || fail "--spacing 1e308"
rm -rf "$W/sp"
# The other programs.
expect_exit 2 "manifest.txt" "$DEC" "$W/nodataset" --step 0 -o "$W/x.f32"
expect_exit 2 "manifest.txt" "$INFO" "$W/nodataset"
expect_exit 2 "manifest.txt" "$REP" "$W/nodataset"
expect_exit 2 "--axis \"w\"" "$DEC" "$W/nodataset" --step 0 --axis w -o "$W/x.f32"
expect_exit 2 "field \"waves\"" "$GEN" --field waves --dims $D --steps 2 -o "$W/g"
finish
