#!/bin/sh
# play-window: the GLFW front end opens a real window under Xvfb, renders,
# and its framebuffer equals the headless image of the same step, with the
# default renderer (cpu: Xvfb's GL is llvmpipe) and with --renderer gl; keys sent
# with xdotool step the playhead (Right x3 from step 0 shows step 3), S
# saves a screenshot, 1 shows the named view +x (= headless --view +x), T
# cycles the transfer function, Q quits; --view -z --up x in the window
# draws what it draws headless.
. "$(dirname "$0")/lib.sh"
third_party_leaks
PLAY=$TVPAL_BUILDDIR/player/app/tvpal-play
[ -x "$PLAY" ] || { echo "built without OSMesa/libpng: skipped"; exit 77; }
"$PLAY" --version | grep -q "window: yes" || { echo "built without the window (GLFW and OSMesa): skipped"; exit 77; }
for tool in xvfb-run xdotool; do
    command -v $tool > /dev/null || { echo "$tool missing (scripts/setup-deps installs it)"; exit 99; }
done
D=24x20x16
"$GEN" --field blobs --dims $D --steps 9 -o "$W/in" || fail gen
"$ENC" -q --dims $D --window 4 -o "$W/ds" "$W"/in/*.f32 > /dev/null || fail encode
TF=$TVPAL_SRCDIR/samples/tf/warm.tf
"$PLAY" "$W/ds" --headless -q --size 96x80 --tf "$TF" -o "$W/hl" > /dev/null || fail headless
# 1. Autoplay: window framebuffer vs headless PNG, for both renderers.
"$PLAY" "$W/ds" --headless -q --renderer gl --size 96x80 --tf "$TF" -o "$W/hlgl" > /dev/null || fail "headless gl"
for r in default gl; do
    ropt=$([ $r = gl ] && echo "--renderer gl")
    hl=$([ $r = gl ] && echo hlgl || echo hl)
    for t in 0 5; do
        xvfb-run -a -s "-screen 0 640x480x24" "$PLAY" "$W/ds" --window $ropt --steps $t:$t \
            --size 96x80 --tf "$TF" --no-hud --autoplay 1 --screenshot "$W/win$r$t.png" > "$W/o.txt" 2>&1 \
            || { fail "window run: $(cat "$W/o.txt")"; continue; }
        cmp -s "$W/win$r$t.png" "$(printf '%s/%s/t%04d.png' "$W" $hl $t)" \
            && ok "$r renderer, step $t: window framebuffer = headless image" \
            || fail "$r renderer, step $t: window differs"
    done
    want=$([ $r = gl ] && echo "renderer=gl" || echo "renderer=cpu")
    grep -q "$want" "$W/o.txt" && ok "$r: $(grep -o 'renderer=.*' "$W/o.txt")" || fail "$r: $(cat "$W/o.txt")"
done
# A named view with a chosen up axis, in the window and headless.
"$PLAY" "$W/ds" --headless -q --size 96x80 --tf "$TF" --steps 2:2 --view -z --up x \
    -o "$W/hlv" > /dev/null || fail "headless --view"
xvfb-run -a -s "-screen 0 640x480x24" "$PLAY" "$W/ds" --window --no-hud --steps 2:2 --view -z --up x \
    --size 96x80 --tf "$TF" --autoplay 1 --screenshot "$W/winv.png" > "$W/o.txt" 2>&1 \
    || fail "window --view: $(cat "$W/o.txt")"
cmp -s "$W/winv.png" "$W/hlv/t0002.png" && ok "--view -z --up x: window = headless" \
    || fail "--view -z --up x: the window differs from headless"
"$PLAY" "$W/ds" --headless -q --size 96x80 --tf "$TF" --steps 3:3 --view +x -o "$W/hlx" \
    > /dev/null || fail "headless --view +x"
# 2. Keys through the X server.
cat > "$W/drive.sh" <<DRIVE
#!/bin/sh
cd "$W"
"$PLAY" "$W/ds" --window --no-hud --steps 0:8 --size 96x80 --tf "$TF" > "$W/play.txt" 2>&1 &
pid=\$!
wid=\$(xdotool search --sync --name tvpal-play | head -n 1)
sleep 0.5
for k in Right Right Right; do xdotool key --window \$wid \$k; sleep 0.3; done
xdotool key --window \$wid s; sleep 0.5
xdotool key --window \$wid 1; sleep 0.3
xdotool key --window \$wid s; sleep 0.5
xdotool key --window \$wid t; sleep 0.3
xdotool getwindowname \$wid > "$W/title.txt"
xdotool key --window \$wid q 2>/dev/null
wait \$pid
DRIVE
timeout 60 xvfb-run -a -s "-screen 0 640x480x24" sh "$W/drive.sh" || fail "driving the window"
cmp -s "$W/tvpal-shot-0000.png" "$W/hl/t0003.png" \
    && ok "Right x3 then S: screenshot = headless step 3" || fail "keys: screenshot differs ($(cat "$W/play.txt"))"
cmp -s "$W/tvpal-shot-0001.png" "$W/hlx/t0003.png" \
    && ok "key 1 then S: screenshot = headless --view +x" || fail "key 1: the +x view differs"
grep -q "t=3/8" "$W/title.txt" && grep -q "default" "$W/title.txt" \
    && ok "title: $(cat "$W/title.txt")" || fail "title: $(cat "$W/title.txt")"
grep -q "last_step=3" "$W/play.txt" && ok "q quits" || fail "quit: $(cat "$W/play.txt")"
expect_exit 2 "--ref-psnr: headless only" "$PLAY" "$W/ds" --window --ref-psnr
# 3. No display: a clear error.
expect_exit 1 "cannot open a window" env -u DISPLAY "$PLAY" "$W/ds" --window --autoplay 1
finish
