#!/bin/sh
# api-mpi: libtvpal's collective encode under mpirun, as a user's MPI
# simulation uses it.  samples/tvpal-heat.c built with -DTVPAL_HEAT_MPI
# against the installed library and header-only tvpal_mpi.h (nothing but
# `pkg-config --cflags --libs ompi-c tvpal`) decomposes its grid along z;
# each rank pushes its slab and writes its node shard.  On 1 rank its
# dataset is the one-process sample's, byte for byte; on 3 ranks its raw
# dumps are the same steps, its node shards are tvpal-encode --nodes 3's
# of those dumps, byte for byte, and its decoded steps within a PSNR floor
# of the simulation's arrays.  Every rank killed mid-run and rerun with
# --resume continues from the ranks' checkpoints to the uninterrupted
# run's dataset.  With levels, rank 0 encodes every node's from every
# rank's part: level 1 is tvpal-encode's of the dumps.  A bad value on one
# rank fails every rank with that
# rank's message, and an output that exists every rank with rank 0's;
# neither hangs or leaves anything that looks complete.  The encode from
# files (tests/api-files.c) on 3 ranks writes tvpal-encode --nodes 3 --axes
# xyz --levels 1's shards.
. "$(dirname "$0")/lib.sh"
third_party_leaks
"$ENC" --version | grep -q "mpi: yes" ||
    { echo "built without MPI (libopenmpi-dev): skipped"; exit 77; }
command -v mpirun > /dev/null || { echo "no mpirun (scripts/setup-deps installs openmpi-bin)"; exit 99; }
command -v pkg-config > /dev/null || { echo "no pkg-config"; exit 99; }
MPI="timeout 120 mpirun --allow-run-as-root --oversubscribe"
export OMPI_MCA_rmaps_base_oversubscribe=1
CC=${TVPAL_CC:-cc}
install_lib || { fail "make install of the library, with tvpal.pc"; finish; }
# Beside the system's ompi-c.pc, tvpal.pc as a user's own --prefix has it
# (no sysroot: that would move Open MPI's paths too).
mkdir -p "$W/pc"
sed "s#^\(prefix\|exec_prefix\|libdir\|includedir\)=/#\1=$W/root/#" "$pcdir/tvpal.pc" > "$W/pc/tvpal.pc"
unset PKG_CONFIG_SYSROOT_DIR PKG_CONFIG_LIBDIR
export PKG_CONFIG_PATH="$W/pc"
libdir=$(pkg-config --variable=libdir tvpal)
pkg-config --exists ompi-c || { fail "MPI build but no ompi-c.pc"; finish; }
src=$TVPAL_SRCDIR/samples/tvpal-heat.c
# shellcheck disable=SC2046,SC2086
$CC ${TVPAL_CFLAGS:-} -DTVPAL_HEAT_MPI $(pkg-config --cflags ompi-c tvpal) "$src" \
    -o "$W/heat-mpi" ${TVPAL_LDFLAGS:-} $(pkg-config --libs ompi-c tvpal) -lm 2> "$W/cc.txt" ||
    { cat "$W/cc.txt"; fail "tvpal-heat -DTVPAL_HEAT_MPI does not build with pkg-config ompi-c tvpal"; finish; }
# shellcheck disable=SC2046,SC2086
$CC ${TVPAL_CFLAGS:-} $(pkg-config --cflags tvpal) "$src" -o "$W/heat" \
    ${TVPAL_LDFLAGS:-} $(pkg-config --libs tvpal) -lm 2> "$W/cc1.txt" ||
    { cat "$W/cc1.txt"; fail "tvpal-heat does not build"; finish; }
export LD_LIBRARY_PATH="$libdir"
D=40x36x28
H="--dims $D --steps 18 --window 4"
mkdir -p "$W/r0" "$W/r1" "$W/r3"
# shellcheck disable=SC2086
"$W/heat" $H --raw "$W/r0" -o "$W/one.ds" > /dev/null || fail "tvpal-heat, one process"
# shellcheck disable=SC2086
$MPI -np 1 "$W/heat-mpi" $H --raw "$W/r1" -o "$W/np1.ds" > "$W/np1.txt" 2>&1 ||
    { cat "$W/np1.txt"; fail "mpirun -np 1 tvpal-heat"; }
same=1
for f in manifest.txt node-0/manifest.txt node-0/axis-z.tvps; do
    cmp -s "$W/one.ds/$f" "$W/np1.ds/$f" || { same=0; fail "np 1: $f differs from one process's"; }
done
[ $same = 1 ] && ok "1 rank: the one-process dataset, byte for byte"
# shellcheck disable=SC2086
$MPI -np 3 "$W/heat-mpi" $H --raw "$W/r3" -o "$W/np3.ds" > "$W/np3.txt" 2>&1 ||
    { cat "$W/np3.txt"; fail "mpirun -np 3 tvpal-heat"; finish; }
grep -q "18 steps of $D encoded into .* on 3 ranks" "$W/np3.txt" && ok "3 ranks encoded in situ" ||
    fail "np 3 said: $(cat "$W/np3.txt")"
