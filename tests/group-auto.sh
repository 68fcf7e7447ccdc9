#!/bin/sh
# group-auto: palette group sizes chosen by measurement (tvpal-encode
# --group auto, TVPAL_GROUP_AUTO; encoder/engine/tvpal_groupauto.h).
# The rule, on inputs whose answer is known: z slices that are copies of
# one another lose nothing by sharing a table, so the largest G (16) is
# taken; slices whose values lie in disjoint ranges (slice s near 1000 s)
# would share 256 entries among G ranges, so G = 1 is.  What it chose
# writes the shards --group G writes (the measure adds nothing of its
# own); the choice does not depend on the threads, the memory plan (a
# limit that makes passes) or the nodes; the levels take level 0's
# groups; slices too large for any group (512^2) are not measured and
# write what --group 1 writes; tvpal-encode's closing line and the
# manifest's options say so; a bad value is refused.
. "$(dirname "$0")/lib.sh"
$PY -c "import numpy" 2>/dev/null || { echo "numpy missing (scripts/setup-deps installs python3-numpy)"; exit 99; }

# shards_same A B: every shard of A (levels included) is B's, and B has
# no other.
shards_same() {
    (cd "$1" && find . -name '*.tvps' | sort) > "$W/a.list"
    (cd "$2" && find . -name '*.tvps' | sort) > "$W/b.list"
    cmp -s "$W/a.list" "$W/b.list" && [ -s "$W/a.list" ] || return 1
    while read -r f; do cmp -s "$1/$f" "$2/$f" || return 1; done < "$W/a.list"
}
# groups OUT: the closing line's groups= (e.g. z:8).
groups() { sed -n 's/.* groups=\([^ ]*\).*/\1/p' "$1"; }

# 1. The rule on known answers: 64x64 slices, 32 of them, 12 steps (on
#    slices this large the tables are a small part of the bits).
$PY - "$W" <<'EOF' || fail "making the inputs"
import os, sys
import numpy as np
w = sys.argv[1]
rng = np.random.default_rng(7)
y, x = np.mgrid[0:64, 0:64].astype(np.float32)
for name in ("copies", "ranges"):
    os.makedirs("%s/%s" % (w, name), exist_ok=True)
for t in range(12):
    # A smooth field that moves, plus noise: one slice of it.
    f = (np.sin(x / 9.0 + t / 4.0) * np.cos(y / 13.0 - t / 6.0) * 40.0 +
         rng.normal(0, 2.0, (64, 64))).astype(np.float32)
    copies = np.repeat(f[None], 32, axis=0)
    ranges = copies + (1000.0 * np.arange(32, dtype=np.float32))[:, None, None]
    copies.astype("<f4").tofile("%s/copies/t%02d.f32" % (w, t))
    ranges.astype("<f4").tofile("%s/ranges/t%02d.f32" % (w, t))
EOF
"$ENC" --dims 64x64x32 --group auto -o "$W/copies.ds" "$W"/copies/*.f32 > "$W/copies.out" 2> "$W/copies.err" \
    || fail "encode copies: $(cat "$W/copies.err")"
[ "$(groups "$W/copies.out")" = z:16 ] && ok "slices that are copies: groups of 16 (the largest)" \
    || fail "copies: groups $(groups "$W/copies.out"), z:16 expected"
"$ENC" --dims 64x64x32 --group auto -o "$W/ranges.ds" "$W"/ranges/*.f32 > "$W/ranges.out" 2> "$W/ranges.err" \
    || fail "encode ranges: $(cat "$W/ranges.err")"
[ "$(groups "$W/ranges.out")" = z:1 ] && ok "slices in disjoint ranges: no groups" \
    || fail "ranges: groups $(groups "$W/ranges.out"), z:1 expected"
"$ENC" -q --dims 64x64x32 -o "$W/ranges1.ds" "$W"/ranges/*.f32 > /dev/null || fail "encode ranges --group 1"
shards_same "$W/ranges.ds" "$W/ranges1.ds" && ok "no groups chosen: the shards --group 1 writes" \
    || fail "ranges: the shards differ from --group 1's"

# 2. What it chose is --group G's output, whatever the threads, passes or
#    nodes; every axis measured on its own.
D=40x34x24
"$GEN" --field turbulence --dims $D --steps 11 -o "$W/in" > /dev/null || fail gen
set -- "$W"/in/*.f32
"$ENC" --axes xyz -j 2 --dims $D --group auto -o "$W/a" "$@" > "$W/a.out" 2> "$W/a.err" \
    || fail "encode --group auto: $(cat "$W/a.err")"
g=$(groups "$W/a.out")
case $g in
x:*,y:*,z:*) ok "closing line: groups=$g" ;;
*) fail "closing line: $(cat "$W/a.out")" ;;
esac
grep -q -- '^options = .* --group auto' "$W/a/manifest.txt" && ok "manifest options say --group auto" \
    || fail "options: $(grep options "$W/a/manifest.txt")"
for a in x y z; do
    ga=$(printf '%s\n' "$g" | tr ',' '\n' | sed -n "s/^$a://p")
    "$ENC" -q --axes $a --dims $D --group "$ga" -o "$W/e$a" "$@" > /dev/null || fail "encode --group $ga"
    cmp -s "$W/a/node-0/axis-$a.tvps" "$W/e$a/node-0/axis-$a.tvps" \
        && ok "axis $a: the shard --group $ga writes" || fail "axis $a: differs from --group $ga"
done
echo "$g" | grep -q ':[2-9]\|:1[0-6]' && ok "groups chosen on 40x34 slices and smaller" \
    || fail "no groups chosen on small turbulent slices ($g)"
"$ENC" -q --axes xyz -j 1 --dims $D --group auto -o "$W/j1" "$@" > /dev/null || fail "encode -j 1"
diff -r "$W/a" "$W/j1" > /dev/null && ok "-j 1 writes what -j 2 writes" || fail "-j 1 differs"
# Under a memory limit that makes passes (each pass holds whole groups),
# the same bytes as one pass.
D2=96x80x64
"$GEN" --field turbulence --dims $D2 --steps 6 -o "$W/in2" > /dev/null || fail gen
m=$("$ENC" --axes xyz -j 1 --mem-limit 1M --dims $D2 --group auto -o "$W/none" "$W"/in2/*.f32 2>&1 |
    sed -n 's/.*give --mem-limit \([0-9]*\)K.*/\1/p')
