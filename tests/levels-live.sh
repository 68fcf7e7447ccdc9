#!/bin/sh
# levels-live: levels of detail with live components (apart from
# tests/levels.sh, so that the sanitizer run can leave MPI's and X's own
# leaks out of leak checking): a cluster of 2 ranks under mpirun draws a
# level as one rank does; the window under Xvfb, driven by xdotool, drops
# to a coarser level while the view is dragged or the steps play faster than
# the budget, and refines when still (its CSV and title show it).
. "$(dirname "$0")/lib.sh"
third_party_leaks
PLAY=$TVPAL_BUILDDIR/player/app/tvpal-play
[ -x "$PLAY" ] || { echo "built without OSMesa/libpng: skipped"; exit 77; }
D=41x36x30
levels_dataset $D 5 2
ran=0
# A cluster of 2 ranks draws level 1 as one rank does: with the gl
# renderer, whose sort-last compositing is exact, within 1 level (as
# tests/cluster.sh); without OSMesa, with the cpu renderer, whose per-rank
# warp differs at the slab seam, no worse than twice level 0's difference
# plus 6 levels (coarse voxels make the seam twice as wide).
if command -v mpirun > /dev/null && "$PLAY" --version | grep -q "mpi: yes"; then
    ran=$((ran + 1))
    "$ENC" -q --dims $D --window 4 --nodes 2 --levels 1 -o "$W/k2" "$W"/in/*.f32 > /dev/null || fail "encode --nodes 2"
    R="--renderer cpu"
    "$PLAY" --version | grep -q "gl: yes" && R="--renderer gl"
    for k in 0 1; do
        "$PLAY" "$W/k2" --headless -q $R --size 64x56 --level $k --steps 1:1 -o "$W/c1-$k" > /dev/null 2>&1 || fail "one rank"
        mpirun --allow-run-as-root --oversubscribe -np 2 "$PLAY" "$W/k2" --headless -q $R --size 64x56 \
            --level $k --steps 1:1 --csv "$W/c2-$k.csv" -o "$W/c2-$k" > "$W/c2.txt" 2>&1 || fail "2 ranks: $(cat "$W/c2.txt")"
        r=$($PY "$TVPAL_SRCDIR/tests/pngdiff.py" "$W/c1-$k/t0001.png" "$W/c2-$k/t0001.png")
        eval "mx$k=$(echo "$r" | sed 's/max=\([0-9]*\).*/\1/')"
        eval "r$k=\"$r\""
    done
    lv=$(awk -F, 'NR == 1 { for (i = 1; i <= NF; i++) if ($i == "level") c = i } NR == 2 { print $c }' "$W/c2-1.csv")
    if [ "$R" = "--renderer gl" ]; then tol=1; else tol=$((2 * mx0 + 6)); fi
    [ "$lv" = 1 ] && [ "$mx1" -le $tol ] && ok "2 ranks ($R) at level $lv: $r1 against one rank (level 0: $r0)" \
        || fail "2 ranks ($R): level $lv, $r1 (level 0: $r0; tolerance $tol)"
else
    echo "no mpirun or built without MPI: cluster part skipped"
fi
# The window: coarse while dragging, refined when still.  A budget of 1 ms
# that no level keeps drives the drag to the coarsest level; after the
# button is let go the frame is drawn again at the still frame's level.
if "$PLAY" --version | grep -q "window: yes" && command -v xvfb-run > /dev/null && command -v xdotool > /dev/null; then
    ran=$((ran + 1))
    cat > "$W/drag.sh" <<DRAG
