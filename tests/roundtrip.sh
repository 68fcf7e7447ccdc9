#!/bin/sh
# roundtrip: every generated field (odd sizes) at N = 1, 2, 4, 8, in both
# window schedules, encodes, decodes on all three axes and meets a PSNR
# floor that falls with N; the constant field is exact.  Floors are the
# measured values less 3 dB, so a regression of the codec shows here.  The
# joined schedule's are lower at the same N (its first windows hold up to
# 2N - 1 steps; on 13 steps of these small slices, where the tables are
# most of the bytes, it saves few bits: FORMAT.md 5).
. "$(dirname "$0")/lib.sh"
D=23x17x14
T=13
# schedule field: floors for N = 1 2 4 8 (dB)
for spec in "staggered blobs 113 62 56 52" "staggered turbulence 71 42 33 30" \
            "staggered front 88 51 43 37" "staggered constant inf inf inf inf" \
            "joined blobs 113 61 54 49" "joined turbulence 71 40 31 27" \
            "joined front 88 51 40 33" "joined constant inf inf inf inf"; do
    set -- $spec
    sch=$1 f=$2; shift 2
    [ -d "$W/in-$f" ] || "$GEN" --field "$f" --dims $D --steps $T -o "$W/in-$f" || fail "gen $f"
    for N in 1 2 4 8; do
        floor=$1; shift
        "$ENC" -q --dims $D --window $N --schedule $sch -o "$W/$sch-$f-$N" "$W/in-$f"/*.f32 \
            > /dev/null || { fail "encode $sch $f N=$N"; continue; }
        line=$("$REP" -q "$W/$sch-$f-$N") || { fail "report $sch $f N=$N"; continue; }
        p=$(kv psnr "$line"); pm=$(kv psnr_min "$line")
        if [ "$floor" = inf ]; then
            [ "$p" = inf ] && [ "$pm" = inf ] && ok "$sch $f N=$N exact" \
                || fail "$sch $f N=$N: psnr $p, expected exact (inf)"
        elif ge "$p" "$floor"; then
            ok "$sch $f N=$N psnr $p >= $floor (worst step $pm)"
        else
            fail "$sch $f N=$N: psnr $p < floor $floor"
        fi
    done
done
finish
