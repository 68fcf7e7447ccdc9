#!/bin/sh
# play-movie: tvpal-play -o FILE.mp4 / FILE.webm writes a movie through
# ffmpeg: read back with ffprobe, the codec (h264, vp9), the pixel format
# (yuv420p), the size (an odd size padded to even), the frame rate (--fps,
# default 24) and the frame count are the ones asked for; the first frame
# decoded back is the PNG frame of the same step within 30 dB PSNR (lossy
# codecs) and far from black (it shows the data); no FILE.partial.EXT is
# left; --csv gives the timing CSV (no default CSV with a movie); an ffmpeg
# that dies early (broken pipe), fails at the end (exit status) or writes
# nothing is reported with its message, exit 1, and leaves no FILE nor
# temporary; a link or FIFO at FILE is refused and left alone, a link at
# the old temporary name FILE.partial.EXT redirects nothing, and a full
# disk (a small tmpfs) fails the run and keeps an older movie;
# without ffmpeg on PATH the run stops before any frame with exit 2.
. "$(dirname "$0")/lib.sh"
PLAY=$TVPAL_BUILDDIR/player/app/tvpal-play
[ -x "$PLAY" ] || { echo "built without OSMesa/libpng: skipped"; exit 77; }
for tool in ffmpeg ffprobe; do
    command -v $tool > /dev/null || { echo "no $tool (Debian ffmpeg; scripts/setup-deps installs it): skipped"; exit 77; }