if [ -n "$m" ]; then
    "$ENC" -q --axes xyz -j 1 --dims $D2 --group auto -o "$W/one" "$W"/in2/*.f32 > /dev/null \
        || fail "encode $D2"
    "$ENC" --axes xyz -j 1 --mem-limit $((m + 2048))K --dims $D2 --group auto -o "$W/m" "$W"/in2/*.f32 \
        > "$W/m.out" 2> "$W/m.err" || fail "encode under $((m + 2048))K: $(cat "$W/m.err")"
    p=$(sed -n 's/.* passes=\([0-9]*\).*/\1/p' "$W/m.out")
    [ "${p:-1}" -gt 3 ] && diff -r "$W/one" "$W/m" > /dev/null \
        && ok "$p passes under --mem-limit $((m + 2048))K, groups $(groups "$W/m.out"): the one-pass dataset" \
        || fail "under the limit: ${p:-?} passes, $(diff -rq "$W/one" "$W/m" | head -n 2)"
else
    fail "no smallest limit from tvpal-encode"
fi
"$ENC" -q --axes xyz --nodes 3 --dims $D --group auto -o "$W/n3" "$@" > /dev/null || fail "encode --nodes 3"
"$ENC" -q --axes xyz --nodes 3 --dims $D --group "$(printf '%s' "$g" | sed -n 's/.*z:\([0-9]*\).*/\1/p')" \
    -o "$W/n3z" "$@" > /dev/null || fail "encode --nodes 3 --group"
for r in 0 1 2; do
    cmp -s "$W/n3/node-$r/axis-z.tvps" "$W/n3z/node-$r/axis-z.tvps" || fail "--nodes 3: node $r differs"
done && ok "--nodes 3: the same choice, each node's z shard"

# 3. The levels take level 0's groups (fewer where a level has fewer
#    slices).
"$ENC" -q --axes z --levels 1 --dims $D --group auto -o "$W/l" "$@" > /dev/null || fail "encode --levels 1"
gz=$(printf '%s' "$g" | sed -n 's/.*z:\([0-9]*\).*/\1/p')
gl=$(( gz < 12 ? gz : 12 ))
u32() { od -A n -t u4 -j "$2" -N 4 "$1" | tr -d ' '; }
h=$(u32 "$W/l/level-1/node-0/axis-z.tvps" 92)
[ "${h:-x}" = "$gl" ] || { [ "$gl" = 1 ] && [ "${h:-x}" = 0 ]; } \
    && ok "level 1 (12 z slices): group $gl, level 0's $gz" || fail "level 1's group field $h, $gl expected"
"$INFO" --verify "$W/l" > /dev/null 2>&1 && ok "the levels verify" || fail "tvpal-info --verify with levels"

# 4. 512^2 slices take no group and are not measured.
"$GEN" --field blobs --dims 512x512x4 --steps 2 -o "$W/big" > /dev/null || fail gen
"$ENC" --dims 512x512x4 --window 2 --group auto -o "$W/big.ds" "$W"/big/*.f32 > "$W/big.out" 2>/dev/null \
    || fail "encode 512x512x4"
"$ENC" -q --dims 512x512x4 --window 2 -o "$W/big1.ds" "$W"/big/*.f32 > /dev/null || fail "encode 512x512x4 --group 1"
[ "$(groups "$W/big.out")" = z:1 ] && shards_same "$W/big.ds" "$W/big1.ds" \
    && ok "512^2 slices: no groups, the shard --group 1 writes" || fail "512^2: $(groups "$W/big.out")"

# 5. Bad values.
for v in automatic "" -1; do
    "$ENC" -q --dims $D --group "$v" -o "$W/bad" "$@" > "$W/out.txt" 2>&1
    rc=$?
    [ $rc -eq 2 ] && grep -q -- 'auto or a whole number' "$W/out.txt" && [ ! -e "$W/bad" ] \
        && ok "--group '$v' refused (exit 2)" || fail "--group '$v': exit $rc: $(cat "$W/out.txt")"
done
finish
