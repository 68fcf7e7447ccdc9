#!/bin/sh
# stored-axes: tvpal-encode --axes LIST (FORMAT.md 2.2).  --axes z writes
# only node-R/axis-z.tvps in every node directory, each byte for byte the
# z shard of the encode of all three axes, so it decodes to the same bits;
# its manifest says axes = z and format_version 4 (3 staggered); on a cube the dataset
# is a third of the three-axis one (0.32 .. 0.35 of its bytes on disk).
# --axes xz stores two axes, decoding as the three-axis encode's x and z.
# A bad list is refused naming --axes.  A resume with other axes starts
# over, with the same axes resumes.  --levels 1 --axes z stores z only in
# the level too.  A memory-limited plan without z takes the statistics
# from its x passes (the same manifest).  The summary's bytes is the sum
# of the files' sizes, ratio the source bytes over it, axis_ratio about
# three times ratio for three axes and about ratio for one.
# tests/stored-axes-mpi.sh: the same under mpirun.
. "$(dirname "$0")/lib.sh"
C=32x32x32
"$GEN" --field turbulence --dims $C --steps 8 -o "$W/cube" > /dev/null || fail gen
CUBE="$W/cube/*.f32"

# files_bytes DIR: the sizes of the regular files under DIR, added up.
files_bytes() { find "$1" -type f -exec stat -c %s {} + | awk '{ s += $1 } END { print s + 0 }'; }

"$ENC" -q --dims $C --window 4 --nodes 2 --axes xyz -o "$W/xyz" $CUBE > "$W/xyz.out" || fail "encode xyz"
"$ENC" -q --dims $C --window 4 --nodes 2 --axes z -o "$W/z" $CUBE > "$W/z.out" || fail "encode --axes z"

# Only the z shards, byte for byte those of the three-axis encode.
for r in 0 1; do
    [ "$(ls "$W/z/node-$r" | tr '\n' ' ')" = "axis-z.tvps manifest.txt " ] \
        && ok "node-$r holds axis-z.tvps and its manifest only" \
        || fail "node-$r holds: $(ls "$W/z/node-$r" | tr '\n' ' ')"
    cmp -s "$W/z/node-$r/axis-z.tvps" "$W/xyz/node-$r/axis-z.tvps" \
        && ok "node-$r/axis-z.tvps is the three-axis encode's" || fail "node-$r/axis-z.tvps differs"
done
# format_version: 4 with the joined schedule (the default), axes or not;
# staggered, 3 with a subset of the axes and 1 with all three.
grep -q "^axes = z$" "$W/z/manifest.txt" && grep -q "^format_version = 4$" "$W/z/manifest.txt" \
    && ! grep -q -- "--axes" "$W/z/manifest.txt" \
    && ok "manifest: axes = z, format_version 4, no --axes in options (z is the default)" \
    || fail "manifest: $(head -n 13 "$W/z/manifest.txt")"
! grep -q "^axes" "$W/xyz/manifest.txt" && grep -q "^format_version = 4$" "$W/xyz/manifest.txt" \
    && grep -q "^options = .* --axes xyz$" "$W/xyz/manifest.txt" \
    && ok "three axes: no axes key, format_version 4, options --axes xyz" \
    || fail "xyz manifest: $(head -n 13 "$W/xyz/manifest.txt")"
for a in z xyz; do
    "$ENC" -q --dims $C --window 4 --axes $a --schedule staggered -o "$W/st-$a" $CUBE > /dev/null \
        || fail "encode --axes $a --schedule staggered"
done
grep -q "^axes = z$" "$W/st-z/manifest.txt" && grep -q "^format_version = 3$" "$W/st-z/manifest.txt" \
    && ! grep -q "^axes" "$W/st-xyz/manifest.txt" && grep -q "^format_version = 1$" "$W/st-xyz/manifest.txt" \
    && ! grep -q "^schedule" "$W/st-z/manifest.txt" \
    && ok "staggered: axes = z format_version 3, all three 1, no schedule key" \
    || fail "staggered manifests: $(head -n 13 "$W/st-z/manifest.txt")"
