#!/bin/sh
# encode-mpi: mpirun -np K tvpal-encode --nodes K (rank r encodes node r's
# shards, reading only its slabs' boxes) gives output byte-identical to the
# one-process --nodes K encode for K = 1, 2, 3 (also with palette groups
# cut by the slabs), also with --shard-dir
# and --levels (rank 0 encodes the levels; a failure there resumes)
# (node-local directories) and under a memory limit (several passes per
# rank); kill -9 of one rank leaves nothing that looks valid and the rerun
# completes every rank; a rank that fails ends the job with rank 0's
# message (no hang), and the rerun resumes; a rank count other than
# --nodes is refused.
. "$(dirname "$0")/lib.sh"
third_party_leaks
command -v mpirun > /dev/null || { echo "no mpirun (scripts/setup-deps installs openmpi-bin)"; exit 99; }
"$ENC" --axes xyz --version | grep -q "mpi: yes" || { echo "built without MPI: skipped (an MPI launch is refused)"; \
    TVPAL_COMM=mpi "$ENC" --axes xyz --dims 2x2x2 -o "$W/x" /dev/null > /dev/null 2> "$W/nompi.txt"; \
    grep -q "libopenmpi-dev" "$W/nompi.txt" && exit 77; cat "$W/nompi.txt"; exit 1; }
MPI="timeout 120 mpirun --allow-run-as-root --oversubscribe"
export OMPI_MCA_rmaps_base_oversubscribe=1
D=40x34x30
"$GEN" --field front --dims $D --steps 13 -o "$W/in" > /dev/null || fail gen
IN="$W/in/*.f32"

for K in 1 2 3; do
    "$ENC" --axes xyz -q --dims $D --window 4 --nodes $K -o "$W/ref$K" $IN > /dev/null || fail "reference K=$K"
    $MPI -np $K "$ENC" --axes xyz -q --dims $D --window 4 --nodes $K -o "$W/mpi$K" $IN \
        > "$W/mpi$K.out" 2> "$W/mpi$K.err" || fail "mpirun -np $K: $(cat "$W/mpi$K.err")"
    diff -r "$W/ref$K" "$W/mpi$K" > /dev/null && ok "K=$K: MPI output byte-identical" \
        || fail "K=$K: MPI output differs"
done
# Palette groups of 3 (FORMAT.md 5.1), cut by the slabs of 3 ranks.
"$ENC" --axes xyz -q --dims $D --window 4 --nodes 3 --group 3 -o "$W/refg" $IN > /dev/null \
    || fail "reference --group 3"
$MPI -np 3 "$ENC" --axes xyz -q --dims $D --window 4 --nodes 3 --group 3 -o "$W/mpig" $IN \
    > /dev/null 2> "$W/mpig.err" || fail "mpirun --group 3: $(cat "$W/mpig.err")"
diff -r "$W/refg" "$W/mpig" > /dev/null && ok "K=3, --group 3: MPI output byte-identical" \
    || fail "K=3, --group 3: MPI output differs"
# --group auto: rank 0 measures, every rank encodes with its choice.
"$ENC" --axes xyz -q --dims $D --window 4 --nodes 3 --group auto -o "$W/refa" $IN > /dev/null \
    || fail "reference --group auto"
$MPI -np 3 "$ENC" --axes xyz -q --dims $D --window 4 --nodes 3 --group auto -o "$W/mpia" $IN \
    > /dev/null 2> "$W/mpia.err" || fail "mpirun --group auto: $(cat "$W/mpia.err")"
diff -r "$W/refa" "$W/mpia" > /dev/null && ok "K=3, --group auto: MPI output byte-identical" \
    || fail "K=3, --group auto: MPI output differs"
grep -q "nodes=3 .*threads=" "$W/mpi3.out" && [ "$(wc -l < "$W/mpi3.out")" -eq 1 ] \
    && ok "one summary line, from rank 0" || fail "summary: $(cat "$W/mpi3.out")"

# Node-local directories: node r's files in PATTERN(r), OUTDIR holds the
# manifest.
$MPI -np 2 "$ENC" --axes xyz -q --dims $D --window 4 --nodes 2 --shard-dir "$W/local%r/ds" \
    -o "$W/sd" $IN > /dev/null 2> "$W/sd.err" || fail "--shard-dir: $(cat "$W/sd.err")"
diff "$W/ref2/manifest.txt" "$W/sd/manifest.txt" > /dev/null \
    && diff -r "$W/ref2/node-0" "$W/local0/ds" > /dev/null \
    && diff -r "$W/ref2/node-1" "$W/local1/ds" > /dev/null \
    && [ ! -e "$W/sd/node-0" ] && [ ! -e "$W/local0/ds.partial" ] \
    && ok "--shard-dir: node directories byte-identical, in place" \
    || fail "--shard-dir output: $(ls -R "$W/sd" "$W/local0")"

