#!/bin/sh
# render-chart: scripts/render-chart measures gl and cpu (K auto and forced)
# on a small series and writes render.csv and the charts; every setting has
# a time and a PSNR against the reference renderer, and gl (which samples
# each slice at the pixel, like the reference) is at least as accurate as
# cpu's automatic K.
. "$(dirname "$0")/lib.sh"
PLAY=$TVPAL_BUILDDIR/player/app/tvpal-play
[ -x "$PLAY" ] || { echo "built without libpng: skipped"; exit 77; }
command -v gnuplot > /dev/null || { echo "gnuplot missing (scripts/setup-deps installs it)"; exit 99; }
TVPAL_RC_DIMS=20x18x16 TVPAL_RC_STEPS=4 TVPAL_RC_SIZE=80x64 TVPAL_RC_ZOOMS="1 2.5" \
    TVPAL_RC_KS="auto 1 2" "$TVPAL_SRCDIR/scripts/render-chart" -o "$W/rc" > "$W/o.txt" 2>&1 \
    || { fail "render-chart: $(tail -n 5 "$W/o.txt")"; finish; }
cat "$W/o.txt"
want=6
"$PLAY" --version | grep -q "gl: yes" && want=8
n=$(awk -F, 'NR > 1 && $4 > 0 && $5 >= 30 && $5 < 1000' "$W/rc/render.csv" | wc -l)
[ "$n" -eq $want ] && ok "$n settings with a time and a PSNR >= 30 dB" \
    || fail "$n of $want settings complete: $(cat "$W/rc/render.csv")"
for f in psnr-vs-ms.png psnr-vs-ms.svg; do
    [ -s "$W/rc/$f" ] && ok "$f" || fail "missing $f"
done
if [ $want -eq 8 ]; then
    awk -F, '$1 == "gl" { g[$3] = $5 } $1 == "cpu" && $2 == "auto" { c[$3] = $5 }
             END { for (z in c) if (g[z] < c[z]) { print "zoom " z ": gl " g[z] " < cpu " c[z]; exit 1 } }' \
        "$W/rc/render.csv" && ok "gl at least as accurate as cpu" || fail "gl less accurate than cpu"
fi
finish
