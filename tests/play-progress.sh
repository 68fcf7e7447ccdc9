#!/bin/sh
# play-progress: headless tvpal-play says how far it is: into a log (stderr
# not a terminal) a line every --progress seconds (0: after every frame but
# the last, which the closing lines report), none on a run shorter than the
# default 10 s; on a terminal (script(1) gives one) a bar that ends at
# N/N frames 100% and is erased; nothing with --quiet.  A run with neither
# -o nor --csv warns that nothing is written (not with -q, not with
# --renderer none: benchmarks).
. "$(dirname "$0")/lib.sh"
PLAY=$TVPAL_BUILDDIR/player/app/tvpal-play
[ -x "$PLAY" ] || { echo "built without OSMesa/libpng: skipped"; exit 77; }
command -v script > /dev/null || { echo "no script(1) (bsdutils) to give a terminal: skipped"; exit 77; }
D=16x12x10
"$GEN" --field blobs --dims $D --steps 5 -o "$W/in" || fail gen
"$ENC" -q --dims $D -o "$W/ds" "$W"/in/*.f32 > /dev/null || fail encode
P="$PLAY $W/ds --headless --size 32x24"
# lines FILE: its progress lines.
lines() { grep -c "^tvpal-play: *[0-9]*%  [0-9]*/5 frames  [0-9.]* fps  ETA " "$1"; }

# 1. Not a terminal.
$P --progress 0 -o "$W/a" > /dev/null 2> "$W/a.err" || fail "run: $(cat "$W/a.err")"
[ "$(lines "$W/a.err")" -eq 4 ] && grep -q "^tvpal-play:  80%  4/5 frames" "$W/a.err" \
    && ok "--progress 0 into a log: a line after frames 1..4" \
    || fail "--progress 0: $(cat "$W/a.err")"
$P -o "$W/b" > /dev/null 2> "$W/b.err" || fail "run: $(cat "$W/b.err")"
[ "$(lines "$W/b.err")" -eq 0 ] && ok "default (10 s): no line on a short run" \
    || fail "default: $(cat "$W/b.err")"
$P -q --progress 0 -o "$W/c" > /dev/null 2> "$W/c.err" || fail "run: $(cat "$W/c.err")"
[ ! -s "$W/c.err" ] && ok "--quiet: nothing on stderr" || fail "--quiet: $(cat "$W/c.err")"

# 2. A terminal: the bar.
script -qec "$P -o $W/d" /dev/null > "$W/d.tty" 2>&1 < /dev/null || fail "script run"
grep -aq "\] 100%  5/5 frames  .* fps  ETA 0s" "$W/d.tty" \
    && grep -aq "$(printf '\r\033\\[K')" "$W/d.tty" \
    && ok "terminal: a bar that reaches 5/5 frames 100%, then erased" \
    || fail "terminal: $(od -c "$W/d.tty" | head -20)"
[ "$(lines "$W/d.tty")" -eq 0 ] && ok "terminal: no log lines" || fail "terminal: log lines"
script -qec "$P -q -o $W/e" /dev/null > "$W/e.tty" 2>&1 < /dev/null || fail "script run -q"
grep -aq "ETA" "$W/e.tty" && fail "terminal, --quiet: $(cat "$W/e.tty")" \
    || ok "terminal, --quiet: no bar"

# 3. Nowhere to write.
$P > /dev/null 2> "$W/f.err" || fail "run: $(cat "$W/f.err")"
grep -q "^tvpal-play: warning: no -o or --csv given: frames are rendered and timed but not written" \
    "$W/f.err" && ok "no -o, no --csv: warned" || fail "no warning: $(cat "$W/f.err")"
for opts in "--csv $W/g.csv" "-q" "--renderer none" "-o $W/h"; do
    $P $opts > /dev/null 2> "$W/g.err" || fail "run $opts: $(cat "$W/g.err")"
    grep -q "warning: no -o" "$W/g.err" && fail "$opts: warned: $(cat "$W/g.err")" \
        || ok "$opts: no warning"
done
expect_exit 2 "--progress \"-1\": expected seconds in 0\.\.86400" $P --progress -1
expect_exit 2 "--progress \"nan\": expected seconds in 0\.\.86400" $P --progress nan
finish
