#!/bin/sh
# rd-chart: scripts/rd-chart runs every setting and ZFP on a small series,
# writes rd.csv and the charts; on it the naive variant is never better than
# the real encoder, and --refine never worse than without.
. "$(dirname "$0")/lib.sh"
command -v zfp > /dev/null || { echo "zfp missing (scripts/setup-deps installs it)"; exit 99; }
"$GEN" --field blobs --dims 20x18x16 --steps 8 -o "$W/in" || fail gen
"$TVPAL_SRCDIR/scripts/rd-chart" -o "$W/rd" --dims 20x18x16 "$W"/in/*.f32 > "$W/o.txt" 2>&1 \
    || { fail "rd-chart: $(tail -n 5 "$W/o.txt")"; finish; }
for m in tvpal-f32 tvpal-u16 tvpal-refine tvpal-best tvpal-naive zfp-3d zfp-4d; do
    grep -q "^$m," "$W/rd/rd.csv" && ok "$m rows" || fail "no $m rows"
done
for f in psnr-vs-bpv.png psnr-vs-bpv.svg time-vs-psnr.png fps-vs-psnr.png flicker.png; do
    [ -s "$W/rd/$f" ] && ok "$f" || fail "missing $f"
done
awk -F, '$1 == "tvpal-f32" { p[$2] = $4 } $1 == "tvpal-naive" { q[$2] = $4 }
         END { for (n in q) if (q[n] > p[n] + 1e-9) { print "naive beats plain at N=" n; exit 1 } }' \
    "$W/rd/rd.csv" && ok "naive <= plain at every N" || fail "naive variant beats the encoder"
awk -F, '$1 == "tvpal-u16" { p[$2] = $4 } $1 == "tvpal-refine" { q[$2] = $4 }
         END { for (n in q) if (q[n] < p[n] - 1e-6) { print "refine loses at N=" n; exit 1 } }' \
    "$W/rd/rd.csv" && ok "refine >= no refine at every N" || fail "refine lost accuracy"
finish