# The default is one copy: no --axes gives the --axes z dataset, byte for byte.
"$ENC" -q --dims $C --window 4 --nodes 2 -o "$W/def" $CUBE > /dev/null || fail "encode, default axes"
cmp -s "$W/def/manifest.txt" "$W/z/manifest.txt" && cmp -s "$W/def/node-1/axis-z.tvps" "$W/z/node-1/axis-z.tvps" \
    && [ ! -e "$W/def/node-0/axis-x.tvps" ] && ok "the default is --axes z" || fail "the default is not --axes z"
cmp -s "$W/z/manifest.txt" "$W/z/node-1/manifest.txt" && ok "node manifests are copies" \
    || fail "node-1/manifest.txt differs"
"$INFO" "$W/z" --verify > "$W/v.txt" 2>&1 && grep -q "^stored_axes = z$" "$W/v.txt" \
    && grep -q "^verify: ok" "$W/v.txt" && [ "$(grep -c '^ok ' "$W/v.txt")" -eq 2 ] \
    && ok "tvpal-info: stored_axes = z, 2 shards verify" || fail "verify: $(cat "$W/v.txt")"

# Decoding: the same bits as the z axis of the three-axis encode.
same=0
for t in 0 1 2 3 4 5 6 7; do
    "$DEC" "$W/z" --step $t -o "$W/z-$t.f32" || fail "decode z step $t"
    "$DEC" "$W/xyz" --step $t --axis z -o "$W/xyz-$t.f32" || fail "decode xyz step $t"
    cmp -s "$W/z-$t.f32" "$W/xyz-$t.f32" && same=$((same + 1))
done
[ $same -eq 8 ] && ok "8 steps decode bit-identical to the three-axis z decode" \
    || fail "only $same of 8 steps decode identically"
for a in x y; do
    expect_exit 2 "--axis $a: .* stores axes z only" "$DEC" "$W/z" --step 0 --axis $a -o "$W/no.f32"
done
"$TVPAL_BUILDDIR/tests/tvpal-check" seqjump "$W/z" > "$W/sj.txt" 2>&1     && ok "jumps decode as sequential playback; the absent axes' readers refused"     || fail "seqjump: $(cat "$W/sj.txt")"
[ ! -e "$W/no.f32" ] && ok "no output for a refused axis" || fail "a refused axis wrote output"

# Sizes: about a third on disk; the summary's figures against the files.
bz=$(files_bytes "$W/z") bx=$(files_bytes "$W/xyz")
awk -v a="$bz" -v b="$bx" 'BEGIN { r = a / b; printf "%.4f\n", r; exit !(r >= 0.32 && r <= 0.35) }' \
    > "$W/r.txt" && ok "--axes z is $(cat "$W/r.txt") of the three-axis dataset ($bz / $bx bytes)" \
    || fail "--axes z is $(cat "$W/r.txt") of the three-axis dataset ($bz / $bx bytes)"
SRC=$((32 * 32 * 32 * 4 * 8))
for name in z xyz; do
    line=$(cat "$W/$name.out") disk=$(files_bytes "$W/$name")
    [ "$(kv bytes "$line")" = "$disk" ] && ok "$name: bytes=$disk, every file" \
        || fail "$name: bytes=$(kv bytes "$line"), files $disk"
    awk -v r="$(kv ratio "$line")" -v s=$SRC -v d="$disk" -v b="$(kv bpv "$line")" \
        'BEGIN { q = s / d; p = d * 8 / (32 * 32 * 32 * 8);
                 exit !(r - q < 0.0006 && q - r < 0.0006 && b - p < 0.00006 && p - b < 0.00006) }' \
        && ok "$name: ratio $(kv ratio "$line") = source / on disk, bpv $(kv bpv "$line")" \
        || fail "$name: ratio $(kv ratio "$line"), bpv $(kv bpv "$line"); on disk $SRC / $disk"
    grep -q "axes=$name " "$W/$name.out" && ok "$name: summary says axes=$name" || fail "summary: $line"