#!/bin/sh
"$PLAY" "$W/ds" --window --size 96x96 --budget-ms 1 --csv "$W/win.csv" > "$W/win.txt" 2>&1 &
pid=\$!
wid=\$(xdotool search --sync --name tvpal-play | head -n 1)
sleep 0.5
xdotool mousemove --window \$wid 40 40
xdotool mousedown 1
for i in 1 2 3 4 5 6; do xdotool mousemove_relative 4 0; sleep 0.15; done
xdotool getwindowname \$wid > "$W/title-drag.txt"
xdotool mouseup 1
sleep 0.8
xdotool getwindowname \$wid > "$W/title-still.txt"
cp "$W/win.csv" "$W/win-still.csv"
xdotool key --window \$wid space; sleep 1.5
xdotool key --window \$wid space; sleep 0.5
cp "$W/win.csv" "$W/win-stopped.csv"
xdotool key --window \$wid End; sleep 0.8
xdotool key --window \$wid Home; sleep 0.8
xdotool key --window \$wid End; sleep 0.8
xdotool key --window \$wid q 2>/dev/null
wait \$pid
DRAG
    timeout 60 xvfb-run -a -s "-screen 0 640x480x24" sh "$W/drag.sh" || fail "driving the window"
    awk -F, 'NR > 1 && $4 == 1 && $3 == 2 { d++ } END { exit !d }' "$W/win.csv" \
        && ok "dragging: frames at level 2 ($(awk -F, 'NR > 1 && $4 == 1' "$W/win.csv" | wc -l) while dragging)" \
        || fail "dragging: no coarse frame: $(head -n 8 "$W/win.csv")"
    tail -n 1 "$W/win-still.csv" | awk -F, '{ exit !($4 == 0 && $3 == 0) }' \
        && ok "still again: refined to level 0 ($(tail -n 1 "$W/win-still.csv"))" || fail "no refinement: $(tail -n 3 "$W/win-still.csv")"
    # Playing (space) faster than the budget: coarse frames, and the
    # playhead moves (every step of the 5 is drawn); stopped, refined.
    n0=$(wc -l < "$W/win-still.csv")
    steps=$(tail -n +$((n0 + 1)) "$W/win.csv" | awk -F, '$3 == 2 { print $2 }' | sort -u | wc -l)
    [ "$steps" -ge 5 ] && ok "playing: $steps steps drawn at level 2" || fail "playing: $steps steps at level 2: $(tail -n 5 "$W/win.csv")"
    tail -n 1 "$W/win.csv" | awk -F, '{ exit !($3 == 0) }' \
        && ok "stopped: refined to level 0" || fail "stopped: $(tail -n 3 "$W/win.csv")"
    # Jumps (End, Home, End) with --progressive on, the window's default:
    # the jump's frame is drawn at once from a coarser level, then the same
    # step at level 0 with its time from the jump (full_ms).  A key that
    # lands on a step whose records are in (prepared as the step playback
    # comes to next, or kept in the record buffers: the window plays round
    # the series, and these 5 steps' records all fit there once played)
    # draws it at level 0 at once.  Home and the last End land somewhere
    # new (the first End may not: playback may have stopped there).
    n1=$(wc -l < "$W/win-stopped.csv")
    tail -n +$((n1 + 1)) "$W/win.csv" > "$W/win-jumps.csv"
    last=$(tail -n 1 "$W/win-stopped.csv" | cut -d, -f2)
    awk -F, -v prev="$last" '$2 != prev { if ($3 > 0) { j[$2] = 1; jumps++ } else at_once++ }
             j[$2] && $3 == 0 && $6 > 0 { back++; delete j[$2] } { prev = $2 }
             END { exit !(jumps + at_once >= 2 && back == jumps) }' "$W/win-jumps.csv" \
        && ok "jumps: coarse at once then level 0, or level 0 at once where the records were in ($(tr '\n' ';' < "$W/win-jumps.csv" | cut -c1-200))" \
        || fail "jumps in the window: $(tr '\n' ';' < "$W/win-jumps.csv" | cut -c1-400)"
    grep -q "level 2/2 (11x9x8) .* - preview" "$W/title-drag.txt" && grep -q "level 0/2 (41x36x30)" "$W/title-still.txt" \
        && ok "title shows the level: $(cat "$W/title-drag.txt")" || fail "title: $(cat "$W/title-drag.txt") / $(cat "$W/title-still.txt")"
else
    echo "no window build, xvfb-run or xdotool: window part skipped"
fi
[ $ran -gt 0 ] || { echo "neither mpirun nor the window: skipped"; exit 77; }
finish
