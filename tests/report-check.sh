#!/bin/sh
# report-check: tvpal-report's PSNR, RMSE, max error, flicker and ratios
# agree with an independent computation in numpy (0.01 dB, 1e-6 relative):
# ratio and bpv of the bytes on disk (every file of the dataset, as os.walk
# and stat see them), axis_ratio of the mean bytes of one axis's shards; its
# CSV and JSON outputs agree with its summary line.  Twice: on plain
# turbulence, and on turbulence with missing values (a NaN block at every
# step, one at some steps only, a fill value given by --missing), which
# every figure leaves out and the report counts.
. "$(dirname "$0")/lib.sh"
$PY -c "import numpy" 2>/dev/null || { echo "numpy missing (scripts/setup-deps installs python3-numpy)"; exit 99; }
D=21x18x15
T=10
"$GEN" --field turbulence --dims $D --steps $T -o "$W/in" || fail gen
mkdir -p "$W/miss"
$PY - "$W" $T <<'PY' || fail "missing-value input"
import numpy as np, sys
w, T = sys.argv[1], int(sys.argv[2])
for t in range(T):
    a = np.fromfile("%s/in/turbulence_t%04d.f32" % (w, t), "<f4").reshape(15, 18, 21)
    a[3:7, 2:9, 5:12] = np.nan            # missing at every step
    if t % 3 == 1:
        a[9:12, :, 14:19] = np.nan        # at some steps only
    a[:, (t % 4)::4, 0] = -999.0          # a fill value
    a.tofile("%s/miss/turbulence_t%04d.f32" % (w, t))
