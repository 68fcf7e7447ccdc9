#!/bin/sh
# play-annot: tvpal-play's annotations and background on real frames.
#  - --annotate none writes byte for byte the frame tvpal-play wrote before
#    it had annotations (tests/tvpal-framecheck: the bare frame path), and
#    --background C that frame over C (empty pixels exactly C);
#  - with a fully transparent TF only the annotations show: identical with
#    the cpu and gl renderers and on rank 0 of a 2-rank cluster, and in a
#    movie (-o FILE.mp4, with ffmpeg) as in the PNG frames;
#  - the default is full; the outline's corners land on the volume box's
#    corners projected as tvpal_view projects them (computed here
#    independently); minimal draws no outline; physical times replace the
#    step in the top left corner only; constant data (no value range)
#    still gets its legend;
#  - the window's HUD (H toggles it) is drawn on the shown image only, and
#    S saves into --shot-dir (xdotool under Xvfb).
# Without cairo, --annotate full is refused naming the package, and after
# the checks of --annotate none and --background the rest skips (77).
. "$(dirname "$0")/lib.sh"
third_party_leaks
PLAY=$TVPAL_BUILDDIR/player/app/tvpal-play
FC=$TVPAL_BUILDDIR/tests/tvpal-framecheck
[ -x "$PLAY" ] || { echo "built without libpng (no tvpal-play): skipped"; exit 77; }
D=24x20x16
"$GEN" --field blobs --dims $D --steps 3 -o "$W/in" > /dev/null || fail gen
"$ENC" -q --dims $D --window 2 -o "$W/ds" "$W"/in/*.f32 > /dev/null || fail encode
TF=$TVPAL_SRCDIR/samples/tf/warm.tf
S=320x200
V="--rotate 25,-35"
# 1. --annotate none: the bare frame; --background: the bare frame over it.
for bg in 0,0,0 1,0.5,0.25; do
    "$PLAY" "$W/ds" --headless -q --size $S $V --tf "$TF" --annotate none \
        --background $bg -o "$W/none-$bg" > /dev/null || fail "play --background $bg"
    for t in 0 2; do
        f=$(printf 't%04d.png' $t)
        "$FC" "$W/ds" "$TF" $t $S 25,-35 $bg "$W/fc-$bg-$t.png" || fail "framecheck"
        cmp -s "$W/none-$bg/$f" "$W/fc-$bg-$t.png" \
            && ok "--annotate none --background $bg, step $t: the bare frame, byte for byte" \
            || fail "--annotate none --background $bg, step $t: differs from the bare frame"
    done
done
"$PLAY" "$W/ds" --headless -q --size $S $V --tf "$TF" --annotate none --background white \
    --steps 1:1 -o "$W/white" > /dev/null || fail "play white"
"$FC" "$W/ds" "$TF" 1 $S 25,-35 1,1,1 "$W/fc-white.png" || fail framecheck
cmp -s "$W/white/t0001.png" "$W/fc-white.png" && ok "--background white = 1,1,1" \
    || fail "--background white differs"
# img.py: pngdiff.py's reader, with whole images as bytes (flat).  Run by
# py SCRIPT-ON-STDIN ARGS... (the script's first line: exec(IMG)).
cat > "$W/img.py" <<PY
import sys
sys.dont_write_bytecode = True
sys.path.insert(0, "$TVPAL_SRCDIR/tests")
from pngdiff import load
def flat(path):
    w, h, b, rows = load(path)
    return w, h, b, b"".join(rows)
PY
py() { IMG="$W/img.py" "$PY" - "$@"; }
# pixel PNG X Y: "R G B" of pixel (X, Y), Y from the top.
pixel() {
    py "$@" <<'PY'
import os, sys
exec(open(os.environ["IMG"]).read())
w, h, b, a = flat(sys.argv[1])
x, y = int(sys.argv[2]), int(sys.argv[3])
print(*list(a[(y * w + x) * b:(y * w + x) * b + 3]))
PY
}
# changed A B: "N X0 Y0 X1 Y1": how many pixels differ, and their box.
changed() {
    py "$@" <<'PY'
import os, sys
exec(open(os.environ["IMG"]).read())
w, h, b, a = flat(sys.argv[1])
_, _, _, c = flat(sys.argv[2])
d = [(i // b % w, i // b // w) for i in range(0, len(a), b) if a[i:i + 3] != c[i:i + 3]]
print(len(d), *([min(x for x, _ in d), min(y for _, y in d), max(x for x, _ in d),
                 max(y for _, y in d)] if d else [0, 0, 0, 0]))
PY
}
p=$(pixel "$W/none-1,0.5,0.25/t0000.png" 0 0)
[ "$p" = "255 128 64" ] && ok "empty pixel over --background 1,0.5,0.25: $p" \
    || fail "empty pixel over --background 1,0.5,0.25: $p, expected 255 128 64"
expect_exit 2 "--background \"1,2,0\": expected black, white" "$PLAY" "$W/ds" --headless --background 1,2,0
expect_exit 2 "--annotate \"some\": expected none, minimal or full" "$PLAY" "$W/ds" --headless --annotate some
expect_exit 2 "--shot-dir and --no-hud need the window" "$PLAY" "$W/ds" --headless --shot-dir "$W/s"
expect_exit 2 "--legend \"middle\": expected auto, right, right-top, right-bottom or left" "$PLAY" "$W/ds" --headless --legend middle
if ! "$PLAY" --version | grep -q "annotations: yes"; then
    expect_exit 2 "--annotate full: built without cairo \(install libcairo2-dev" \
        "$PLAY" "$W/ds" --headless -q --annotate full -o "$W/x"
    [ "$failures" -eq 0 ] || finish
    echo "built without cairo: annotations not drawn, the rest skipped (--annotate none and --background checked)"
    rm -rf "$W"; exit 77
fi
# 2. Only the annotations: a fully transparent TF.
printf 'name clear\ndomain normalized\n0 0 0.2 1 0\n1 1 0.6 0 0\n' > "$W/clear.tf"
CL="--size $S $V --zoom 0.7 --tf $W/clear.tf"
"$PLAY" "$W/ds" --headless -q $CL -o "$W/def" > /dev/null || fail "play default"
"$PLAY" "$W/ds" --headless -q $CL --annotate full -o "$W/full" > /dev/null || fail "play full"
"$PLAY" "$W/ds" --headless -q $CL --annotate minimal -o "$W/min" > /dev/null || fail "play minimal"
cmp -s "$W/def/t0001.png" "$W/full/t0001.png" && ok "default: --annotate full" || fail "default is not full"
cmp -s "$W/none-0,0,0/t0000.png" "$W/full/t0000.png" && fail "full draws nothing" || ok "full draws"
if "$PLAY" --version | grep -q "gl: yes"; then
    "$PLAY" "$W/ds" --headless -q $CL --renderer gl -o "$W/gl" > /dev/null || fail "play gl"
    same=1
    for t in 0 1 2; do f=$(printf 't%04d.png' $t); cmp -s "$W/full/$f" "$W/gl/$f" || same=0; done
    [ $same = 1 ] && ok "annotations: cpu and gl frames byte-identical" || fail "annotations differ between cpu and gl"
else
    echo "built without OSMesa: cpu/gl comparison not run"
fi
if command -v mpirun > /dev/null && "$PLAY" --version | grep -q "mpi: yes"; then
    "$ENC" -q --dims $D --window 2 --nodes 2 -o "$W/k2" "$W"/in/*.f32 > /dev/null || fail "encode --nodes 2"
    mpirun --allow-run-as-root --oversubscribe -np 2 "$PLAY" "$W/k2" --headless -q $CL \
        --steps 1:1 -o "$W/mpi" > "$W/mpi.txt" 2>&1 || fail "2 ranks: $(cat "$W/mpi.txt")"
    cmp -s "$W/mpi/t0001.png" "$W/full/t0001.png" && ok "2 ranks: rank 0 annotates the same frame" \
        || fail "2 ranks: annotations differ"
else
    echo "no mpirun or built without MPI: cluster comparison not run"
fi
# A movie (-o FILE.mp4) is written from the same annotated frame, over the
# background: its first frame (H.264, lossy) is far closer to the annotated
# PNG than to the bare one, and its empty corner is the background.
if command -v ffmpeg > /dev/null; then
    for a in full none; do
        "$PLAY" "$W/ds" --headless -q $CL --annotate $a --background darkgray --steps 0:1 \
            -o "$W/png-$a" > /dev/null || fail "play png $a"
    done
    "$PLAY" "$W/ds" --headless -q $CL --background darkgray --steps 0:1 -o "$W/m.mp4" \
        > /dev/null 2>&1 || fail "play movie"
    ffmpeg -v error -i "$W/m.mp4" -frames:v 1 "$W/m0.png" || fail "decode the movie"
    py "$W/m0.png" "$W/png-full/t0000.png" "$W/png-none/t0000.png" <<'PY' > "$W/movie.txt" 2>&1 \
        && ok "movie: $(cat "$W/movie.txt")" || fail "movie: $(cat "$W/movie.txt")"
import os, sys
exec(open(os.environ["IMG"]).read())
w, h, b, m = flat(sys.argv[1])
_, _, bf, f = flat(sys.argv[2])
_, _, bn, n = flat(sys.argv[3])
def mad(x, bx):
    return sum(abs(m[i * b + c] - x[i * bx + c]) for i in range(w * h) for c in range(3)) / (3 * w * h)
df, dn = mad(f, bf), mad(n, bn)
corner = list(m[(5 * w + w // 2) * b:(5 * w + w // 2) * b + 3])
if not (df * 3 < dn and all(abs(c - 51) <= 3 for c in corner)):
    sys.exit("mean difference %.3f to the annotated frame, %.3f to the bare one; "
             "top centre %s (darkgray is 51)" % (df, dn, corner))
print("mean difference %.3f to the annotated PNG, %.3f to the bare one; background %s"
      % (df, dn, corner))
PY
else
    echo "no ffmpeg: movie check not run"
fi
# Constant data, small and huge (a fill value left in): one value, no
# range; the legend spans a little around it and the frames are written.
for v in 1.5 9.96921e36; do
    "$GEN" --field constant --value $v --dims 8x8x8 --steps 2 -o "$W/cin-$v" > /dev/null || fail "gen constant"
    "$ENC" -q --dims 8x8x8 -o "$W/cds-$v" "$W"/cin-$v/*.f32 > /dev/null 2>&1 || fail "encode constant"
    "$PLAY" "$W/cds-$v" --headless -q --size 160x120 -o "$W/cf-$v" > "$W/cf.txt" 2>&1 && [ -f "$W/cf-$v/t0001.png" ] \
        && ok "constant data ($v): annotated frames" || fail "constant data ($v): $(cat "$W/cf.txt")"
done
# The outline: at every projected box corner a lit pixel; 4 pixels out
# from the silhouette's corners, black (the background); minimal: none.
py "$W/full/t0001.png" "$W/min/t0001.png" <<'PY' > "$W/outline.txt" 2>&1 \
    && ok "outline on the projected box corners: $(cat "$W/outline.txt")" || fail "outline: $(cat "$W/outline.txt")"
import math, os, sys
exec(open(os.environ["IMG"]).read())
w, h, b, full = flat(sys.argv[1])
_, _, _, mini = flat(sys.argv[2])
ax, ay, zoom, dims = math.radians(25), math.radians(-35), 0.7, (24, 20, 16)
half = [d / max(dims) for d in dims]
ca, sa, cb, sb = math.cos(ax), math.sin(ax), math.cos(ay), math.sin(ay)
r = math.sqrt(sum(x * x for x in half))
aspect = w / h
sx, sy = r / zoom * max(aspect, 1), r / zoom / min(aspect, 1)
pts = []
for c in range(8):
    p = [half[i] * (1 if c >> i & 1 else -1) for i in range(3)]
    y1, z1 = ca * p[1] - sa * p[2], sa * p[1] + ca * p[2]       # Rx(ax)
    x2, z2 = cb * p[0] + sb * z1, -sb * p[0] + cb * z1          # Ry(ay)
    px, py = (x2 / sx + 1) * 0.5 * w, (y1 / sy + 1) * 0.5 * h
    pts.append((px, h - py, z2))
cx, cy = w / 2, h / 2
near = max(range(8), key=lambda c: pts[c][2])
far = min(range(8), key=lambda c: pts[c][2])
bad = []
def at(img, x, y):
    i = (int(y) * w + int(x)) * b
    return img[i:i + 3]
for c, (x, y, _) in enumerate(pts):
    if max(at(full, x, y)) < 128:
        bad.append("corner %d (%.1f, %.1f) not lit: %s" % (c, x, y, list(at(full, x, y))))
    if max(at(mini, x, y)) != 0:
        bad.append("minimal: corner %d drawn" % c)
    if c in (near, far):
        continue
    dx, dy = x - cx, y - cy
    n = math.hypot(dx, dy)
    ox, oy = x + 4 * dx / n, y + 4 * dy / n
    if max(at(full, ox, oy)) != 0:
        bad.append("outside corner %d (%.1f, %.1f) lit" % (c, ox, oy))
if bad:
    sys.exit("; ".join(bad))
print("8 corners lit, 6 silhouette corners sharp")
PY
# Times: "t = ..." in the top left corner instead of "step N"; the same
# frame elsewhere.
printf '0\n0.5\n1.25\n' > "$W/t.txt"
"$ENC" -q --dims $D --window 2 --times "$W/t.txt" --time-units s -o "$W/dst" "$W"/in/*.f32 > /dev/null || fail "encode --times"
"$PLAY" "$W/dst" --headless -q $CL -o "$W/times" > /dev/null || fail "play times"
set -- $(changed "$W/full/t0002.png" "$W/times/t0002.png")
[ "${1:-0}" -gt 0 ] && [ "$4" -le 160 ] && [ "$5" -le 50 ] \
    && ok "times: $1 pixels differ, all within (0..$4, 0..$5)" \
    || fail "times: ${1:-no} pixels differ, up to (${4:-}, ${5:-}); expected some, in the top left"
# Units that are not valid UTF-8 (a Latin-1 degree sign, as old files
# have it): every frame drawn, U+FFFD for the byte, one warning for the run.
"$ENC" -q --dims $D --window 2 --units "$(printf 'T [\260C]')" -o "$W/dsu" "$W"/in/*.f32 > /dev/null \
    || fail "encode --units latin-1"
"$PLAY" "$W/dsu" --headless -q $CL -o "$W/units" > /dev/null 2> "$W/units.txt"
rc=$?
n=$(ls "$W/units" | grep -c '\.png$')
w=$(grep -c "warning: the manifest's units is not valid UTF-8 (a byte 0xb0)" "$W/units.txt")
[ $rc -eq 0 ] && [ "$n" -eq 3 ] && [ "$w" -eq 1 ] \
    && ok "units not valid UTF-8: $n frames, warned once" \
    || { fail "units not valid UTF-8: exit $rc, $n frames, $w warnings"; sed 's/^/    /' "$W/units.txt" >&2; }
# 3. The window: S with the HUD, H, S without; both in --shot-dir.
if "$PLAY" --version | grep -q "window: yes" && command -v xvfb-run > /dev/null \
   && command -v xdotool > /dev/null; then
    cat > "$W/drive.sh" <<DRIVE
#!/bin/sh
cd "$W"
"$PLAY" "$W/ds" --window --steps 1:2 $CL --shot-dir "$W/shots/new" > "$W/win.txt" 2>&1 &
pid=\$!
wid=\$(xdotool search --sync --name tvpal-play | head -n 1)
sleep 0.8
xdotool key --window \$wid s; sleep 0.5
xdotool key --window \$wid h; sleep 0.5
xdotool key --window \$wid s; sleep 0.5
xdotool key --window \$wid q 2>/dev/null
wait \$pid
DRIVE
    timeout 60 xvfb-run -a -s "-screen 0 640x480x24" sh "$W/drive.sh" || fail "driving the window"
    [ -f "$W/shots/new/tvpal-shot-0000.png" ] && [ -f "$W/shots/new/tvpal-shot-0001.png" ] \
        && [ ! -f "$W/tvpal-shot-0000.png" ] && ok "S saves into --shot-dir (created)" \
        || fail "--shot-dir: $(ls "$W" "$W/shots/new" 2>&1 | tr '\n' ' ') $(cat "$W/win.txt")"
    cmp -s "$W/shots/new/tvpal-shot-0001.png" "$W/full/t0001.png" \
        && ok "HUD hidden (H): the window shows the headless frame" || fail "H: the window differs from the headless frame"
    set -- $(changed "$W/shots/new/tvpal-shot-0000.png" "$W/shots/new/tvpal-shot-0001.png")
    [ "${1:-0}" -ge 500 ] && [ "$4" -le 160 ] && [ "$5" -le 133 ] \
        && ok "HUD: $1 pixels in the top left (up to x $4, y $5), none elsewhere" \
        || fail "HUD: ${1:-no} pixels differ, up to (${4:-}, ${5:-}); expected 500 or more, in the top left"
else
    echo "no window build, xvfb-run or xdotool: window part not run"
fi
finish
