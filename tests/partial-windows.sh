#!/bin/sh
# partial-windows: every timestep decodes for T < N, T % N != 0 and T = 1,
# in both window schedules; random jumps, backward and forward playback all
# give the same volumes as a sequential decode, and a jump reads at most N
# records per shard.
. "$(dirname "$0")/lib.sh"
CHK=$TVPAL_BUILDDIR/tests/tvpal-check
D=19x11x9
"$GEN" --field blobs --dims $D --steps 11 -o "$W/in" || fail gen
for case in "1 4 joined" "3 8 joined" "10 4 joined" "11 3 joined" "5 5 joined" \
            "7 16 joined" "11 1 joined" "9 5 joined" "3 8 staggered" "10 4 staggered" \
            "11 3 staggered" "7 16 staggered"; do
    set -- $case
    T=$1 N=$2 S=$3
    files=$(ls "$W"/in/*.f32 | head -n "$T")
    rm -rf "$W/d-$T-$N"
    "$ENC" --axes xyz -q --dims $D --window "$N" --schedule $S -o "$W/d-$T-$N" $files > /dev/null \
        || { fail "encode T=$T N=$N $S"; continue; }
    "$CHK" seqjump "$W/d-$T-$N" > "$W/sj.txt" 2>&1 \
        && ok "T=$T N=$N $S: jumps = sequential" \
        || { fail "T=$T N=$N $S seqjump"; cat "$W/sj.txt" >&2; }
    last=$((T - 1))
    for a in x y z; do
        "$DEC" "$W/d-$T-$N" --step $last --axis $a -o "$W/last.f32" \
            || fail "decode last step T=$T N=$N axis $a"
    done
    line=$("$REP" -q "$W/d-$T-$N") || { fail "report T=$T N=$N"; continue; }
    p=$(kv psnr_min "$line")
    ge "$p" 35 && ok "T=$T N=$N $S worst step psnr $p" \
        || fail "T=$T N=$N $S: worst step psnr $p < 35"
    expect_exit 2 "expected 0\.\.$last" "$DEC" "$W/d-$T-$N" --step "$T" -o "$W/x.f32"
done
finish