PY
check_case() { # NAME INPUT-DIR ENCODER-OPTIONS...
    name=$1 src=$2
    shift 2
    "$ENC" --axes xyz -q --dims $D --window 4 --nodes 2 "$@" -o "$W/ds-$name" "$W/$src"/*.f32 > /dev/null \
        || { fail "encode $name"; return; }
    line=$("$REP" -q "$W/ds-$name" --csv "$W/r-$name.csv" --json "$W/r-$name.json") \
        || { fail "report $name"; return; }
    for a in x y z; do
        for t in $(seq 0 $((T - 1))); do
            "$DEC" "$W/ds-$name" --step $t --axis $a \
                -o "$(printf '%s/dec-%s-%s-%04d.f32' "$W" $name $a $t)" || fail "decode $name $a $t"
        done
    done
    $PY - "$W" "$T" "$line" "$name" "$src" <<'PY' || fail "independent check ($name)"
import json, math, os, sys, numpy as np
w, T, line, name, src = sys.argv[1], int(sys.argv[2]), sys.argv[3], sys.argv[4], sys.argv[5]
kv = dict(p.split("=") for p in line.split())
R = np.stack([np.fromfile("%s/%s/turbulence_t%04d.f32" % (w, src, t), "<f4")
              for t in range(T)]).astype(np.float64)
R[R == -999.0] = np.nan                    # --missing -999 (none in "in")
M = np.isnan(R)
peak = np.nanmax(R) - np.nanmin(R)
bad = 0
def close(what, mine, theirs, tol):
    global bad
    if abs(mine - theirs) > tol:
        print("MISMATCH %s %s: numpy %.9g, report %.9g" % (name, what, mine, theirs)); bad += 1
psnrs, worst_rmse, worst_max, worst_fl = [], 0, 0, 0
csv = [l.strip().split(",") for l in open("%s/r-%s.csv" % (w, name))][1:]
for a in "xyz":
    V = np.stack([np.fromfile("%s/dec-%s-%s-%04d.f32" % (w, name, a, t), "<f4")
                  for t in range(T)]).astype(np.float64)
    if not (np.isnan(V) == M).all():
        print("MISMATCH %s: NaN of axis %s not where the reference's are" % (name, a)); bad += 1
    E = V - R
    mse = np.nanmean(E ** 2)
    p = 10 * math.log10(peak ** 2 / mse)
    close("psnr_" + a, p, float(kv["psnr_" + a]), 0.01)
    psnrs.append(p)
    worst_rmse = max(worst_rmse, math.sqrt(mse))
    worst_max = max(worst_max, np.nanmax(np.abs(E)))
    fl = np.nanmean(np.abs(np.diff(R, axis=0) - np.diff(V, axis=0))) / peak
    worst_fl = max(worst_fl, fl)
    for t in range(T):
        row = [r for r in csv if r[0] == str(t) and r[1] == a][0]
        pt = 10 * math.log10(peak ** 2 / np.nanmean(E[t] ** 2))
        close("csv psnr %s %d" % (a, t), pt, float(row[3]), 0.01)
        close("csv max %s %d" % (a, t), np.nanmax(np.abs(E[t])), float(row[4]), 1e-6 * peak)
        close("csv missing %s %d" % (a, t), M[t].sum(), float(row[7]), 0)
close("psnr", min(psnrs), float(kv["psnr"]), 0.01)
close("rmse", worst_rmse, float(kv["rmse"]), 1e-6 * worst_rmse)
close("max_abs_error", worst_max, float(kv["max_abs_error"]), 1e-6 * peak)
close("flicker", worst_fl, float(kv["flicker"]), 1e-6)
close("missing", M.sum(), float(kv["missing"]), 0)
close("missing_mismatch", 0, float(kv["missing_mismatch"]), 0)
sizes = [sum(os.path.getsize("%s/ds-%s/node-%d/axis-%s.tvps" % (w, name, r, a)) for r in range(2))
         for a in "xyz"]
mean = sum(sizes) / 3.0
disk = sum(os.path.getsize(os.path.join(d, f))
           for d, _, fs in os.walk("%s/ds-%s" % (w, name)) for f in fs)
close("bytes", disk, float(kv["bytes"]), 0)
close("ratio", R.size * 4 / disk, float(kv["ratio"]), 1e-3)
close("ratio_f32", R.size * 4 / disk, float(kv["ratio_f32"]), 1e-3)
close("bpv", disk * 8 / R.size, float(kv["bpv"]), 1e-3)
close("axis_ratio", R.size * 4 / mean, float(kv["axis_ratio"]), 1e-3)
# Three axes stored: the one-axis ratio is about three times the disk's.
close("axis_ratio / ratio", 3.0, float(kv["axis_ratio"]) / float(kv["ratio"]), 0.05)
j = json.load(open("%s/r-%s.json" % (w, name)))
close("json psnr", j["summary"]["psnr"], float(kv["psnr"]), 1e-3)
close("json missing", j["summary"]["missing"], M.sum(), 0)
close("json bytes x", sizes[0], j["axes"]["x"]["bytes"], 0)
close("json axis_ratio x", R.size * 4 / sizes[0], j["axes"]["x"]["axis_ratio"], 1e-3)
close("json bytes", disk, j["summary"]["bytes"], 0)
close("json ratio", R.size * 4 / disk, j["summary"]["ratio"], 1e-3)
close("json axis_ratio", R.size * 4 / mean, j["summary"]["axis_ratio"], 1e-3)
print("numpy (%s): psnr %.4f ratio %.4f axis_ratio %.4f, %d missing; report agrees"
      % (name, min(psnrs), R.size * 4 / disk, R.size * 4 / mean, M.sum()))
sys.exit(1 if bad else 0)
PY
}
check_case plain in
check_case missing miss --missing -999
if [ -d "$W/ds-missing" ]; then
    # The default tables (--table auto, per chunk: 4) with missing values: 5.
    [ "$(od -A n -t u4 -j 64 -N 4 "$W/ds-missing/node-0/axis-z.tvps" | tr -d ' ')" = 5 ] \
        && ok "missing: shards say table_format 5" || fail "missing: table_format"
    # A reference whose missing values are elsewhere is refused.
    expect_exit 1 "missing \(NaN\) in only one" "$REP" -q "$W/ds-missing" --reference "$W"/in/*.f32
fi
finish
