#!/bin/sh
# cluster: mpirun -np K tvpal-play (one rank per shard, binary-swap or
# gather compositing) gives the single-node image for K = 1, 2, 3, 4, 5, 8,
# on every axis in both depth directions, with an empty slab; bytes sent per
# rank follow the model image bytes x (1 - 1/K) on a dense image; a rank
# count that does not match the shards, a missing shard directory and a
# corrupt record on one rank stop every rank with a message from rank 0.
# The exact comparisons use the GL renderer (per-pixel compositing of the
# slabs is exact there); the CPU shear-warp renderer gets its own tolerance.
. "$(dirname "$0")/lib.sh"
third_party_leaks
PLAY=$TVPAL_BUILDDIR/player/app/tvpal-play
[ -x "$PLAY" ] || { echo "built without OSMesa/libpng: skipped"; exit 77; }
command -v mpirun > /dev/null || { echo "no mpirun (scripts/setup-deps installs openmpi-bin)"; exit 99; }
"$PLAY" --help | grep -q -- "--composite" || exit 99
"$PLAY" --version | grep -q "mpi: yes" || { echo "built without MPI: skipped (an MPI launch is refused; see below)"; \
    TVPAL_COMM=mpi "$PLAY" --version > /dev/null 2> "$W/nompi.txt"; \
    grep -q "libopenmpi-dev" "$W/nompi.txt" && exit 77; cat "$W/nompi.txt"; exit 1; }
MPI="timeout 300 mpirun --allow-run-as-root --oversubscribe"
export LP_NUM_THREADS=1 OMPI_MCA_rmaps_base_oversubscribe=1
# A build without OSMesa has only the cpu renderer: the same checks run with
# it, at its tolerance (see below).
if "$PLAY" --version | grep -q "gl: yes"; then
    GLR="--renderer gl" TOL=1
else
    GLR="--renderer cpu" TOL=6
    echo "built without OSMesa: the comparisons run with the cpu renderer (tolerance $TOL levels)"
fi
within() { # pngdiff-output: max <= TOL
    [ "$(echo "$1" | sed 's/max=\([0-9]*\).*/\1/')" -le $TOL ]
}
D=24x20x16
TF=$TVPAL_SRCDIR/samples/tf/warm.tf
# Slabs along z hold z in [0,16): blobs live in the middle; a band TF that
# is transparent below mid-range leaves the outer slabs empty.
"$GEN" --field blobs --dims $D --steps 4 -o "$W/in" || fail gen
# The views, as sweeps: one launch draws several, --spin turning the view
# about the screen's y axis each frame (R = Ry(spin) Rx(a), so a start at
# 90,0 looks along +y, x, -y, -x in turn).  Starting mpirun costs a second
# or more (8 ranks on 2 cores), a 64x56 frame next to nothing, so a sweep
# checks every view for about the price of one.
#   90,0/90/0:3   along y and x, both ways: the slabs side by side;
#   0,0/180/0:1   along +z and -z: the slabs behind one another, both orders;
#   30,40/90/0:3  between the axes, in four quadrants (elevation 30).
SWEEPS="90,0/90/0:3 0,0/180/0:1 30,40/90/0:3"
# diffs REF OUT: pngdiff_dirs's lines; a missing frame or a failed
# comparison reads as max=255 differing=1.
diffs() { pngdiff_dirs "$1" "$2" || echo "max=255 differing=1"; }
max_of() { sed 's/max=\([0-9]*\).*/\1/' | sort -n | tail -n 1; }        # lines: the largest max
share_of() { sed 's/.*differing=//' | sort -g | tail -n 1; }              # lines: the largest share
for K in 1 2 3 4 5 8; do
    "$ENC" --axes xyz -q --dims $D --window 2 --nodes $K -o "$W/k$K" "$W"/in/*.f32 > /dev/null || fail "encode K=$K"
done
i=0
for sw in $SWEEPS; do
    i=$((i + 1))
    "$PLAY" "$W/k1" --headless -q $GLR --size 64x56 $(sweep_opts $sw) --tf "$TF" -o "$W/ref-$i" \
        --csv "$W/ref-$i.csv" > /dev/null || fail "single-node $sw"
done
# The sweeps look along the axes they are said to: the slices drawn.
axes=""
for i in 1 2 3; do
    axes="$axes $(awk -F, 'NR == 1 { for (i = 1; i <= NF; i++) if ($i == "axis") c = i; next }
                          { printf "%s", $c }' "$W/ref-$i.csv")"
done
n=$(ls "$W"/ref-*/*.png | wc -l)
case "$axes" in
    " yxyx zz "????) [ "$n" -eq 10 ] && ok "sweeps: slices along$axes, $n frames" \
                         || fail "sweeps drew $n frames, not 10" ;;
    *) fail "sweeps drew slices along '$axes' (expected yxyx, zz and four more)" ;;
