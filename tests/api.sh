#!/bin/sh
# api: libtvpal as a user gets it.  The library, its headers and tvpal.pc
# are installed into a scratch root (make install-... DESTDIR); the in-situ
# sample samples/tvpal-heat.c is built against them with nothing but
# `pkg-config --cflags --libs tvpal` (shared library, then --static) and
# run: it encodes its steps from memory while it simulates.  Its shards
# must be byte-identical to tvpal-encode's of the same steps dumped as raw
# files, its decoded steps within a PSNR floor of the simulation's arrays
# (tvpal-report against the dumps), and the shared library must export
# the API's symbols only.
. "$(dirname "$0")/lib.sh"
command -v pkg-config > /dev/null || { echo "no pkg-config: skipped"; exit 77; }
CC=${TVPAL_CC:-cc}
R=$W/root
install_lib || { fail "make install of the library, with tvpal.pc"; finish; }
pcflags=$(pkg-config --cflags tvpal) && plibs=$(pkg-config --libs tvpal) ||
    { fail "pkg-config --cflags --libs tvpal"; finish; }
[ "$(pkg-config --modversion tvpal)" = 0.4.0 ] && ok "pkg-config: tvpal 0.4.0" ||
    fail "pkg-config --modversion: $(pkg-config --modversion tvpal)"
so=$(ls "$libdir"/libtvpal.so.0* 2>/dev/null | head -n 1)
[ -n "$so" ] || fail "no libtvpal.so.0 installed in $libdir"
# Only the API: every exported function is declared in tvpal.h or
# tvpal_error.h.
hdrs=$(find "$R" -name tvpal.h)
if [ -n "$so" ]; then
    for s in $(nm -D --defined-only "$so" | awk '$2 == "T" { print $3 }'); do
        grep -q "\\b$s(" "$hdrs" "$(dirname "$hdrs")/tvpal_error.h" ||
            fail "libtvpal.so exports $s, which no public header declares"
    done
    ok "libtvpal.so exports the API only ($(nm -D --defined-only "$so" | awk '$2 == "T"' | wc -l) functions)"
fi
# The sample, as a user builds it (no tree paths).
# shellcheck disable=SC2086
$CC ${TVPAL_CFLAGS:-} $pcflags "$TVPAL_SRCDIR/samples/tvpal-heat.c" -o "$W/heat" \
    ${TVPAL_LDFLAGS:-} $plibs -lm 2> "$W/cc.txt" ||
    { cat "$W/cc.txt"; fail "tvpal-heat does not build with pkg-config"; finish; }
# shellcheck disable=SC2086
$CC ${TVPAL_CFLAGS:-} $pcflags "$TVPAL_SRCDIR/samples/tvpal-heat.c" -o "$W/heat-static" \
    ${TVPAL_LDFLAGS:-} -static-libgcc $(pkg-config --libs --static tvpal | sed 's/-ltvpal/-l:libtvpal.a/') -lm \
    2> "$W/cc-static.txt" || { cat "$W/cc-static.txt"; fail "tvpal-heat does not build against libtvpal.a"; }
mkdir -p "$W/raw" "$W/raw2"
LD_LIBRARY_PATH="$libdir" "$W/heat" --dims 40x36x28 --steps 18 --window 4 \
    --raw "$W/raw" -o "$W/heat.ds" > "$W/out.txt" 2> "$W/err.txt" ||
    { cat "$W/err.txt"; fail "tvpal-heat failed"; finish; }
grep -q "18 steps of 40x36x28 encoded" "$W/out.txt" && ok "tvpal-heat ran in situ" ||
    fail "tvpal-heat said: $(cat "$W/out.txt")"
ldd "$W/heat" | grep -q "$libdir/libtvpal.so" 2>/dev/null ||
    LD_LIBRARY_PATH="$libdir" ldd "$W/heat" | grep -q "libtvpal.so.0 => $libdir" ||
    fail "tvpal-heat is not linked to the installed libtvpal.so"
if [ -x "$W/heat-static" ]; then
    "$W/heat-static" --dims 40x36x28 --steps 18 --window 4 -o "$W/heat-static.ds" > /dev/null &&
        ! ldd "$W/heat-static" 2>/dev/null | grep -q libtvpal &&
        ok "tvpal-heat linked statically runs" || fail "the static tvpal-heat"
fi
# The same steps from the dumps through tvpal-encode: the same shards.
"$ENC" -q --dims 40x36x28 --window 4 -o "$W/enc.ds" "$W"/raw/heat_t*.f32 > /dev/null ||
    fail "tvpal-encode of the dumps"
