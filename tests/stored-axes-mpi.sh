#!/bin/sh
# stored-axes-mpi: mpirun -np 2 tvpal-encode --nodes 2 --axes z writes
# only the z shards, byte-identical to the one-process --axes z encode, and
# its summary's bytes (every rank's node directory and OUTDIR's manifest)
# is the sum of the files' sizes, also with --shard-dir; skipped (77)
# without mpirun or an MPI build.
. "$(dirname "$0")/lib.sh"
third_party_leaks
command -v mpirun > /dev/null || { echo "no mpirun: skipped"; exit 77; }
"$ENC" --version | grep -q "mpi: yes" || { echo "built without MPI: skipped"; exit 77; }
MPI="timeout 120 mpirun --allow-run-as-root --oversubscribe"
export OMPI_MCA_rmaps_base_oversubscribe=1
D=28x24x20
"$GEN" --field front --dims $D --steps 7 -o "$W/in" > /dev/null || fail gen
IN="$W/in/*.f32"
files_bytes() { find "$@" -type f -exec stat -c %s {} + | awk '{ s += $1 } END { print s + 0 }'; }

"$ENC" -q --dims $D --window 4 --nodes 2 --axes z -o "$W/ref" $IN > "$W/ref.out" || fail "one-process --axes z"
$MPI -np 2 "$ENC" -q --dims $D --window 4 --nodes 2 --axes z -o "$W/mpi" $IN \
    > "$W/mpi.out" 2> "$W/mpi.err" || fail "mpirun --axes z: $(cat "$W/mpi.err")"
diff -r "$W/ref" "$W/mpi" > /dev/null && ok "MPI --axes z output byte-identical" \
    || fail "MPI --axes z output differs"
[ "$(ls "$W/mpi/node-1" | tr '\n' ' ')" = "axis-z.tvps manifest.txt " ] \
    && grep -q "^axes = z$" "$W/mpi/manifest.txt" && ok "only the z shards, axes = z" \
    || fail "node-1 holds: $(ls "$W/mpi/node-1" | tr '\n' ' ')"
line=$(cat "$W/mpi.out")
[ "$(kv bytes "$line")" = "$(files_bytes "$W/mpi")" ] && [ "$(kv ratio "$line")" = "$(kv ratio "$(cat "$W/ref.out")")" ] \
    && [ "$(kv axis_ratio "$line")" = "$(kv axis_ratio "$(cat "$W/ref.out")")" ] \
    && ok "summary: bytes $(kv bytes "$line") every file, ratio and axis_ratio as one process" \
    || fail "summary: $line; one process: $(cat "$W/ref.out"); files $(files_bytes "$W/mpi")"
$MPI -np 2 "$ENC" -q --dims $D --window 4 --nodes 2 --axes z --shard-dir "$W/local%r/ds" \
    -o "$W/sd" $IN > "$W/sd.out" 2> "$W/sd.err" || fail "--shard-dir: $(cat "$W/sd.err")"
[ "$(kv bytes "$(cat "$W/sd.out")")" = "$(files_bytes "$W/sd" "$W/local0/ds" "$W/local1/ds")" ] \
    && diff -r "$W/ref/node-0" "$W/local0/ds" > /dev/null \
    && ok "--shard-dir: bytes counts the node directories and the manifest" \
    || fail "--shard-dir: $(cat "$W/sd.out")"
finish
