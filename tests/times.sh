#!/bin/sh
# times: --times FILE puts the steps' time values and units in the
# manifest, and they come back in tvpal-report's CSV and tvpal-play's
# timing CSV; an interval more than twice its neighbour's is named in a
# warning; a --times file with the wrong count, a falling value or text is
# refused (exit 2, nothing left).
. "$(dirname "$0")/lib.sh"
D=10x8x6
"$GEN" --field turbulence --dims $D --steps 6 -o "$W/in" > /dev/null || exit 99
printf '0 1.5 3\n4.5 6 20\n' > "$W/t.txt"
"$ENC" --axes xyz -q --dims $D --window 2 --times "$W/t.txt" --time-units "hours since 2005-08-28" -o "$W/ds" "$W"/in/*.f32 \
    > /dev/null 2> "$W/e.txt" || { fail "encode: $(cat "$W/e.txt")"; finish; }
grep -q "irregular time intervals: 1 interval is more than twice.*steps 4-5" "$W/e.txt" \
    && ok "warning names the gap 4-5" || fail "no irregular warning: $(cat "$W/e.txt")"
grep -q "^times = 0 1.5 3 4.5 6 20$" "$W/ds/manifest.txt" && grep -q "^time_units = hours since 2005-08-28$" "$W/ds/manifest.txt" \
    && ok "manifest: times and units" || fail "manifest: $(grep '^time' "$W/ds/manifest.txt")"
grep -q "^units" "$W/ds/manifest.txt" && fail "raw input without --units: a units line" || ok "raw input: no units"
# --units on raw input, kept by the levels (each level a dataset of its own).
"$ENC" --axes z -q --dims $D --window 2 --levels 1 --units "m s-1" -o "$W/u" "$W"/in/*.f32 > /dev/null 2> "$W/e.txt" \
    && grep -qx "units = m s-1" "$W/u/manifest.txt" && grep -qx "units = m s-1" "$W/u/level-1/manifest.txt" \
    && ok "--units in the manifest and the level's" || fail "--units: $(cat "$W/e.txt")"
"$REP" -q "$W/ds" --csv "$W/r.csv" > /dev/null || fail report
awk -F, 'NR == 1 { for (i = 1; i <= NF; i++) if ($i == "time") c = i }
         NR > 1 && $1 == 5 && $c == 20 { n++ } END { exit !(c && n == 3) }' "$W/r.csv" \
    && ok "report CSV: time of step 5 on every axis" || fail "report CSV time: $(head -n 2 "$W/r.csv")"
PLAY=$TVPAL_BUILDDIR/player/app/tvpal-play
if [ -x "$PLAY" ]; then
    "$PLAY" "$W/ds" --headless -q --size 48x40 --csv "$W/p.csv" > /dev/null || fail play
    awk -F, 'NR == 1 { for (i = 1; i <= NF; i++) if ($i == "time") c = i }
             NR > 1 { s = s " " $c } END { exit !(c && s == " 0 1.5 3 4.5 6 20") }' "$W/p.csv" \
        && ok "timing CSV: the time of every frame" || fail "timing CSV time: $(cut -d, -f30 "$W/p.csv" | tr '\n' ' ')"
fi
"$ENC" --axes xyz -q --dims $D --window 2 -o "$W/plain" "$W"/in/*.f32 > /dev/null 2> "$W/e.txt" || fail "plain encode"
[ ! -s "$W/e.txt" ] && ! grep -q "^times" "$W/plain/manifest.txt" && ok "no times: no warning, no times key" \
    || fail "plain: $(cat "$W/e.txt")"
printf '0 1 2\n' > "$W/few.txt"; printf '0 1 2 2 3 4\n' > "$W/flat.txt"; printf '0 1 2 x 4 5\n' > "$W/text.txt"
expect_exit 2 "few.txt: 3 numbers; expected 6" "$ENC" --axes xyz -q --dims $D --times "$W/few.txt" -o "$W/bad" "$W"/in/*.f32
expect_exit 2 "flat.txt: value 4 .*larger than the one before" "$ENC" --axes xyz -q --dims $D --times "$W/flat.txt" -o "$W/bad" "$W"/in/*.f32
expect_exit 2 "text.txt: not a number after 3" "$ENC" --axes xyz -q --dims $D --times "$W/text.txt" -o "$W/bad" "$W"/in/*.f32
# Too many values: their count, not "not a number" after T + 1 of them.
seq 0 20 > "$W/many.txt"
expect_exit 2 "many.txt: 21 numbers; expected 6, one per step" "$ENC" --axes xyz -q --dims $D --times "$W/many.txt" -o "$W/bad" "$W"/in/*.f32
# A subnormal time: the manifest could not hold it.
printf '0 1e-310 1 2 3 4\n' > "$W/sub.txt"
expect_exit 2 "sub.txt: the time of step 1 is 9.99.*e-311" "$ENC" --axes xyz -q --dims $D --times "$W/sub.txt" -o "$W/bad" "$W"/in/*.f32
[ ! -e "$W/bad" ] && [ ! -e "$W/bad.partial" ] && ok "nothing left" || fail "output left"
finish
