#!/bin/sh
# report-check: tvpal-report's PSNR, RMSE, max error, flicker and ratios
# agree with an independent computation in numpy (0.01 dB, 1e-6 relative);
# its CSV and JSON outputs agree with its summary line.
. "$(dirname "$0")/lib.sh"
$PY -c "import numpy" 2>/dev/null || { echo "numpy missing (scripts/setup-deps installs python3-numpy)"; exit 99; }
D=21x18x15
T=10
"$GEN" --field turbulence --dims $D --steps $T -o "$W/in" || fail gen
"$ENC" -q --dims $D --window 4 --nodes 2 -o "$W/ds" "$W"/in/*.f32 > /dev/null || fail encode
line=$("$REP" -q "$W/ds" --csv "$W/r.csv" --json "$W/r.json") || fail report
for a in x y z; do
    for t in $(seq 0 $((T - 1))); do
        "$DEC" "$W/ds" --step $t --axis $a -o "$(printf '%s/dec-%s-%04d.f32' "$W" $a $t)" \
            || fail "decode $a $t"
    done
done
$PY - "$W" "$T" "$line" <<'PY' || fail "independent check"
import json, math, os, sys, numpy as np
w, T, line = sys.argv[1], int(sys.argv[2]), sys.argv[3]
kv = dict(p.split("=") for p in line.split())
R = np.stack([np.fromfile("%s/in/turbulence_t%04d.f32" % (w, t), "<f4")
              for t in range(T)]).astype(np.float64)
peak = R.max() - R.min()
bad = 0
def close(name, mine, theirs, tol):
    global bad
    if abs(mine - theirs) > tol:
        print("MISMATCH %s: numpy %.9g, report %.9g" % (name, mine, theirs)); bad += 1
psnrs, worst_rmse, worst_max, worst_fl = [], 0, 0, 0
csv = [l.strip().split(",") for l in open(w + "/r.csv")][1:]
for a in "xyz":
    V = np.stack([np.fromfile("%s/dec-%s-%04d.f32" % (w, a, t), "<f4")
                  for t in range(T)]).astype(np.float64)
    E = V - R
    mse = np.mean(E ** 2)
    p = 10 * math.log10(peak ** 2 / mse)
    close("psnr_" + a, p, float(kv["psnr_" + a]), 0.01)
    psnrs.append(p)
    worst_rmse = max(worst_rmse, math.sqrt(mse))
    worst_max = max(worst_max, np.abs(E).max())
    fl = np.mean(np.abs(np.diff(R, axis=0) - np.diff(V, axis=0))) / peak
    worst_fl = max(worst_fl, fl)
    for t in range(T):
        row = [r for r in csv if r[0] == str(t) and r[1] == a][0]
        pt = 10 * math.log10(peak ** 2 / np.mean(E[t] ** 2))
        close("csv psnr %s %d" % (a, t), pt, float(row[3]), 0.01)
        close("csv max %s %d" % (a, t), np.abs(E[t]).max(), float(row[4]), 1e-6 * peak)
close("psnr", min(psnrs), float(kv["psnr"]), 0.01)
close("rmse", worst_rmse, float(kv["rmse"]), 1e-6 * worst_rmse)
close("max_abs_error", worst_max, float(kv["max_abs_error"]), 1e-6 * peak)
close("flicker", worst_fl, float(kv["flicker"]), 1e-6)
sizes = [sum(os.path.getsize("%s/ds/node-%d/axis-%s.tvps" % (w, r, a)) for r in range(2))
         for a in "xyz"]
mean = sum(sizes) / 3.0
close("ratio", R.size * 4 / mean, float(kv["ratio"]), 1e-3)
close("bpv", mean * 8 / R.size, float(kv["bpv"]), 1e-3)
j = json.load(open(w + "/r.json"))
close("json psnr", j["summary"]["psnr"], float(kv["psnr"]), 1e-3)
close("json bytes x", sizes[0], j["axes"]["x"]["bytes"], 0)
print("numpy: psnr %.4f ratio %.4f; report agrees" % (min(psnrs), R.size * 4 / mean))
sys.exit(1 if bad else 0)
PY
finish