done
awk -v a="$(kv axis_ratio "$(cat "$W/xyz.out")")" -v r="$(kv ratio "$(cat "$W/xyz.out")")" \
    'BEGIN { q = a / r; exit !(q > 2.95 && q < 3.05) }' \
    && ok "xyz: axis_ratio $(kv axis_ratio "$(cat "$W/xyz.out")") about 3 x ratio" \
    || fail "xyz: axis_ratio / ratio: $(cat "$W/xyz.out")"
# --axes z's axis_ratio is that of the three-axis encode's z shards (the
# same files; the axes' sizes differ once chunks are coded, so not xyz's
# mean), and above its ratio (which counts the manifests too: how much
# above depends on the length of the source paths they name).
zs=$(stat -c %s "$W/xyz"/node-*/axis-z.tvps | awk '{ s += $1 } END { print s + 0 }')
awk -v a="$(kv axis_ratio "$(cat "$W/z.out")")" -v r="$(kv ratio "$(cat "$W/z.out")")" \
    -v q="$(awk -v s=$SRC -v z="$zs" 'BEGIN { printf "%.3f", s / z }')" \
    'BEGIN { exit !(a == q && a > r) }' \
    && ok "z: axis_ratio = source / the three-axis encode's z shards, above its ratio" \
    || fail "z axis_ratio: $(cat "$W/z.out"); z shards of xyz: $zs bytes"

# Two axes of a box that is not a cube: x and z, as the three-axis encode's.
D=30x26x22
"$GEN" --field blobs --dims $D --steps 6 -o "$W/box" > /dev/null || fail gen
BOX="$W/box/*.f32"
"$ENC" -q --dims $D --window 3 --axes xyz -o "$W/b-xyz" $BOX > /dev/null || fail "encode box xyz"
"$ENC" -q --dims $D --window 3 --axes zx -o "$W/b-xz" $BOX > /dev/null || fail "encode --axes zx"
[ "$(ls "$W/b-xz/node-0" | tr '\n' ' ')" = "axis-x.tvps axis-z.tvps manifest.txt " ] \
    && grep -q "^axes = xz$" "$W/b-xz/manifest.txt" \
    && ok "--axes zx: axis-x and axis-z, manifest axes = xz" \
    || fail "--axes zx: $(ls "$W/b-xz/node-0" | tr '\n' ' ')"
same=0
for t in 0 2 5; do
    for a in x z; do
        "$DEC" "$W/b-xz" --step $t --axis $a -o "$W/p.f32" && "$DEC" "$W/b-xyz" --step $t --axis $a -o "$W/q.f32" \
            && cmp -s "$W/p.f32" "$W/q.f32" && same=$((same + 1))
    done
done
[ $same -eq 6 ] && ok "--axes xz: x and z decode as the three-axis encode's" || fail "xz decodes: $same of 6 equal"
expect_exit 2 "--axis y: .* stores axes xz only" "$DEC" "$W/b-xz" --step 0 --axis y -o "$W/no.f32"
line=$("$REP" -q "$W/b-xz") || fail "report xz"
[ -n "$(kv psnr_x "$line")" ] && [ -n "$(kv psnr_z "$line")" ] && [ -z "$(kv psnr_y "$line")" ] \
    && ok "tvpal-report: psnr_x and psnr_z, no psnr_y" || fail "report: $line"

# Bad lists, refused before anything is written.
for v in "" zz w xyzx "x,z" X; do
    expect_exit 2 "--axes \"$v\": expected" "$ENC" -q --dims $D --axes "$v" -o "$W/bad" $BOX
done
[ ! -e "$W/bad" ] && [ ! -e "$W/bad.partial" ] && ok "nothing written for a bad --axes" \
    || fail "a bad --axes left $(ls -d "$W"/bad*)"

