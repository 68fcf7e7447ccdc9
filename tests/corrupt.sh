#!/bin/sh
# corrupt: a flipped byte in a record, a truncated shard, a damaged header,
# a missing shard and a broken manifest are each reported by every tool as
# such (file, record, field), with a non-zero exit and no crash.
. "$(dirname "$0")/lib.sh"
D=20x16x12
"$GEN" --field turbulence --dims $D --steps 9 -o "$W/in" || fail gen
"$ENC" --axes xyz -q --dims $D --window 4 -o "$W/good" "$W"/in/*.f32 > /dev/null || fail encode
"$INFO" "$W/good" --verify > /dev/null && ok "clean dataset verifies" || fail "clean verify"
fresh() { rm -rf "$W/ds"; cp -r "$W/good" "$W/ds"; }
# Byte offset of record 5 of node-0/axis-y from the index (entry 5).
rec_off() {
    $PY - "$1" "$2" <<'PY'
import struct, sys
f = open(sys.argv[1], "rb"); h = f.read(4096)
idx = struct.unpack_from("<Q", h, 72)[0]
f.seek(idx + 32 * int(sys.argv[2])); print(struct.unpack("<Q", f.read(8))[0])
PY
}
flip() { # file offset
    $PY - "$1" "$2" <<'PY'
import sys
p, o = sys.argv[1], int(sys.argv[2])
b = bytearray(open(p, "rb").read()); b[o] ^= 0x20; open(p, "wb").write(b)
PY
}
fresh
off=$(rec_off "$W/ds/node-0/axis-y.tvps" 5)
flip "$W/ds/node-0/axis-y.tvps" $((off + 64 + 200))
expect_exit 1 "corrupt record" "$INFO" "$W/ds" --verify
grep -q "CORRUPT .*axis-y.tvps: record 5 .*CRC-32C mismatch" "$W/out.txt" \
    && ok "verify names axis-y record 5" || fail "verify output: $(cat "$W/out.txt")"
expect_exit 2 "axis-y.tvps: record 5: payload CRC-32C mismatch" \
    "$DEC" "$W/ds" --step 5 --axis y -o "$W/x.f32"
[ ! -e "$W/x.f32" ] && ok "no output file on error" || fail "x.f32 written"
"$DEC" "$W/ds" --step 5 --axis x -o "$W/x.f32" && ok "axis x still decodes" \
    || fail "axis x decode"
expect_exit 2 "axis-y.tvps: record 5" "$REP" "$W/ds"
fresh
truncate -s -4096 "$W/ds/node-0/axis-z.tvps"
expect_exit 2 "axis-z.tvps: file is truncated" "$DEC" "$W/ds" --step 0 -o "$W/x.f32"
expect_exit 1 "corrupt" "$INFO" "$W/ds" --verify
grep -q "CORRUPT .*axis-z.tvps: file is truncated" "$W/out.txt" \
    && ok "verify names the truncated file" || fail "truncation not named"
fresh
flip "$W/ds/node-0/axis-x.tvps" 30   # header field (steps)
expect_exit 2 "axis-x.tvps: checksum mismatch.*header: CRC-32C" "$INFO" "$W/ds"
fresh
printf 'XXXXXXXX' | dd of="$W/ds/node-0/axis-x.tvps" conv=notrunc 2>/dev/null
expect_exit 2 "axis-x.tvps: not a tvpal file" "$DEC" "$W/ds" --step 1 --axis x -o "$W/x.f32"
fresh
rm "$W/ds/node-0/axis-y.tvps"
expect_exit 2 "axis-y.tvps: cannot open" "$REP" "$W/ds"
fresh
sed -i '/^window = /d' "$W/ds/manifest.txt"
expect_exit 2 "manifest.txt.*\"window\" is missing" "$INFO" "$W/ds"
fresh
sed -i 's/^window = 4/window = 2/' "$W/ds/manifest.txt"
expect_exit 2 "does not match the manifest" "$DEC" "$W/ds" --step 0 -o "$W/x.f32"
expect_exit 1 "corrupt" "$INFO" "$W/ds" --verify
fresh
: > "$W/ds/node-0/axis-z.tvps"
expect_exit 2 "axis-z.tvps: file is truncated" "$REP" "$W/ds"
finish