# Under a memory limit each rank makes several passes over its slabs.
m=$($MPI -np 2 "$ENC" --axes xyz -j 1 --mem-limit 1M --dims $D --window 8 --nodes 2 -o "$W/none" $IN 2>&1 \
    | sed -n 's/.*give --mem-limit \([0-9]*\)K.*/\1/p' | head -1)
[ -n "$m" ] && [ ! -e "$W/none" ] && [ ! -e "$W/none.partial/node-1/axis-x.tvps" ] \
    && ok "too small a limit refused by rank 0 before any work" || fail "MPI refusal"
$MPI -np 2 "$ENC" --axes xyz -j 1 --mem-limit $((m + 300))K --dims $D --window 8 --nodes 2 -o "$W/lim" $IN \
    > "$W/lim.out" 2> "$W/lim.err" || fail "limited: $(cat "$W/lim.err")"
"$ENC" --axes xyz -q --dims $D --window 8 --nodes 2 -o "$W/ref8" $IN > /dev/null
p=$(sed -n 's/.*passes=\([0-9]*\).*/\1/p' "$W/lim.out")
diff -r "$W/ref8" "$W/lim" > /dev/null && [ "${p:-0}" -gt 3 ] \
    && ok "memory-limited MPI encode: $p passes on rank 0, byte-identical" \
    || fail "memory-limited MPI encode (passes ${p:-?})"

# kill -9 of rank 1 after 7 steps: nothing valid; the rerun completes.
TVPAL_ENCODE_FAULT_AFTER=7 TVPAL_ENCODE_FAULT_RANK=1 $MPI -np 3 "$ENC" --axes xyz -q --dims $D \
    --window 4 --nodes 3 -o "$W/kill" $IN > /dev/null 2>&1
rc=$?
[ $rc -ne 0 ] && [ $rc -ne 124 ] && [ ! -e "$W/kill" ] && [ ! -e "$W/kill.partial/manifest.txt" ] \
    && [ ! -e "$W/kill.partial/node-0/manifest.txt" ] \
    && ok "a rank killed: job ended ($rc), nothing that looks valid" \
    || fail "after kill -9 of a rank: rc $rc, $(ls -R "$W/kill"* | head)"
$MPI -np 3 "$ENC" --axes xyz --dims $D --window 4 --nodes 3 -o "$W/kill" $IN > /dev/null 2> "$W/kill.err" \
    || fail "rerun after kill: $(cat "$W/kill.err")"
grep -q "resuming" "$W/kill.err" && diff -r "$W/ref3" "$W/kill" > /dev/null \
    && ok "rerun resumed every rank, output byte-identical" \
    || fail "rerun after kill: $(cat "$W/kill.err")"

# A rank that fails: rank 0 reports it, every rank ends, the rerun resumes.
TVPAL_ENCODE_FAULT_AFTER=5 TVPAL_ENCODE_FAULT_RANK=2 TVPAL_ENCODE_FAULT=fail \
    $MPI -np 3 "$ENC" --axes xyz -q --dims $D --window 4 --nodes 3 -o "$W/fail" $IN > /dev/null 2> "$W/fail.err"
rc=$?
[ $rc -eq 1 ] && grep -q "^tvpal-encode: rank 2: test fault after 5 steps" "$W/fail.err" \
    && [ ! -e "$W/fail" ] && ok "a failing rank: exit 1, rank 0 names it" \
    || fail "failing rank: rc $rc: $(cat "$W/fail.err")"
$MPI -np 3 "$ENC" --axes xyz -q --dims $D --window 4 --nodes 3 -o "$W/fail" $IN > /dev/null 2>&1 \
    && diff -r "$W/ref3" "$W/fail" > /dev/null && ok "rerun after a failure: byte-identical" \
    || fail "rerun after a failure"

# --levels: rank 0 makes and encodes every node's levels after level 0;
# the dataset (levels and summary included) is the one process's.  A
# failure in level 2 ends every rank; the rerun resumes level 0 at its
# last step, keeps level 1 and redoes level 2 only.
"$ENC" --axes xyz -q --dims $D --window 4 --nodes 3 --levels 2 -o "$W/lref" $IN > "$W/lref.out"     || fail "--levels reference"
$MPI -np 3 "$ENC" --axes xyz -q --dims $D --window 4 --nodes 3 --levels 2 -o "$W/lmpi" $IN \
    > "$W/lmpi.out" 2> "$W/lmpi.err" || fail "--levels 2 on 3 ranks: $(cat "$W/lmpi.err")"
