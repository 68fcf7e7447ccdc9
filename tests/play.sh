#!/bin/sh
# play: tvpal-play headless writes one PNG per timestep and a timing CSV,
# ends with the fps=... summary; in-core, io_uring and pread, forward and
# backward give identical frames; a corrupt record is reported with its
# file and record and playback continues (exit 1), or stops with --strict
# (exit 2); a TF change every frame gives the frames of fresh runs;
# --nan-color leaves a frame without missing values as it is; bad options
# and transfer functions are refused (exit 2).
. "$(dirname "$0")/lib.sh"
PLAY=$TVPAL_BUILDDIR/player/app/tvpal-play
[ -x "$PLAY" ] || { echo "built without OSMesa/libpng: skipped"; exit 77; }
D=24x20x16
"$GEN" --field blobs --dims $D --steps 9 -o "$W/in" || fail gen
"$ENC" -q --dims $D --window 4 -o "$W/ds" "$W"/in/*.f32 > /dev/null || fail encode
TF=$TVPAL_SRCDIR/samples/tf/warm.tf
line=$("$PLAY" "$W/ds" --headless -q --size 96x80 --tf "$TF" -o "$W/f-stream") || fail "play"
echo "$line" | grep -Eq '^fps=[0-9.]+ frames=9 io_ms=[0-9.]+ stream_ms=[0-9.]+ upload_ms=[0-9.]+ draw_ms=[0-9.]+ readback_ms=[0-9.]+ composite_ms=[0-9.]+ ranks=1 bytes_read=[0-9]+ incore_mib=[0-9.]+ mode=(uring|pread) io=(uring|pread) direct=(yes|no|some) fixed=(yes|no|some) fixed_reads=[0-9]+ buffers=[0-9]+ io_submits=[0-9]+ renderer=cpu errors=0$' \
    && ok "summary: $line" || fail "summary: $line"
n=$(ls "$W/f-stream"/t*.png | wc -l)
[ "$n" -eq 9 ] && ok "9 PNG frames" || fail "$n frames"
[ "$(head -c 4 "$W/f-stream/t0004.png" | od -An -c | tr -d ' ')" = "211PNG" ] && ok "PNG signature" || fail "not a PNG"
head -n 1 "$W/f-stream/timing.csv" | grep -q '^step,axis,io_ms,stream_ms,upload_ms,draw_ms,readback_ms,total_ms,bytes_read' \
    && [ "$(wc -l < "$W/f-stream/timing.csv")" -eq 10 ] && ok "timing CSV" || fail "timing CSV"
for mode in "--mode incore" "--io pread" "--io pread --no-direct" "--io uring --prefetch 0"; do
    tag=$(echo $mode | tr -d ' -')
    "$PLAY" "$W/ds" --headless -q --size 96x80 --tf "$TF" $mode -o "$W/f-$tag" > /dev/null || fail "play $mode"
    same=1
    for f in "$W/f-stream"/t*.png; do cmp -s "$f" "$W/f-$tag/$(basename "$f")" || same=0; done
    [ $same = 1 ] && ok "$mode: identical frames" || fail "$mode: frames differ"
done
"$PLAY" "$W/ds" --headless -q --size 96x80 --tf "$TF" --steps 8:0 -o "$W/f-back" > /dev/null || fail "backward"
same=1
for f in "$W/f-stream"/t*.png; do cmp -s "$f" "$W/f-back/$(basename "$f")" || same=0; done
[ $same = 1 ] && ok "backward playback identical" || fail "backward frames differ"
"$PLAY" "$W/ds" --headless -q --size 96x80 --tf "$TF" --steps 6:6 -o "$W/f-jump" > /dev/null || fail "jump"
cmp -s "$W/f-stream/t0006.png" "$W/f-jump/t0006.png" && ok "jump to 6 = playing to 6" || fail "jump differs"
"$PLAY" "$W/ds" --mem 1 --steps 0:0 -q | grep -q "^memory: 1 MiB holds [0-9]* timesteps" && ok "--mem report" || fail "--mem"
# In-core with a memory budget: crossing all three axes (--spin) keeps at
# most the budget in RAM; an axis larger than the budget is streamed.
axis_kib=$(( $(stat -c %s "$W/ds/node-0/axis-z.tvps") / 1024 ))
line=$("$PLAY" "$W/ds" --headless -q --size 64x64 --mode incore --mem 1 --spin 45 --steps 0:8) || fail "mem budget"
mib=$(kv incore_mib "$line")
awk -v m="$mib" 'BEGIN { exit !(m <= 1.0) }' && ok "in-core with --mem 1 holds $mib MiB (axis ${axis_kib} KiB)" \
    || fail "in-core holds $mib MiB over the 1 MiB budget"
# Corrupt record 5 of every axis (one with chunks in either schedule: at
# N = 4 the joined one starts no window at steps 1..3).
cp -r "$W/ds" "$W/bad"
for a in x y z; do
    $PY - "$W/bad/node-0/axis-$a.tvps" <<'PY'
import struct, sys
p = sys.argv[1]; b = bytearray(open(p, "rb").read())
idx = struct.unpack_from("<Q", b, 72)[0]
off = struct.unpack_from("<Q", b, idx + 32 * 5)[0]
b[off + 64 + 10] ^= 0x40
open(p, "wb").write(b)
PY
done
expect_exit 1 "axis-.\.tvps: record 5: payload CRC-32C mismatch \(keeping the last good data\)" \
    "$PLAY" "$W/bad" --headless -q --size 96x80 -o "$W/f-bad"
[ "$(ls "$W/f-bad"/t*.png | wc -l)" -eq 9 ] && ok "playback went on after the bad record" || fail "frames missing"
grep -q "errors=1" "$W/out.txt" && ok "summary counts the error" || fail "errors not counted"
expect_exit 2 "record 5: payload CRC-32C mismatch" "$PLAY" "$W/bad" --headless -q --size 96x80 --strict
# A transfer-function change every frame (--tf-cycle) gives each frame the
# image a run with that TF alone gives, for both renderers.
TF2=$TVPAL_SRCDIR/samples/tf/band.tf
if "$PLAY" --version | grep -q "gl: yes"; then RENDERERS="cpu gl"; else RENDERERS=cpu; fi
for r in $RENDERERS; do
    "$PLAY" "$W/ds" --headless -q --renderer $r --size 96x80 --tf "$TF" --tf "$TF2" --tf-cycle \
        -o "$W/cyc-$r" > /dev/null || fail "tf-cycle $r"
    for i in 1 2; do
        tf=$([ $i = 1 ] && echo "$TF" || echo "$TF2")
        "$PLAY" "$W/ds" --headless -q --renderer $r --size 96x80 --tf "$tf" -o "$W/one-$r-$i" > /dev/null \
            || fail "single TF $r"
    done
    same=1
    for t in 0 1 2 3 4 5 6 7 8; do
        f=$(printf 't%04d.png' $t)
        cmp -s "$W/cyc-$r/$f" "$W/one-$r-$(( t % 2 + 1 ))/$f" || same=0
    done
    [ $same = 1 ] && ok "$r: TF change every frame = fresh runs with each TF" || fail "$r: tf-cycle frames differ"
done
# --fb asks for GL: 8-bit blending bands (differs from the float buffer);
# with the cpu renderer it is refused.  Without OSMesa, gl is refused.
if [ "$RENDERERS" = cpu ]; then
    expect_exit 1 "no GL renderer: built without OSMesa" "$PLAY" "$W/ds" --headless -q --fb 8
else
    "$PLAY" "$W/ds" --headless --size 96x80 --tf "$TF" --steps 4:4 --fb 8 -o "$W/fb8" > "$W/fb.txt" 2>&1 \
        && grep -q "renderer gl (.*--fb asks for a GL framebuffer" "$W/fb.txt" && ok "--fb 8 renders with gl" \
        || fail "--fb 8: $(cat "$W/fb.txt")"
    "$PLAY" "$W/ds" --headless -q --renderer gl --size 96x80 --tf "$TF" --steps 4:4 -o "$W/fb32" > /dev/null
    cmp -s "$W/fb8/t0004.png" "$W/fb32/t0004.png" && fail "--fb 8 = float buffer" \
        || ok "--fb 8 differs from the float buffer ($($PY "$TVPAL_SRCDIR/tests/pngdiff.py" "$W/fb8/t0004.png" "$W/fb32/t0004.png"))"
fi
# --cpu-scale: a finer intermediate image (another image, the same size),
# refused with gl and out of range.
"$PLAY" "$W/ds" --headless -q --size 96x80 --tf "$TF" --steps 4:4 --cpu-scale 8 -o "$W/k8" > /dev/null \
    && [ -f "$W/k8/t0004.png" ] && ! cmp -s "$W/k8/t0004.png" "$W/f-stream/t0004.png" \
    && ok "--cpu-scale 8 renders another image" || fail "--cpu-scale 8"
expect_exit 2 "--cpu-scale: .*only with --renderer cpu" "$PLAY" "$W/ds" --headless --renderer gl --cpu-scale 2
expect_exit 2 "--cpu-scale \"9\": expected auto or 1..8" "$PLAY" "$W/ds" --headless --cpu-scale 9
line=$("$PLAY" "$W/ds" --headless -q --size 96x80 --tf "$TF" --steps 2:4 --ref-psnr --csv "$W/rp.csv") \
    && echo "$line" | grep -q "^psnr_ref=[0-9.]*$" \
    && awk -F, 'NR == 1 { for (i = 1; i <= NF; i++) if ($i == "psnr_ref") c = i; ok = c > 0 }
                 NR > 1 && !($c >= 35) { ok = 0 } END { exit !ok }' "$W/rp.csv" \
    && ok "--ref-psnr: $line (per frame in the CSV)" || fail "--ref-psnr: $line"
expect_exit 2 "--ref-psnr: one rank, with the cpu or gl renderer" "$PLAY" "$W/ds" --headless --renderer ref --ref-psnr
expect_exit 2 "--fb: .*only with --renderer gl" "$PLAY" "$W/ds" --headless --renderer cpu --fb 8
printf 'domain normalized\n0 0 0 0 0\n0.5 1 1 1\n' > "$W/bad.tf"
expect_exit 2 "bad.tf: line 3: expected 5 numbers" "$PLAY" "$W/ds" --headless --tf "$W/bad.tf"
expect_exit 2 "nope.tf: cannot read" "$PLAY" "$W/ds" --headless --tf "$W/nope.tf"
printf 'nan 1 0 0 2\ndomain normalized\n0 0 0 0 0\n' > "$W/badnan.tf"
expect_exit 2 "badnan.tf: line 1: nan a = 2; expected 0..1" "$PLAY" "$W/ds" --headless --tf "$W/badnan.tf"
# --nan-color: a data set without missing values draws as without it.
"$PLAY" "$W/ds" --headless -q --size 96x80 --tf "$TF" --steps 4:4 --nan-color 1,0,0.5 -o "$W/f-nan" > /dev/null \
    && cmp -s "$W/f-stream/t0004.png" "$W/f-nan/t0004.png" && ok "--nan-color: no missing values, same frame" \
    || fail "--nan-color changed a frame without missing values"
for bad in 2,0,0 1,0 1,0,0, 1,0,0,1,1 red nan,0,0 ""; do
    expect_exit 2 "--nan-color \"$bad\": expected none or R,G,B\[,A\], each 0..1" \
        "$PLAY" "$W/ds" --headless --nan-color "$bad"
done
expect_exit 2 "--steps \"0:9\": expected T or A:B within 0..8" "$PLAY" "$W/ds" --headless --steps 0:9
expect_exit 2 "--size" "$PLAY" "$W/ds" --headless --size 0x10
expect_exit 2 "manifest.txt" "$PLAY" "$W/none" --headless
expect_exit 2 "--mode" "$PLAY" "$W/ds" --mode fast
finish