same=1
for f in "$W"/enc.ds/node-0/*.tvps; do
    cmp -s "$f" "$W/heat.ds/node-0/$(basename "$f")" || { same=0; fail "$(basename "$f") differs from tvpal-encode's"; }
    [ -x "$W/heat-static" ] && { cmp -s "$f" "$W/heat-static.ds/node-0/$(basename "$f")" || { same=0; fail "static: $(basename "$f") differs"; }; }
done
[ $same = 1 ] && ok "in-situ shards byte-identical to tvpal-encode's from raw dumps"
# Levels made in situ (TVPAL_PARAM_LEVELS): tvpal-encode --levels 2's shards.
mkdir -p "$W/lraw"
LD_LIBRARY_PATH="$libdir" "$W/heat" --dims 41x36x27 --steps 18 --levels 2 --raw "$W/lraw" \
    -o "$W/lheat.ds" > /dev/null || fail "tvpal-heat --levels 2"
"$ENC" -q --dims 41x36x27 --window 4 --levels 2 -o "$W/lenc.ds" "$W"/lraw/heat_t*.f32 > /dev/null ||
    fail "tvpal-encode --levels 2 of the dumps"
same=1
for f in node-0/axis-z.tvps level-1/node-0/axis-z.tvps level-2/node-0/axis-z.tvps; do
    cmp -s "$W/lenc.ds/$f" "$W/lheat.ds/$f" || { same=0; fail "levels in situ: $f differs from tvpal-encode --levels 2's"; }
done
[ $same = 1 ] && grep -q "^levels = 2" "$W/lheat.ds/manifest.txt" &&
    ok "levels in situ: shards of levels 0-2 byte-identical to tvpal-encode --levels 2's"
# tvpal-report of a dataset from memory: no sources to read, so it asks
# for the original values; given the dumps, it measures against them.
expect_exit 2 "heat.ds names no source \(encoded from memory\?\): give the original values with --reference" \
    "$REP" "$W/heat.ds"
"$REP" -q "$W/heat.ds" --reference "$W"/raw/heat_t*.f32 > "$W/rep.txt" &&
    awk -F'psnr=' '{split($2, a, " "); exit !(a[1] + 0 > 30)}' "$W/rep.txt" &&
    ok "tvpal-report against the dumps: $(grep -o 'psnr=[^ ]*' "$W/rep.txt")" ||
    fail "tvpal-report --reference the dumps: $(cat "$W/rep.txt")"
grep -q "^encoder = libtvpal 0.4.0" "$W/heat.ds/manifest.txt" &&
    grep -q "^units = K" "$W/heat.ds/manifest.txt" &&
    grep -q "^time_units = seconds" "$W/heat.ds/manifest.txt" &&
    ok "manifest: encoder, units, time units" || fail "manifest: $(head -c 600 "$W/heat.ds/manifest.txt")"
# The disk fills while the sample writes (a 200 KiB tmpfs): the push that
# cannot write says which file, the sample aborts, and nothing is left
# that looks like a dataset.
mkdir -p "$W/full"
if mount -t tmpfs -o size=200k tmpfs "$W/full" 2> /dev/null; then
    LD_LIBRARY_PATH="$libdir" "$W/heat" --dims 40x36x28 --steps 18 -o "$W/full/ds" > /dev/null 2> "$W/full.err"
    rc=$?
    [ $rc = 1 ] && grep -q "ds.partial/node-0/axis-z.tvps.*\(No space\|write\)" "$W/full.err" \
        && ok "disk full: the push fails naming the shard" \
        || fail "disk full: exit $rc: $(cat "$W/full.err")"
    [ -z "$(ls "$W/full")" ] && ok "disk full: abort left nothing" || fail "disk full: left $(ls "$W/full")"
    umount "$W/full"
else
    echo "mount -t tmpfs not permitted: the full-disk case is skipped"
fi
# Killed (SIGKILL) while it runs: no dataset; a rerun with --resume
# continues from the checkpoint (it must not start over) and gives the
# shards of an uninterrupted run; a plain rerun starts over, the same.
H="--dims 96x96x64 --steps 40 --window 4 --levels 2"
# shellcheck disable=SC2086
LD_LIBRARY_PATH="$libdir" "$W/heat" $H -o "$W/ref.ds" > /dev/null || fail "tvpal-heat 96x96x64"
# shellcheck disable=SC2086
LD_LIBRARY_PATH="$libdir" "$W/heat" $H -o "$W/kill.ds" > /dev/null 2>&1 &
pid=$!
i=0
while ! grep -qs "^done" "$W/kill.ds.partial/checkpoint" && [ $i -lt 400 ]; do sleep 0.05; i=$((i + 1)); done
sleep 0.3
kill -9 $pid 2> /dev/null
wait $pid 2> /dev/null
if [ -e "$W/kill.ds" ]; then
    echo "note: the run ended before it was killed"
else
    [ -e "$W/kill.ds.partial" ] && ok "killed: only the partial output" || fail "killed: no partial output"
    # shellcheck disable=SC2086
    LD_LIBRARY_PATH="$libdir" "$W/heat" $H --resume -o "$W/kill.ds" > "$W/kill.out" 2> "$W/kill.err" ||
        fail "rerun with --resume: $(cat "$W/kill.err")"
    at=$(sed -n 's/.*resumed .* at step \([0-9]*\) of 40/\1/p' "$W/kill.out")
    [ "${at:-0}" -gt 0 ] && ok "resumed from the checkpoint at step $at of 40" ||
        fail "--resume started over: $(cat "$W/kill.out")"
    same=1
    for f in manifest.txt node-0/axis-z.tvps level-1/manifest.txt level-1/node-0/axis-z.tvps \
        level-2/node-0/axis-z.tvps; do
        cmp -s "$W/kill.ds/$f" "$W/ref.ds/$f" || { same=0; fail "resumed: $f differs from the uninterrupted run's"; }
    done
    [ $same = 1 ] && [ ! -e "$W/kill.ds.partial" ] &&
        ok "resumed after kill -9: the uninterrupted run's shards and manifests, levels 0-2"
    ! grep -rqs . "$W/kill.ds/checkpoint" && ok "no checkpoint left in the dataset" || fail "a checkpoint left"
fi
# Decoded against the simulation's arrays.
"$REP" "$W/heat.ds" --reference "$W"/raw/heat_t*.f32 > "$W/rep.txt" 2>&1 ||
    { cat "$W/rep.txt"; fail "tvpal-report"; }
psnr=$(sed -n 's/.*psnr=\([0-9.]*\).*/\1/p' "$W/rep.txt" | head -n 1)
awk -v p="${psnr:-0}" 'BEGIN { exit !(p > 40) }' && ok "PSNR $psnr dB (floor 40)" ||
    fail "PSNR ${psnr:-none} below 40: $(head -n 3 "$W/rep.txt")"
finish
