#!/bin/sh
# plot: scripts/plot-report charts PSNR per timestep and PSNR against
# compression ratio as PNG files, and rejects a file that is not a report.
. "$(dirname "$0")/lib.sh"
command -v gnuplot > /dev/null || { echo "gnuplot missing (scripts/setup-deps installs gnuplot-nox)"; exit 99; }
P=$TVPAL_SRCDIR/scripts/plot-report
D=16x12x10
"$GEN" --field blobs --dims $D --steps 6 -o "$W/in" || fail gen
for N in 1 2 4; do
    "$ENC" -q --dims $D --window $N -o "$W/d$N" "$W"/in/*.f32 > /dev/null || fail "encode $N"
    "$REP" "$W/d$N" --csv "$W/r$N.csv" > "$W/s$N.txt" || fail "report $N"
done
"$P" "$W/r4.csv" "$W/psnr.png" > /dev/null && [ "$(head -c 4 "$W/psnr.png" | od -An -c | tr -d ' ')" = "211PNG" ] \
    && ok "PSNR per timestep chart" || fail "per-step chart"
"$P" --rd "$W/rd.png" "$W/s1.txt" "$W/s2.txt" "$W/s4.txt" > /dev/null && [ -s "$W/rd.png" ] \
    && ok "PSNR against ratio chart" || fail "rd chart"
expect_exit 2 "not a tvpal-report CSV" "$P" "$W/s1.txt" "$W/x.png"
finish
