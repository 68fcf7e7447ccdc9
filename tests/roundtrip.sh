#!/bin/sh
# roundtrip: every generated field (odd sizes) at N = 1, 2, 4, 8 encodes,
# decodes on all three axes and meets a PSNR floor that falls with N; the
# constant field is exact.  Floors are the measured values less 3 dB, so a
# regression of the codec shows here.
. "$(dirname "$0")/lib.sh"
D=23x17x14
T=13
# field: floors for N = 1 2 4 8 (dB)
for spec in "blobs 113 62 56 52" "turbulence 71 42 33 30" "front 88 51 43 37" \
            "constant inf inf inf inf"; do
    set -- $spec
    f=$1; shift
    "$GEN" --field "$f" --dims $D --steps $T -o "$W/in-$f" || fail "gen $f"
    for N in 1 2 4 8; do
        floor=$1; shift
        "$ENC" -q --dims $D --window $N -o "$W/$f-$N" "$W/in-$f"/*.f32 \
            > /dev/null || { fail "encode $f N=$N"; continue; }
        line=$("$REP" -q "$W/$f-$N") || { fail "report $f N=$N"; continue; }
        p=$(kv psnr "$line"); pm=$(kv psnr_min "$line")
        if [ "$floor" = inf ]; then
            [ "$p" = inf ] && [ "$pm" = inf ] && ok "$f N=$N exact" \
                || fail "$f N=$N: psnr $p, expected exact (inf)"
        elif ge "$p" "$floor"; then
            ok "$f N=$N psnr $p >= $floor (worst step $pm)"
        else
            fail "$f N=$N: psnr $p < floor $floor"
        fi
    done
done
finish