esac
for K in 1 2 3 4 5 8; do
    for comp in bswap gather; do
        [ $K -eq 1 ] && [ $comp = gather ] && continue
        worst=0 i=0
        for sw in $SWEEPS; do
            i=$((i + 1))
            $MPI -np $K "$PLAY" "$W/k$K" --headless -q $GLR --size 64x56 $(sweep_opts $sw) --tf "$TF" \
                --composite $comp -o "$W/c$K-$comp-$i" > "$W/o.txt" 2>&1 \
                || { fail "K=$K $comp sweep $sw: $(tail -n 3 "$W/o.txt")"; continue; }
            m=$(diffs "$W/ref-$i" "$W/c$K-$comp-$i" | max_of)
            [ "$m" -gt "$worst" ] && worst=$m
        done
        # Tolerance: one 8-bit level (float blending order differs).
        [ "$worst" -le $TOL ] && ok "K=$K $comp: all views and depth directions within $worst level(s)" \
            || fail "K=$K $comp: composited image differs from single node by $worst levels"
    done
done
# The CPU renderer on a cluster: each rank warps its own partial image, and
# the warp's bilinear filter does not commute with "over", so the composite
# differs from the single-node CPU image by a few 8-bit levels where alpha
# changes within a pixel (measured: at most 4).  Tolerance: 6 levels, on at
# most 5% of the pixels.  The sweeps along x and y, and between the axes.
CSWEEPS="90,0/90/0:3 30,40/90/0:3"
for sw in $CSWEEPS; do
    "$PLAY" "$W/k1" --headless -q --renderer cpu --size 64x56 $(sweep_opts $sw) --tf "$TF" \
        -o "$W/cref-${sw%%/*}" > /dev/null || fail "cpu single-node $sw"