same=1
for f in "$W"/r0/*.f32; do
    cmp -s "$f" "$W/r3/$(basename "$f")" || { same=0; fail "np 3: the simulation's $(basename "$f") differs"; }
done
[ $same = 1 ] && ok "3 ranks simulate the same steps, bit for bit"
"$ENC" -q --dims $D --window 4 --nodes 3 -o "$W/enc3.ds" "$W"/r3/heat_t*.f32 > /dev/null ||
    fail "tvpal-encode --nodes 3 of the dumps"
same=1
for k in 0 1 2; do
    cmp -s "$W/enc3.ds/node-$k/axis-z.tvps" "$W/np3.ds/node-$k/axis-z.tvps" ||
        { same=0; fail "node $k's shard differs from tvpal-encode --nodes 3's"; }
done
[ $same = 1 ] && ok "3 ranks: node shards byte-identical to tvpal-encode --nodes 3 of the dumps"
grep -q "^nodes = 3" "$W/np3.ds/manifest.txt" && [ ! -e "$W/np3.ds.partial" ] &&
    [ ! -e "$W/np3.ds.partial.lock" ] && ok "one manifest, nodes = 3, no partial output left" ||
    fail "np 3 manifest or leftovers: $(grep nodes "$W/np3.ds/manifest.txt")"
"$INFO" --verify "$W/np3.ds" > "$W/verify.txt" 2>&1 && ok "tvpal-info --verify: ok" ||
    { cat "$W/verify.txt"; fail "verify of the 3-rank dataset"; }
"$REP" "$W/np3.ds" --reference "$W"/r3/heat_t*.f32 > "$W/rep.txt" 2>&1 ||
    { cat "$W/rep.txt"; fail "tvpal-report"; }
psnr=$(sed -n 's/.*psnr=\([0-9.]*\).*/\1/p' "$W/rep.txt" | head -n 1)
awk -v p="${psnr:-0}" 'BEGIN { exit !(p > 40) }' && ok "3 ranks: PSNR $psnr dB against the simulation (floor 40)" ||
    fail "PSNR ${psnr:-none} below 40: $(head -n 3 "$W/rep.txt")"
# Every rank killed (SIGKILL) mid-run, then the same job with --resume:
# every rank continues from the step their checkpoints share (not 0) and
# the dataset is the uninterrupted run's.
K="--dims 64x60x48 --steps 40 --window 4"
# shellcheck disable=SC2086
$MPI -np 3 "$W/heat-mpi" $K -o "$W/kref.ds" > "$W/kref.txt" 2>&1 || { cat "$W/kref.txt"; fail "np 3, 64x60x48"; }
# shellcheck disable=SC2086
$MPI -np 3 "$W/heat-mpi" $K -o "$W/kill.ds" > /dev/null 2>&1 &
mpid=$!
i=0
while [ $i -lt 600 ]; do
    n=0
    for k in 0 1 2; do grep -qs "^done" "$W/kill.ds.partial/node-$k/checkpoint" && n=$((n + 1)); done
    [ $n = 3 ] && break
    sleep 0.05; i=$((i + 1))
done
sleep 0.2
pkill -9 -f "$W/heat-mpi" 2> /dev/null
wait $mpid 2> /dev/null
if [ -e "$W/kill.ds" ]; then
    echo "note: the run ended before it was killed"
else
    # shellcheck disable=SC2086
    $MPI -np 3 "$W/heat-mpi" $K --resume -o "$W/kill.ds" > "$W/resume.txt" 2>&1 ||
        { cat "$W/resume.txt"; fail "np 3 --resume"; }
    at=$(sed -n 's/.*resumed .* at step \([0-9]*\) of 40/\1/p' "$W/resume.txt")
    [ "${at:-0}" -gt 0 ] && ok "3 ranks killed, resumed from step $at of 40" ||
        fail "--resume on 3 ranks started over: $(cat "$W/resume.txt")"
    same=1
    for f in manifest.txt node-0/axis-z.tvps node-1/axis-z.tvps node-2/axis-z.tvps node-2/manifest.txt; do
        cmp -s "$W/kref.ds/$f" "$W/kill.ds/$f" || { same=0; fail "resumed on 3 ranks: $f differs"; }
    done
    [ $same = 1 ] && [ ! -e "$W/kill.ds.partial" ] && ok "resumed on 3 ranks: the uninterrupted run's dataset, byte for byte"
fi
# A bad value on rank 1 at step 9: every rank's finish fails with rank 1's
# message; nothing is left.
# shellcheck disable=SC2086
$MPI -np 3 "$W/heat-mpi" $H --bad-value 1 -o "$W/bad.ds" > "$W/bad.txt" 2>&1
rc=$?
n=$(grep -c "rank 1: step 9: an infinite value at voxel (0,0,10)" "$W/bad.txt")
[ $rc -ne 0 ] && [ $rc -ne 124 ] && [ "$n" = 2 ] && grep -q "^tvpal-heat\[rank 1\]: .*step 9: an infinite" "$W/bad.txt" &&
    ok "a bad value on rank 1: every rank fails, naming rank 1's voxel (exit $rc)" ||
    { cat "$W/bad.txt"; fail "bad value on rank 1: exit $rc, $n ranks told"; }