# Resume: with the same axes it continues, with others it starts over.
TVPAL_ENCODE_FAULT_AFTER=3 "$ENC" -q --dims $D --window 3 --axes z -o "$W/r1" $BOX > /dev/null 2>&1
[ -d "$W/r1.partial" ] && [ ! -e "$W/r1" ] && ok "interrupted --axes z leaves r1.partial" \
    || fail "interruption: $(ls "$W")"
"$ENC" --dims $D --window 3 --axes z -o "$W/r1" $BOX > /dev/null 2> "$W/e.txt" || fail "rerun r1"
"$ENC" -q --dims $D --window 3 --axes z -o "$W/r1-ref" $BOX > /dev/null || fail "r1 reference"
grep -q "resuming" "$W/e.txt" && diff -r "$W/r1" "$W/r1-ref" > /dev/null \
    && ok "same axes: resumed, output identical" || fail "same axes: $(cat "$W/e.txt")"
TVPAL_ENCODE_FAULT_AFTER=3 "$ENC" -q --dims $D --window 3 --axes z -o "$W/r2" $BOX > /dev/null 2>&1
"$ENC" --dims $D --window 3 --axes xz -o "$W/r2" $BOX > /dev/null 2> "$W/e.txt" || fail "rerun r2"
! grep -q "resuming" "$W/e.txt" && diff -r "$W/r2" "$W/b-xz" > /dev/null \
    && ok "other axes: started over, output that of --axes xz" || fail "other axes: $(cat "$W/e.txt")"

# Levels: level 1 stores z only as well.
"$ENC" -q --dims $D --window 3 --levels 1 --axes z -o "$W/lv" $BOX > "$W/lv.out" || fail "encode --levels 1 --axes z"
[ "$(ls "$W/lv/node-0" | tr '\n' ' ')" = "axis-z.tvps manifest.txt " ] \
    && [ "$(ls "$W/lv/level-1/node-0" | tr '\n' ' ')" = "axis-z.tvps manifest.txt " ] \
    && grep -q "^axes = z$" "$W/lv/level-1/manifest.txt" && grep -q "^format_version = 4$" "$W/lv/level-1/manifest.txt" \
    && grep -q "^levels = 1$" "$W/lv/manifest.txt" && grep -q "^format_version = 4$" "$W/lv/manifest.txt" \
    && ok "--levels 1 --axes z: both levels store z only, format_version 4" \
    || fail "levels: $(ls -R "$W/lv")"
"$INFO" "$W/lv/level-1" --verify > /dev/null && ok "level 1 verifies" || fail "level 1 verify"
line=$(cat "$W/lv.out")
[ "$(kv bytes "$line")" = "$(files_bytes "$W/lv")" ] && [ "$(kv levels_bytes "$line")" = "$(files_bytes "$W/lv/level-1")" ] \
    && ok "bytes counts the level too, levels_bytes the level" || fail "levels bytes: $line"

# A memory-limited plan of x alone: several x passes take the statistics.
m=$("$ENC" -j 1 --mem-limit 1M --dims $D --window 3 --axes x -o "$W/none" $BOX 2>&1 |
    sed -n 's/.*give --mem-limit \([0-9]*\)K.*/\1/p')
"$ENC" -q -j 1 --mem-limit "$((m + 32))K" --dims $D --window 3 --axes x -o "$W/mx" $BOX > "$W/mx.out" \
    || fail "memory-limited --axes x"
p=$(kv passes "$(cat "$W/mx.out")")
strip() { grep -v "^options\|^axes\|^format_version" "$1"; }
[ "${p:-0}" -gt 1 ] && strip "$W/mx/manifest.txt" > "$W/m1" && strip "$W/b-xyz/manifest.txt" > "$W/m2" \
    && cmp -s "$W/m1" "$W/m2" && cmp -s "$W/mx/node-0/axis-x.tvps" "$W/b-xyz/node-0/axis-x.tvps" \
    && ok "--axes x in $p passes: the same statistics and x shard" \
    || fail "--axes x under a limit: ${p:-?} passes; $(diff "$W/m1" "$W/m2" | head -n 4)"
finish
