#!/bin/sh
# play-missing: missing values are drawn fully transparent.  A volume with
# a hole of missing voxels through it and a missing block in front of
# other data draws, with the cpu and the gl renderer and on two MPI ranks,
# like the same volume with those voxels at a value the transfer function
# makes transparent (what lies behind shows; within the quantization's
# difference), and differently from the volume without them (so the test
# can tell); --nan-color 1,0,0 draws them red; a ParaView preset's
# NanColor is honoured and --nan-color none overrides it.
. "$(dirname "$0")/lib.sh"
third_party_leaks
PLAY=$TVPAL_BUILDDIR/player/app/tvpal-play
[ -x "$PLAY" ] || { echo "built without OSMesa/libpng: skipped"; exit 77; }
D=24x20x16
"$GEN" --field blobs --dims $D --steps 4 -o "$W/in" > /dev/null || fail gen
mkdir -p "$W/nan" "$W/low"
$PY - "$W" <<'PY' || fail "inputs"
import glob, math, struct, sys
w = sys.argv[1]
files = sorted(glob.glob(w + "/in/*.f32"))
allv = []
for f in files:
    b = open(f, "rb").read()
    allv += struct.unpack("<%df" % (len(b) // 4), b)
lo = min(allv)
for f in files:
    b = open(f, "rb").read()
    v = list(struct.unpack("<%df" % (len(b) // 4), b))
    nan, low = list(v), list(v)
    for z in range(16):
        for y in range(20):
            for x in range(24):
                hole = 4 <= x < 12 and 4 <= y < 12
                block = 13 <= x < 21 and 8 <= y < 16 and z >= 8
                if hole or block:
                    i = x + 24 * (y + 20 * z)
                    nan[i] = float("nan")
                    low[i] = lo
    name = f.rsplit("/", 1)[1]
    open(w + "/nan/" + name, "wb").write(struct.pack("<%df" % len(nan), *nan))
    open(w + "/low/" + name, "wb").write(struct.pack("<%df" % len(low), *low))
PY
for s in in nan low; do
    "$ENC" -q --dims $D --window 2 --nodes 2 -o "$W/ds-$s" "$W/$s"/*.f32 > /dev/null || fail "encode $s"
done
grep -q "^missing = 6144$" "$W/ds-nan/manifest.txt" && ok "4 steps x 1536 voxels missing" \
    || fail "missing count: $(grep missing "$W/ds-nan/manifest.txt")"
TF=$TVPAL_SRCDIR/samples/tf/warm.tf
diff_of() { "$PY" "$TVPAL_SRCDIR/tests/pngdiff.py" "$1" "$2" | sed 's/max=\([0-9]*\).*/\1/'; }
for r in cpu gl; do
    for s in in nan low; do
        "$PLAY" "$W/ds-$s" --headless -q --renderer $r --size 96x80 --tf "$TF" --steps 1:1 \
            -o "$W/f-$r-$s" > /dev/null 2> "$W/e.txt" || fail "play $r $s: $(cat "$W/e.txt")"
    done
    [ -r "$W/f-$r-nan/t0001.png" ] || continue
    d=$(diff_of "$W/f-$r-nan/t0001.png" "$W/f-$r-low/t0001.png")
    [ "$d" -le 6 ] && ok "$r: missing drawn as transparent voxels (max difference $d/255)" \
        || fail "$r: missing vs transparent voxels differ by $d/255"
    d=$(diff_of "$W/f-$r-nan/t0001.png" "$W/f-$r-in/t0001.png")
    [ "$d" -ge 40 ] && ok "$r: the missing voxels change the frame ($d/255)" \
        || fail "$r: the test cannot tell (difference $d/255 to the full volume)"
    "$PLAY" "$W/ds-nan" --headless -q --renderer $r --size 96x80 --tf "$TF" --steps 1:1 \
        --nan-color 1,0,0 -o "$W/f-$r-red" > /dev/null || fail "play $r red"
    d=$(diff_of "$W/f-$r-nan/t0001.png" "$W/f-$r-red/t0001.png")
    [ "$d" -ge 100 ] && ok "$r: --nan-color 1,0,0 draws them ($d/255)" || fail "$r: --nan-color: $d/255"
done
# ParaView preset: NanColor honoured (opacity 1), --nan-color none hides it.
cat > "$W/pv.json" <<'JSON'
[{"Name": "test", "ColorSpace": "RGB", "NanColor": [0, 1, 0],
  "RGBPoints": [0, 0, 0, 0, 1, 1, 1, 1]}]
JSON
"$PLAY" "$W/ds-nan" --headless -q --size 96x80 --tf "$W/pv.json" --steps 1:1 -o "$W/f-pv" > /dev/null \
    || fail "play preset"
"$PLAY" "$W/ds-nan" --headless -q --size 96x80 --tf "$W/pv.json" --steps 1:1 --nan-color none \
    -o "$W/f-pv-none" > /dev/null || fail "play preset none"
d=$(diff_of "$W/f-pv/t0001.png" "$W/f-pv-none/t0001.png")
[ "$d" -ge 100 ] && ok "preset NanColor drawn, --nan-color none removes it ($d/255)" \
    || fail "preset NanColor: $d/255"
# Two ranks, one slab each, composited: as one process draws it.
if command -v mpirun > /dev/null && "$PLAY" --version | grep -q "mpi: yes"; then
    timeout 300 mpirun --allow-run-as-root --oversubscribe -np 2 "$PLAY" "$W/ds-nan" --headless -q \
        --size 96x80 --tf "$TF" --steps 1:1 -o "$W/f-mpi" > /dev/null 2> "$W/e.txt" \
        || fail "mpirun: $(cat "$W/e.txt")"
    if [ -r "$W/f-mpi/t0001.png" ]; then
        d=$(diff_of "$W/f-mpi/t0001.png" "$W/f-cpu-nan/t0001.png")
        [ "$d" -le 2 ] && ok "2 ranks draw the missing voxels as one does ($d/255)" \
            || fail "2 ranks differ by $d/255"
    fi
else
    echo "no MPI build or mpirun: the cluster case is not run"
fi
finish