done
"$PY" -c "import numpy" 2> /dev/null || { echo "no numpy (python3-numpy): skipped"; exit 77; }
D=24x20x16
"$GEN" --field blobs --dims $D --steps 7 -o "$W/in" || fail gen
"$ENC" -q --dims $D --window 4 -o "$W/ds" "$W"/in/*.f32 > /dev/null || fail encode

# probe FILE: codec,width,height,pix_fmt,r_frame_rate,frames of its video.
probe() {
    ffprobe -v error -count_frames -select_streams v:0 -show_entries \
        stream=codec_name,pix_fmt,width,height,r_frame_rate,nb_read_frames \
        -of csv=p=0 "$1"
}
# 1. H.264 at 97x81 (odd: padded to 98x82), 12 fps; VP9 at the default rate.
mkdir -p "$W/mv" || exit 99
"$PLAY" "$W/ds" --headless --size 97x81 --fps 12 -o "$W/mv/a.mp4" --csv "$W/a.csv" \
    > "$W/a.txt" 2> "$W/a.err" || fail "mp4: $(cat "$W/a.err")"
got=$(probe "$W/mv/a.mp4")
[ "$got" = "h264,98,82,yuv420p,12/1,7" ] && ok "mp4: $got" \
    || fail "mp4: '$got', expected h264,98,82,yuv420p,12/1,7"
grep -q "97x81 padded to 98x82" "$W/a.err" && ok "odd size: said padded" \
    || fail "no padding note: $(cat "$W/a.err")"
grep -q "7 frames in $W/mv/a.mp4 (H.264, 12 fps)" "$W/a.err" && ok "mp4: closing line" \
    || fail "mp4 closing line: $(cat "$W/a.err")"
[ "$(ls "$W/mv")" = a.mp4 ] && ok "mp4: no temporary, no default CSV beside it" \
    || fail "mp4: the directory holds: $(ls "$W/mv")"
[ "$(wc -l < "$W/a.csv")" -eq 8 ] && ok "--csv with a movie: header + 7 rows" \
    || fail "--csv: $(wc -l < "$W/a.csv") lines"
grep -q "^fps=.* frames=7 " "$W/a.txt" && ok "summary line" || fail "summary: $(cat "$W/a.txt")"
"$PLAY" "$W/ds" --headless -q --size 64x48 -o "$W/mv/b.webm" > /dev/null 2> "$W/b.err" \
    || fail "webm: $(cat "$W/b.err")"
got=$(probe "$W/mv/b.webm")
[ "$got" = "vp9,64,48,yuv420p,24/1,7" ] && ok "webm: $got" \
    || fail "webm: '$got', expected vp9,64,48,yuv420p,24/1,7"

# 2. The first movie frame against the PNG frame of step 0.
"$PLAY" "$W/ds" --headless -q --size 97x81 -o "$W/png" > /dev/null || fail "PNG frames"
ffmpeg -v error -i "$W/mv/a.mp4" -frames:v 1 -f rawvideo -pix_fmt rgb24 "$W/m0.rgb" \
    && ffmpeg -v error -i "$W/png/t0000.png" -f rawvideo -pix_fmt rgb24 "$W/p0.rgb" \
    || fail "decoding frames"
res=$("$PY" - "$W/m0.rgb" "$W/p0.rgb" <<'PY'
import sys, numpy as np
m = np.fromfile(sys.argv[1], np.uint8).reshape(82, 98, 3)[:81, :97].astype(float)
p = np.fromfile(sys.argv[2], np.uint8).reshape(81, 97, 3).astype(float)
def psnr(a, b):
    e = ((a - b) ** 2).mean()
    return 99.0 if e == 0 else 10 * np.log10(255.0 ** 2 / e)
print("%.2f %.2f" % (psnr(m, p), psnr(p, np.zeros_like(p))))
PY
)
set -- $res
ge "${1:-0}" 30 && ok "first movie frame vs PNG step 0: $1 dB (> 30)" \
    || fail "first movie frame vs PNG step 0: ${1:-?} dB (expected > 30)"
ge 25 "${2:-99}" && ok "the PNG frame is far from black ($2 dB against black, < 25)" \
    || fail "the PNG frame is nearly black (${2:-?} dB): the comparison shows nothing"

# 3. ffmpeg failing: early (the pipe breaks: frames of 120 KB overflow the
# pipe's 64 KB) and at the end (exit status).
mkdir -p "$W/fake" || exit 99
printf '#!/bin/sh\nhead -c 20000 > /dev/null\necho "fake ffmpeg: early failure" >&2\nexit 3\n' \
    > "$W/fake/ffmpeg"
chmod +x "$W/fake/ffmpeg"
expect_exit 1 "c\.mp4: ffmpeg stopped reading at frame [0-9]+ \(ffmpeg exited with status 3\): fake ffmpeg: early failure" \
    env PATH="$W/fake:$PATH" "$PLAY" "$W/ds" --headless -q --size 200x200 -o "$W/mv/c.mp4"
printf '#!/bin/sh\ncat > /dev/null\necho "fake ffmpeg: late failure" >&2\nexit 1\n' > "$W/fake/ffmpeg"
expect_exit 1 "d\.webm: ffmpeg exited with status 1: fake ffmpeg: late failure" \
    env PATH="$W/fake:$PATH" "$PLAY" "$W/ds" --headless -q --size 64x48 -o "$W/mv/d.webm"
# An encoder that quits quietly with status 0 before the end is no success.
printf '#!/bin/sh\nhead -c 100 > /dev/null\nexit 0\n' > "$W/fake/ffmpeg"
expect_exit 1 "e\.mp4: ffmpeg stopped reading at frame [0-9]+ \(ffmpeg exited with status 0\)" \
    env PATH="$W/fake:$PATH" "$PLAY" "$W/ds" --headless -q --size 200x200 -o "$W/mv/e.mp4"
# One that reads every frame and exits 0 but writes nothing.
printf '#!/bin/sh\ncat > /dev/null\nexit 0\n' > "$W/fake/ffmpeg"
expect_exit 1 "i\.mp4: ffmpeg exited with status 0 but wrote no movie" \
    env PATH="$W/fake:$PATH" "$PLAY" "$W/ds" --headless -q --size 64x48 -o "$W/mv/i.mp4"
left=$(ls "$W/mv" | grep -v '^a\.mp4$\|^b\.webm$')
[ -z "$left" ] && ok "failed movies leave neither FILE nor FILE.partial" \
    || fail "left behind: $left"

# 4. No ffmpeg on PATH: exit 2 before any frame is drawn.
expect_exit 2 "-o .*f\.mp4: ffmpeg not found on PATH .*Debian package ffmpeg" \
    env PATH=/nonexistent "$PLAY" "$W/ds" --headless --size 64x48 -o "$W/mv/f.mp4"
grep -q "renderer" "$W/err.txt" && fail "without ffmpeg the run started: $(cat "$W/err.txt")" \
    || ok "without ffmpeg: stopped before the start line"
[ ! -e "$W/mv/f.mp4" ] && [ ! -e "$W/mv/f.partial.mp4" ] && ok "without ffmpeg: no file" \
    || fail "without ffmpeg: a file was left"

# 5. Option rules.
# --fps without a movie is a playback's clock: the frames come no faster
# (7 frames at 20 fps: the summary's fps at most 20, 0.3 s at least).
s0=$(date +%s.%N)
"$PLAY" "$W/ds" --headless -q --fps 20 -o "$W/paced" > "$W/paced.out" 2>&1 || fail "--fps 20 -o DIR: $(cat "$W/paced.out")"
s1=$(date +%s.%N)
f=$(sed -n 's/^fps=\([0-9.]*\).*/\1/p' "$W/paced.out")
awk -v f="$f" -v s="$(echo "$s1 - $s0" | bc)" 'BEGIN { exit !(f > 0 && f <= 20.2 && s >= 0.3) }' \
    && ok "--fps 20 -o DIR: frames paced ($f fps)" || fail "--fps 20 -o DIR: $f fps"