[ ! -e "$W/bad.ds" ] && [ ! -e "$W/bad.ds.partial" ] && [ ! -e "$W/bad.ds.partial.lock" ] &&
    ok "a bad value on rank 1: nothing left" || fail "bad value: left $(ls -d "$W"/bad.ds*)"
# An encode from files under mpirun (tests/api-files.c, -DAPI_FILES_MPI):
# every rank reads the files and writes its node shard of x, y and z, and
# rank 0 the levels, after level 0: tvpal-encode --nodes 3 --axes xyz
# --levels 1's shards, byte for byte, with and without a memory limit.
# shellcheck disable=SC2046,SC2086
$CC ${TVPAL_CFLAGS:-} -DAPI_FILES_MPI $(pkg-config --cflags ompi-c tvpal) \
    "$TVPAL_SRCDIR/tests/api-files.c" -o "$W/files-mpi" ${TVPAL_LDFLAGS:-} \
    $(pkg-config --libs ompi-c tvpal) 2> "$W/ccf.txt" ||
    { cat "$W/ccf.txt"; fail "api-files -DAPI_FILES_MPI does not build"; }
"$ENC" -q --dims $D --window 4 --nodes 3 --axes xyz --levels 1 -o "$W/fenc.ds" "$W"/r0/heat_t*.f32 \
    > /dev/null || fail "tvpal-encode --nodes 3 --axes xyz --levels 1"
for lim in 0 20500000; do
    # shellcheck disable=SC2086
    $MPI -np 3 "$W/files-mpi" --dims $D --window 4 --axes 7 --levels 1 --threads 1 \
        --mem-limit $lim -o "$W/files-$lim.ds" "$W"/r0/heat_t*.f32 > "$W/files-$lim.txt" 2>&1 ||
        { cat "$W/files-$lim.txt"; fail "mpirun -np 3 api-files (limit $lim)"; continue; }
    same=1
    for f in $(cd "$W/fenc.ds" && find . -name '*.tvps'); do
        cmp -s "$W/fenc.ds/$f" "$W/files-$lim.ds/$f" || { same=0; fail "limit $lim: $f differs"; }
    done
    n=$(cd "$W/files-$lim.ds" && find . -name '*.tvps' | wc -l)
    [ $same = 1 ] && [ "$n" = 18 ] &&
        ok "3 ranks encode from files (limit $lim, $(sed -n 's/^passes=\([0-9]*\).*/\1/p' "$W/files-$lim.txt" | sort -u | tr '\n' ' ')passes): tvpal-encode --nodes 3 --axes xyz --levels 1's $n shards" ||
        fail "limit $lim: $n shards"
done
# Levels under a collective: rank 0 makes level 1 from every rank's part
# (28 planes in slabs 10, 9, 9: a block split between ranks 1 and 2) and
# encodes every node's levels; level 1 is tvpal-encode --nodes 3
# --levels 1's of the dumps, shard for shard.
mkdir -p "$W/rl"
# shellcheck disable=SC2086
$MPI -np 3 "$W/heat-mpi" $H --levels 1 --raw "$W/rl" -o "$W/lv.ds" > "$W/lv.txt" 2>&1 ||
    { cat "$W/lv.txt"; fail "np 3 --levels 1"; }
"$ENC" -q --dims $D --window 4 --nodes 3 --levels 1 -o "$W/lenc.ds" "$W"/rl/heat_t*.f32 > /dev/null ||
    fail "tvpal-encode --nodes 3 --levels 1 of the dumps"
same=1
for f in level-1/node-0/axis-z.tvps level-1/node-1/axis-z.tvps level-1/node-2/axis-z.tvps node-1/axis-z.tvps; do
    cmp -s "$W/lenc.ds/$f" "$W/lv.ds/$f" || { same=0; fail "levels on 3 ranks: $f differs"; }
done
[ $same = 1 ] && grep -q "^levels = 1" "$W/lv.ds/manifest.txt" && [ ! -e "$W/lv.ds.partial" ] &&
    "$INFO" --verify "$W/lv.ds" > /dev/null 2>&1 &&
    ok "levels on 3 ranks: level 1's shards byte-identical to tvpal-encode --nodes 3 --levels 1's" ||
    fail "levels on 3 ranks: the dataset"
# An output that exists: every rank fails with rank 0's message.
mkdir -p "$W/exists.ds" && echo keep > "$W/exists.ds/mine"
# shellcheck disable=SC2086
$MPI -np 3 "$W/heat-mpi" $H -o "$W/exists.ds" > "$W/ex.txt" 2>&1
rc=$?
n=$(grep -c "rank 0: .*exists.ds: output already exists" "$W/ex.txt")
[ $rc -ne 0 ] && [ $rc -ne 124 ] && [ "$n" = 3 ] && [ "$(cat "$W/exists.ds/mine")" = keep ] &&
    [ ! -e "$W/exists.ds.partial" ] && ok "an existing output: every rank refuses, it is untouched" ||
    { cat "$W/ex.txt"; fail "existing output: exit $rc, $n ranks told"; }
finish