diff -r "$W/lref" "$W/lmpi" > /dev/null && [ -e "$W/lmpi/level-2/node-2/axis-z.tvps" ] \
    && ok "--levels 2 on 3 ranks: byte-identical to one process, every node's levels" \
    || fail "--levels 2 on 3 ranks differs"
[ "$(kv levels_bytes "$(cat "$W/lmpi.out")")" = "$(kv levels_bytes "$(cat "$W/lref.out")")" ] \
    && [ "$(kv bytes "$(cat "$W/lmpi.out")")" = "$(kv bytes "$(cat "$W/lref.out")")" ] \
    && ok "--levels on 3 ranks: bytes and levels_bytes as one process says" \
    || fail "summary: $(cat "$W/lmpi.out") / $(cat "$W/lref.out")"
TVPAL_ENCODE_FAULT_LEVEL=2 $MPI -np 3 "$ENC" --axes xyz -q --dims $D --window 4 --nodes 3 --levels 2 \
    -o "$W/lf" $IN > /dev/null 2> "$W/lf.err"
rc=$?
[ $rc -ne 0 ] && [ ! -e "$W/lf" ] && [ -e "$W/lf.partial/level-1/manifest.txt" ] \
    && [ ! -e "$W/lf.partial/level-2" ] && grep -q "level 2: failed" "$W/lf.err" \
    && ok "a level failing on rank 0 ends every rank (exit $rc), nothing in place" \
    || fail "level failure under MPI: rc $rc: $(cat "$W/lf.err")"
$MPI -np 3 "$ENC" --axes xyz --dims $D --window 4 --nodes 3 --levels 2 -o "$W/lf" $IN \
    > /dev/null 2> "$W/lf2.err"
grep -q "every step is encoded" "$W/lf2.err" && grep -q "level 2 of 2" "$W/lf2.err" \
    && ! grep -q "level 1 of 2" "$W/lf2.err" && diff -r "$W/lref" "$W/lf" > /dev/null \
    && ok "the rerun resumes level 0, keeps level 1, byte-identical" \
    || fail "rerun after a level failure: $(cat "$W/lf2.err")"

# A rerun asking for fewer levels keeps level 0 and level 1 and drops the
# earlier run's level 2 (it would have gone into OUTDIR unnamed).
TVPAL_ENCODE_FAULT_LEVEL=3 $MPI -np 3 "$ENC" --axes xyz -q --dims $D --window 4 --nodes 3 --levels 3 \
    -o "$W/lfew" $IN > /dev/null 2>&1
$MPI -np 3 "$ENC" --axes xyz -q --dims $D --window 4 --nodes 3 --levels 1 -o "$W/lfew" $IN > /dev/null 2>&1 \
    && [ ! -e "$W/lfew/level-2" ] && diff -r "$W/lref/level-1" "$W/lfew/level-1" > /dev/null \
    && ok "a rerun with fewer levels: no level beyond them left in OUTDIR" \
    || fail "fewer levels on rerun: $(ls "$W/lfew" "$W/lfew.partial" 2>&1)"

# Rank count and --nodes must agree.
$MPI -np 2 "$ENC" --axes xyz --dims $D --nodes 3 -o "$W/bad" $IN > /dev/null 2> "$W/bad.err"
rc=$?
[ $rc -eq 2 ] && grep -q "expected --nodes 2" "$W/bad.err" && [ "$(grep -c "expected --nodes" "$W/bad.err")" -eq 1 ] \
    && ok "--nodes 3 under 2 ranks refused once, by rank 0" || fail "rank count: rc $rc: $(cat "$W/bad.err")"

# Another job holds OUTDIR.partial's lock (here flock(1)): every rank stops
# before touching its node directory, rank 0 says why, once.
if command -v flock > /dev/null; then
    mkdir -p "$W/held.partial/node-1" && echo mine > "$W/held.partial/node-1/other-job"
    flock "$W/held.partial.lock" sleep 60 &
    fpid=$!
    sleep 0.5
    $MPI -np 2 "$ENC" --axes xyz -q --dims $D --window 4 --nodes 2 -o "$W/held" $IN > /dev/null 2> "$W/held.err"
    rc=$?
    kill $fpid 2> /dev/null; wait $fpid 2> /dev/null
    [ $rc -eq 1 ] && [ "$(grep -c "another encode is writing it" "$W/held.err")" -eq 1 ] \
        && [ "$(cat "$W/held.partial/node-1/other-job")" = mine ] \
        && ok "a locked OUTDIR.partial: every rank stopped, the other job's files untouched" \
        || fail "locked under MPI: rc $rc: $(cat "$W/held.err")"
else
    echo "no flock(1) (util-linux): the locked case is skipped"
fi
finish
