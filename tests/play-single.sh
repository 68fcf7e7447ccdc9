#!/bin/sh
# play-single: single-copy datasets (tvpal-encode --axes z) played.
#  - The z shard of a single-copy encode is byte for byte the z shard of
#    the three-copy encode, and the dataset is about a third of its size.
#  - Views along x, y, z and between the axes, cpu and gl renderers: the
#    image against the reference renderer (on the same decoded data, the
#    player's --ref-psnr) is as close as the three-copy dataset's (within
#    0.5 dB) and at least 35 dB (test-sw's floor); and the three-copy dataset
#    drawn from its z slices (--from-z) gives the very same PNG frames as
#    the single-copy one.
#  - cpu: 1 and 2 threads give the same bits; a transfer function change
#    every frame (--tf-cycle) and random jumps (--jumps) give the frames of
#    plain sequential playback with that transfer function.
#  - Crossing the principal axes (--spin) streams no record more than a
#    fixed view (three copies: it reads the other axes' records).
#  - Cluster (mpirun, K = 2, 3, 5, z slabs; ten views in four sweeps):
#    every view within the cpu cluster tolerance of tests/cluster.sh for
#    views along z and between axes, and for x and y views within the
#    stated seam tolerance below.
#  - Old three-copy datasets still play every view from their own axes.
. "$(dirname "$0")/lib.sh"
third_party_leaks
PLAY=$TVPAL_BUILDDIR/player/app/tvpal-play
[ -x "$PLAY" ] || { echo "built without OSMesa/libpng: skipped"; exit 77; }
"$ENC" --help | grep -q -- "--axes" || fail "tvpal-encode has no --axes"
D=40x36x32
"$GEN" --field turbulence --dims $D --steps 4 -o "$W/in" || fail gen
"$ENC" -q --dims $D --window 2 --axes xyz -o "$W/xyz" "$W"/in/*.f32 > /dev/null || fail "encode xyz"
"$ENC" -q --dims $D --window 2 --axes z -o "$W/z" "$W"/in/*.f32 > /dev/null || fail "encode z"
cmp -s "$W/xyz/node-0/axis-z.tvps" "$W/z/node-0/axis-z.tvps" \
    && ok "single copy: its z shard is the three-copy one's, byte for byte" \
    || fail "single copy: the z shards differ"
[ ! -e "$W/z/node-0/axis-x.tvps" ] && [ ! -e "$W/z/node-0/axis-y.tvps" ] \
    && ok "single copy: no x or y shard" || fail "single copy has x or y shards"
bz=$(cat "$W"/z/node-0/*.tvps | wc -c) bx=$(cat "$W"/xyz/node-0/*.tvps | wc -c)
awk -v a="$bz" -v b="$bx" 'BEGIN { r = a / b; exit !(r > 0.30 && r < 0.37) }' \
    && ok "single copy: $bz bytes of shards, three copies $bx" \
    || fail "single copy: $bz bytes against $bx (expected about a third)"
HAVE_GL=0
"$PLAY" --version | grep -q "gl: yes" && HAVE_GL=1
VIEWS="0,0 0,90 90,0 30,60 -80,20 10,130 180,-90"
for r in cpu gl; do
    [ $r = gl ] && [ $HAVE_GL = 0 ] && { echo "no OSMesa: gl views skipped"; continue; }
    worst=""
    for view in $VIEWS; do
        p1=$("$PLAY" "$W/z" --headless -q --renderer $r --size 96x80 --rotate $view \
            --ref-psnr -o "$W/$r-z-$view" | sed -n 's/^psnr_ref=\([0-9.]*\)$/\1/p')
        p3=$("$PLAY" "$W/xyz" --headless -q --renderer $r --size 96x80 --rotate $view \
            --ref-psnr | sed -n 's/^psnr_ref=\([0-9.]*\)$/\1/p')
        [ -n "$p1" ] && [ -n "$p3" ] || fail "$r view $view: no psnr_ref ($p1, $p3)"
        awk -v a="$p1" -v b="$p3" 'BEGIN { exit !(a >= 35 && a >= b - 0.5) }' \
            || fail "$r view $view: one copy $p1 dB, three copies $p3 dB against the reference"
        worst="$worst $view:$p1/$p3"
        "$PLAY" "$W/xyz" --headless -q --renderer $r --size 96x80 --rotate $view \
            --from-z -o "$W/$r-f-$view" > /dev/null || fail "$r --from-z $view"
        for f in "$W/$r-z-$view"/*.png; do
            cmp -s "$f" "$W/$r-f-$view/$(basename "$f")" \
                || fail "$r view $view $(basename "$f"): single copy differs from --from-z"
        done
    done
    ok "$r against the reference, one copy/three copies dB:$worst"
done
# Threads, TF changes and jumps (cpu).
for view in 0,90 90,0; do
    OMP_NUM_THREADS=1 "$PLAY" "$W/z" --headless -q --renderer cpu --size 96x80 --rotate $view \
        -o "$W/t1-$view" > /dev/null || fail "1 thread"
    OMP_NUM_THREADS=2 "$PLAY" "$W/z" --headless -q --renderer cpu --size 96x80 --rotate $view \
        -o "$W/t2-$view" > /dev/null || fail "2 threads"
    for f in "$W/t1-$view"/*.png; do
        cmp -s "$f" "$W/t2-$view/$(basename "$f")" || fail "view $view: 1 and 2 threads differ"
    done
done
ok "cpu x and y views: 1 and 2 threads give the same bits"
TFW=$TVPAL_SRCDIR/samples/tf/warm.tf TFB=$TVPAL_SRCDIR/samples/tf/band.tf
"$PLAY" "$W/z" --headless -q --renderer cpu --size 96x80 --rotate 0,90 --tf "$TFW" --tf "$TFB" \
    --tf-cycle -o "$W/cyc" > /dev/null || fail "tf-cycle"
"$PLAY" "$W/z" --headless -q --renderer cpu --size 96x80 --rotate 0,90 --tf "$TFW" -o "$W/cw" > /dev/null
"$PLAY" "$W/z" --headless -q --renderer cpu --size 96x80 --rotate 0,90 --tf "$TFB" -o "$W/cb" > /dev/null
cmp -s "$W/cyc/t0000.png" "$W/cw/t0000.png" && cmp -s "$W/cyc/t0001.png" "$W/cb/t0001.png" \
    && cmp -s "$W/cyc/t0002.png" "$W/cw/t0002.png" \
    && ok "a TF change every frame draws what each TF draws alone" || fail "tf-cycle frames differ"
"$PLAY" "$W/z" --headless -q --renderer cpu --size 96x80 --rotate 90,0 --jumps 1 \
    --csv "$W/j.csv" -o "$W/jump" > /dev/null || fail "jumps"
n=0
for f in "$W/jump"/*.png; do
    cmp -s "$f" "$W/t2-90,0/$(basename "$f")" || fail "after a jump, $(basename "$f") differs"
    n=$((n + 1))
done
ok "$n frames after random jumps are the sequential ones"
# Crossing axes reads nothing more (streamed, no prefetch: each step read once).
br() { sed 's/.*bytes_read=\([0-9]*\).*/\1/'; }
fixed=$("$PLAY" "$W/z" --headless -q --renderer cpu --size 64x64 --prefetch 0 --steps 0:3 | br)
spun=$("$PLAY" "$W/z" --headless -q --renderer cpu --size 64x64 --prefetch 0 --steps 0:3 \
    --spin 60 --csv "$W/spin.csv" | br)