expect_exit 2 "--fps \"0\": expected frames per second in 0\.1\.\.1000" \
    "$PLAY" "$W/ds" --headless -q --fps 0 -o "$W/mv/g.mp4"
expect_exit 2 "movies are written headless" "$PLAY" "$W/ds" --window -o "$W/mv/g.mp4"
expect_exit 2 "g\.mp4: cannot create a temporary beside it" "$PLAY" "$W/ds" --headless -q -o "$W/no/such/g.mp4"
mkdir -p "$W/h.webm" || exit 99
expect_exit 2 "h\.webm: is a directory \(a trailing / writes PNG frames into it\)" \
    "$PLAY" "$W/ds" --headless -q -o "$W/h.webm"
"$PLAY" "$W/ds" --headless -q --size 16x16 --steps 0:0 -o "$W/h.webm/" > /dev/null \
    && [ -f "$W/h.webm/t0000.png" ] && ok "-o h.webm/: PNG frames in the directory" \
    || fail "-o h.webm/: no PNG frame"

# 6. A movie goes through the same safe output as every file: a link or
# FIFO at its name is refused and left alone; a link planted at the old
# predictable temporary name (FILE.partial.EXT) redirects nothing (the
# temporary has a unique name and ffmpeg writes it through a descriptor).
mkdir -p "$W/safe" && echo victim > "$W/safe/victim" || exit 99
ln -s "$W/safe/victim" "$W/safe/l.mp4"
expect_exit 2 "l\.mp4: exists and is not a regular file \(a symbolic link\)" \
    "$PLAY" "$W/ds" --headless -q --size 32x32 -o "$W/safe/l.mp4"
mkfifo "$W/safe/p.mp4" || exit 99
expect_exit 2 "p\.mp4: exists and is not a regular file \(a FIFO\)" \
    "$PLAY" "$W/ds" --headless -q --size 32x32 -o "$W/safe/p.mp4"
ln -s "$W/safe/victim" "$W/safe/m.partial.mp4"
"$PLAY" "$W/ds" --headless -q --size 32x32 -o "$W/safe/m.mp4" > /dev/null 2> "$W/err.txt" \
    && [ "$(probe "$W/safe/m.mp4" | cut -d, -f6)" = 7 ] \
    && ok "a link at FILE.partial.mp4: the movie written beside it, 7 frames" \
    || fail "planted FILE.partial.mp4: $(cat "$W/err.txt")"
[ "$(cat "$W/safe/victim")" = victim ] && [ -L "$W/safe/l.mp4" ] && [ -p "$W/safe/p.mp4" ] \
    && ok "links, their target and the FIFO are untouched" || fail "a link, its target or the FIFO changed"
ls "$W/safe" | grep -q 'partial-' && fail "a temporary was left: $(ls "$W/safe")" \
    || ok "no temporary left"

# 7. A full disk: ffmpeg may exit 0 after failed writes, leaving a file
# without its index.  The run fails (exit 1, ffmpeg's words) and an older
# movie of that name stays.  On a 12 KiB tmpfs (skipped out loud where
# mounting is not permitted).
mkdir -p "$W/full" || exit 99
if mount -t tmpfs -o size=12k tmpfs "$W/full" 2> /dev/null; then
    echo "an older movie" > "$W/full/old.mp4"
    expect_exit 1 "old\.mp4: .*(No space left on device|holds .* of its 7 frames)" \
        "$PLAY" "$W/ds" --headless -q --size 256x256 -o "$W/full/old.mp4"
    [ "$(cat "$W/full/old.mp4")" = "an older movie" ] && ok "disk full: the older movie stays" \
        || fail "disk full: the older movie was replaced"
    ls "$W/full" | grep -q 'partial-' && fail "disk full: a temporary was left" \
        || ok "disk full: no temporary left"
    umount "$W/full"
else
    echo "mount -t tmpfs not permitted: the full-disk case is skipped"
fi
finish
