#!/bin/sh
# rd-chart: scripts/rd-chart runs every setting and ZFP on a small series,
# writes rd.csv and the charts; on it the naive variant is never better than
# the real encoder, and --refine never worse than the default without it.
. "$(dirname "$0")/lib.sh"
command -v zfp > /dev/null || { echo "zfp missing (scripts/setup-deps installs it)"; exit 99; }
"$GEN" --field blobs --dims 20x18x16 --steps 8 -o "$W/in" || fail gen
"$TVPAL_SRCDIR/scripts/rd-chart" -o "$W/rd" --dims 20x18x16 "$W"/in/*.f32 > "$W/o.txt" 2>&1 \
    || { fail "rd-chart: $(tail -n 5 "$W/o.txt")"; finish; }
for m in tvpal-f32 tvpal-u16 tvpal-auto tvpal-staggered tvpal-group tvpal-refine tvpal-best tvpal-naive \
         zfp-3d zfp-4d; do
    grep -q "^$m," "$W/rd/rd.csv" && ok "$m rows" || fail "no $m rows"
done
for f in psnr-vs-bpv.png psnr-vs-bpv.svg time-vs-psnr.png fps-vs-psnr.png flicker.png; do
    [ -s "$W/rd/$f" ] && ok "$f" || fail "missing $f"
done
awk -F, '$1 == "tvpal-f32" { p[$2] = $4 } $1 == "tvpal-naive" { q[$2] = $4 }
         END { for (n in q) if (q[n] > p[n] + 1e-9) { print "naive beats plain at N=" n; exit 1 } }' \
    "$W/rd/rd.csv" && ok "naive <= plain at every N" || fail "naive variant beats the encoder"
awk -F, '$1 == "tvpal-auto" { p[$2] = $4 } $1 == "tvpal-refine" { q[$2] = $4 }
         END { for (n in q) if (q[n] < p[n] - 1e-6) { print "refine loses at N=" n; exit 1 } }' \
    "$W/rd/rd.csv" && ok "refine >= no refine at every N" || fail "refine lost accuracy"
# The gap at equal bits: where tvpal's bpv lies within ZFP's rates, ZFP's
# PSNR there is between those of the two rates around it, and the gap is
# ZFP's minus tvpal's.
awk -F, 'FNR == NR { if ($1 == "zfp-4d") { n++; r[n] = $3; p[n] = $4 } next }
         FNR > 1 && $6 != "" {
             ok = 0
             for (i = 1; i < n; i++)
                 if (r[i] <= $3 && $3 <= r[i + 1]) {
                     lo = p[i] < p[i + 1] ? p[i] : p[i + 1]; hi = p[i] + p[i + 1] - lo
                     ok = $6 >= lo - 1e-3 && $6 <= hi + 1e-3
                 }
             d = $8 - ($6 - $4); if (d < 0) d = -d
             if (!ok || d > 2e-3) { print "row " FNR ": " $0; bad = 1 }
             rows++
         }
         END { exit bad || rows < 3 }' "$W/rd/rd.csv" "$W/rd/gap.csv" \
    && ok "gap.csv: ZFP 4D at tvpal's bits between its rates, gap = its PSNR - tvpal's" \
    || fail "gap at equal bits: $(head -n 4 "$W/rd/gap.csv")"
grep -q "the gap at equal bits" "$W/o.txt" && grep -q "SZ3" "$W/o.txt" \
    && ok "the gap printed, SZ3 said" || fail "rd-chart output: $(tail -n 5 "$W/o.txt")"
finish