axes=$(awk -F, 'NR == 1 { for (i = 1; i <= NF; i++) if ($i == "axis") c = i; next }
                { print $c }' "$W/spin.csv" | sort -u | tr -d '\n')
[ "$spun" = "$fixed" ] && [ ${#axes} -ge 2 ] \
    && ok "spin over axes $axes: $spun bytes read, as a fixed view" \
    || fail "spin over axes $axes read $spun bytes, a fixed view $fixed"
x3=$("$PLAY" "$W/xyz" --headless -q --renderer cpu --size 64x64 --prefetch 0 --steps 0:3 --spin 60 | br)
[ "$x3" -gt "$fixed" ] && ok "three copies, the same spin: $x3 bytes (the other axes' records)" \
    || fail "three copies read $x3 bytes on the spin, expected more than $fixed"
# Cluster: z slabs, rank order along the view's z, K = 2, 3, 5.  Each node
# gets its neighbours' boundary rows (ghost rows), so the nodes' samples
# are exactly the one node's: gl within one 8-bit level (as
# tests/cluster.sh), cpu along z and between the axes within the cpu
# cluster tolerance there (6 levels on at most 5% of the pixels).  cpu
# views along x and y: a slab boundary is then a line across the image
# where two nodes' warped images abut, and "over" of two bilinearly
# warped images that each half cover a pixel is not their sum (measured:
# at most 21 levels, at K = 3 in a view near y, and at most 0.6% of the
# pixels; 0 at K = 2, whose boundary falls between pixels here).  Stated
# tolerance there: 24 levels on at most 2% of the pixels.
if command -v mpirun > /dev/null && "$PLAY" --version | grep -q "mpi: yes"; then
    MPI="timeout 300 mpirun --allow-run-as-root --oversubscribe"
    export LP_NUM_THREADS=1 OMPI_MCA_rmaps_base_oversubscribe=1
    DC=24x20x16 TF=$TVPAL_SRCDIR/samples/tf/warm.tf
    "$GEN" --field blobs --dims $DC --steps 3 -o "$W/cin" || fail gen
    for K in 1 2 3 5; do
        "$ENC" -q --dims $DC --window 2 --nodes $K --axes z -o "$W/k$K" "$W"/cin/*.f32 > /dev/null \
            || fail "encode K=$K"
    done
    RS=cpu
    [ $HAVE_GL = 1 ] && RS="cpu gl"
    # Views as sweeps, a launch each (--spin turns the view about the
    # screen's y each frame, a frame per step): from 0,0 along +z and -z,
    # from 30,40 two views between the axes (the cpu tolerance along z);
    # from 90,0 along +y, x and -y, from -80,20 three views near y (the
    # seam tolerance).
    SWEEPS="0,0/180/0:1 30,40/180/0:1 90,0/90/0:2 -80,20/120/0:2"
    for r in $RS; do
        for sw in $SWEEPS; do
            "$PLAY" "$W/k1" --headless -q --renderer $r --size 64x56 $(sweep_opts $sw) --tf "$TF" \
                -o "$W/cref-$r-${sw%%/*}" > /dev/null || fail "one node, $r $sw"
        done
        for K in 2 3 5; do
            worst=0 wshare=0 frames=0
            for sw in $SWEEPS; do
                view=${sw%%/*}
                $MPI -np $K "$PLAY" "$W/k$K" --headless -q --renderer $r --size 64x56 \
                    $(sweep_opts $sw) --tf "$TF" -o "$W/c$K-$r-$view" > "$W/o.txt" 2>&1 \
                    || { fail "$r K=$K sweep $sw: $(tail -n 3 "$W/o.txt")"; continue; }
                case $r-$view in
                gl-*) lim=1 share=1 ;;
                cpu-0,0|cpu-30,40) lim=6 share=0.05 ;;
                *) lim=24 share=0.02 ;;
                esac
                pngdiff_dirs "$W/cref-$r-$view" "$W/c$K-$r-$view" > "$W/d.txt" \
                    || fail "$r K=$K sweep $sw: frames missing or not comparable"
                frames=$((frames + $(wc -l < "$W/d.txt")))
                while read -r res; do
                    m=$(echo "$res" | sed 's/max=\([0-9]*\).*/\1/') d=$(echo "$res" | sed 's/.*differing=//')
                    [ "$m" -gt "$worst" ] && worst=$m
                    wshare=$(awk -v a="$wshare" -v b="$d" 'BEGIN { print (b > a) ? b : a }')
                    [ "$m" -le $lim ] && awk -v d="$d" -v s="$share" 'BEGIN { exit !(d <= s) }' \
                        || fail "$r K=$K sweep $sw: $res (limit $lim levels on $share)"
                done < "$W/d.txt"
            done
            [ $frames -eq 10 ] && ok "$r K=$K: z slabs with ghost rows, $frames views within the stated tolerance (worst $worst levels, on $wshare)" \
                || fail "$r K=$K: $frames frames compared, not 10"
        done
    done
else
    echo "no mpirun or built without MPI: cluster part skipped"
fi
# Old three-copy datasets draw x views from their own x slices, not z.
"$PLAY" "$W/xyz" --headless -q --renderer cpu --size 96x80 --rotate 0,90 -o "$W/own" > /dev/null \
    || fail "three copies, x view"
cmp -s "$W/own/t0001.png" "$W/cpu-f-0,90/t0001.png" \
    && fail "three copies: the x view is drawn from z" \
    || ok "three copies: the x view is drawn from the x slices"
finish