done
for K in 2 3 5 8; do
    worst=0 share=0
    for sw in $CSWEEPS; do
        view=${sw%%/*}
        $MPI -np $K "$PLAY" "$W/k$K" --headless -q --renderer cpu --size 64x56 $(sweep_opts $sw) \
            --tf "$TF" -o "$W/cc$K-$view" > "$W/o.txt" 2>&1 \
            || { fail "cpu K=$K sweep $sw: $(tail -n 3 "$W/o.txt")"; continue; }
        r=$(diffs "$W/cref-$view" "$W/cc$K-$view")
        m=$(echo "$r" | max_of) d=$(echo "$r" | share_of)
        [ "$m" -gt "$worst" ] && worst=$m
        share=$(awk -v a="$share" -v b="$d" 'BEGIN { print (b > a) ? b : a }')
    done
    [ "$worst" -le 6 ] && awk -v s="$share" 'BEGIN { exit !(s <= 0.05) }' \
        && ok "cpu K=$K: within $worst level(s) of the single-node CPU image, on $share of the pixels" \
        || fail "cpu K=$K: $worst levels, $share of the pixels differ"
done
# Empty slabs: with a TF transparent below mid-range, K=5 slabs along x
# include slabs with nothing to show.
printf 'domain normalized\n0 0 0 0 0\n0.55 0 0 0 0\n0.7 1 0.6 0.2 0.5\n1 1 1 1 0.9\n' > "$W/high.tf"
"$PLAY" "$W/k1" --headless -q $GLR --size 64x56 --rotate 0,90 --tf "$W/high.tf" -o "$W/ref-high" > /dev/null
$MPI -np 5 "$PLAY" "$W/k5" --headless -q $GLR --size 64x56 --rotate 0,90 --tf "$W/high.tf" -o "$W/c5-high" > "$W/o.txt" 2>&1 \
    || fail "K=5 high TF"
r=$($PY "$TVPAL_SRCDIR/tests/pngdiff.py" "$W/ref-high/t0001.png" "$W/c5-high/t0001.png")
within "$r" && ok "K=5 with empty slabs: $r" || fail "empty slabs: $r"
# Bytes sent: a dense image (opaque everywhere, zoomed in so the volume
# covers the frame) at K = 4: binary swap sends 1/2 + 1/4 of the image.
printf 'domain normalized\n0 0.5 0.5 0.5 0.3\n1 1 1 1 0.3\n' > "$W/dense.tf"
$MPI -np 4 "$PLAY" "$W/k4" --headless -q $GLR --size 64x56 --rotate 0,0 --zoom 4 --tf "$W/dense.tf" \
    --steps 0:0 --csv "$W/dense.csv" > "$W/o.txt" 2>&1 || fail "dense K=4"
sent=$(awk -F, 'NR == 1 { for (i = 1; i <= NF; i++) if ($i == "bytes_sent_max") c = i }
                NR == 2 { print $c }' "$W/dense.csv")
model=$((64 * 56 * 8 * 3 / 4))   # 16-bit RGBA on the wire
awk -v s="$sent" -v m="$model" 'BEGIN { d = (s - m) / m; exit !(d > -0.05 && d < 0.05) }' \
    && ok "K=4 dense: $sent bytes sent by the busiest rank, model $model" \
    || fail "K=4 dense: $sent bytes sent, model $model"
# Errors on every rank, reported by rank 0, no hang.
expect_exit 2 "dataset has 3 node shards; started with 2 ranks" $MPI -np 2 "$PLAY" "$W/k3" --headless -q $GLR
cp -r "$W/k3" "$W/k3m" && rm -rf "$W/k3m/node-1"
expect_exit 2 "rank 1: .*node-1/manifest.txt" $MPI -np 3 "$PLAY" "$W/k3m" --headless -q $GLR
cp -r "$W/k3" "$W/k3c"
$PY - "$W/k3c/node-2/axis-z.tvps" <<'PY'
import struct, sys
p = sys.argv[1]; b = bytearray(open(p, "rb").read())
idx = struct.unpack_from("<Q", b, 72)[0]
off = struct.unpack_from("<Q", b, idx + 32 * 2)[0]  # (N = 2, joined: record 1 is empty)
b[off + 64 + 5] ^= 0x40
open(p, "wb").write(b)
PY
expect_exit 2 "rank 2: step 2: .*axis-z.tvps: record 2: payload CRC-32C mismatch" \
    $MPI -np 3 "$PLAY" "$W/k3c" --headless -q $GLR --rotate 0,0 --strict
expect_exit 1 "rank 2: step 2: .*record 2: payload CRC-32C mismatch \(keeping" \
    $MPI -np 3 "$PLAY" "$W/k3c" --headless -q $GLR --rotate 0,0
# A rank that dies (SIGKILL mid-playback) ends the job instead of hanging.
$MPI -np 3 "$PLAY" "$W/k3" --headless -q $GLR --size 64x56 --spin 3 --steps 0:2 --repeat 20000 \
    > "$W/kill.txt" 2>&1 &
mpid=$!
victim=""
for i in $(seq 50); do
    for p in $(pgrep -f "tvpal-play $W/k3" 2>/dev/null); do
        tr '\0' '\n' < /proc/$p/environ 2>/dev/null | grep -qx OMPI_COMM_WORLD_RANK=1 && victim=$p
    done
    [ -n "$victim" ] && break
    sleep 0.2
done
sleep 0.5
[ -n "$victim" ] && kill -9 "$victim"
wait $mpid
rc=$?
[ -n "$victim" ] && [ $rc -ne 0 ] && [ $rc -ne 124 ] && ok "killing rank 1 ends the job (mpirun exit $rc)" \
    || fail "killed rank: victim '$victim', mpirun exit $rc"
# --shard-dir maps each rank's shard to its own path.
mkdir -p "$W/disks" && for r in 0 1 2; do cp -r "$W/k3/node-$r" "$W/disks/local$r"; done
$MPI -np 3 "$PLAY" "$W/nowhere" --shard-dir "$W/disks/local%r" --headless -q $GLR --size 64x56 \
    --rotate 30,40 --tf "$TF" -o "$W/c3-map" > "$W/o.txt" 2>&1 || fail "--shard-dir: $(cat "$W/o.txt")"
# The 30,40 sweep's first frame is step 0 seen from 30,40.
r=$($PY "$TVPAL_SRCDIR/tests/pngdiff.py" "$W/ref-3/t0000.png" "$W/c3-map/t0000.png")
within "$r" && ok "--shard-dir: $r" || fail "--shard-dir: $r"
# Rank 0 shows the composited frame in its window (Xvfb); keys pressed in
# it reach every rank (Right x2 from step 0 shows step 2 of all slabs), and
# S saves the frame of the keys before it.
if "$PLAY" --version | grep -q "window: yes" && command -v xvfb-run > /dev/null \
   && command -v xdotool > /dev/null; then
    "$PLAY" "$W/k1" --headless -q $GLR --size 64x56 --rotate 30,40 --tf "$TF" -o "$W/ref-w" > /dev/null
    timeout 120 xvfb-run -a -s "-screen 0 640x480x24" $MPI -np 3 "$PLAY" "$W/k3" --window --no-hud $GLR \
        --steps 1:1 --size 64x56 --rotate 30,40 --tf "$TF" --autoplay 1 \
        --screenshot "$W/win3.png" > "$W/o.txt" 2>&1 || fail "cluster window: $(tail -n 3 "$W/o.txt")"
    cmp -s "$W/win3.png" "$W/ref-w/t0001.png" && ok "K=3 window shows the single-node frame" \
        || fail "K=3 window frame differs: $($PY "$TVPAL_SRCDIR/tests/pngdiff.py" "$W/win3.png" "$W/ref-w/t0001.png")"
    # The window's default renderer under Xvfb (llvmpipe) is cpu: the same
    # frame as the headless CPU run of the same ranks.
    $MPI -np 3 "$PLAY" "$W/k3" --headless -q --renderer cpu --steps 1:1 --size 64x56 \
        --rotate 30,40 --tf "$TF" -o "$W/c3cpu" > /dev/null 2>&1 || fail "K=3 cpu headless"
    timeout 120 xvfb-run -a -s "-screen 0 640x480x24" $MPI -np 3 "$PLAY" "$W/k3" --window --no-hud \
        --steps 1:1 --size 64x56 --rotate 30,40 --tf "$TF" --autoplay 1 \
        --screenshot "$W/win3cpu.png" > "$W/o.txt" 2>&1 || fail "cluster cpu window: $(tail -n 3 "$W/o.txt")"
    grep -q "renderer cpu (shear-warp.*default: the window's GL is .*draws on the CPU" "$W/o.txt" \
        && ok "window default renderer: $(grep -o 'renderer cpu.*' "$W/o.txt" | head -n 1)" \
        || fail "window default renderer: $(cat "$W/o.txt")"
    cmp -s "$W/win3cpu.png" "$W/c3cpu/t0001.png" && ok "K=3 cpu window shows the headless CPU frame" \
        || fail "K=3 cpu window differs: $($PY "$TVPAL_SRCDIR/tests/pngdiff.py" "$W/win3cpu.png" "$W/c3cpu/t0001.png")"
    cat > "$W/drive.sh" <<DRIVE
#!/bin/sh
cd "$W"
$MPI -np 3 "$PLAY" "$W/k3" --window --no-hud $GLR --size 64x56 --rotate 30,40 --tf "$TF" > "$W/play.txt" 2>&1 &
pid=\$!
wid=\$(xdotool search --sync --name tvpal-play | head -n 1)
sleep 1
# One burst: S is read in the same poll as the Right keys before it and
# must still save the frame they lead to (step 2), however slow the frame.
xdotool key --window \$wid Right Right s; sleep 2
xdotool key --window \$wid q 2>/dev/null
wait \$pid
DRIVE
    timeout 120 xvfb-run -a -s "-screen 0 640x480x24" sh "$W/drive.sh" || fail "driving the cluster window"
    cmp -s "$W/tvpal-shot-0000.png" "$W/ref-w/t0002.png" \
        && ok "K=3: keys reach every rank (Right x2 = step 2)" \
        || fail "K=3 keys: $(cat "$W/play.txt" | tail -n 3)"
else
    echo "no GLFW, Xvfb or xdotool: cluster window test not run"
fi
finish
