#!/bin/sh
# resume: an encode interrupted (SIGKILL after step 5) leaves no valid
# dataset, only OUTDIR.partial; the same command then finishes the job and
# the result is byte-identical to an uninterrupted run, also when every step
# was encoded and only the finish (which packs the per-chunk tables of
# --table auto, FORMAT.md 9.1) was left.  A partial output of a different
# job (another window, another --table) is discarded, not resumed.
# Checkpoints are saved at most every --checkpoint-every seconds: killed
# with its latest unsaved, a job resumes from the checkpoint before it (0:
# every step) or, with none saved yet, starts over.
. "$(dirname "$0")/lib.sh"
D=18x14x10
"$GEN" --field front --dims $D --steps 12 -o "$W/in" || fail gen
"$ENC" --axes xyz -q --dims $D --window 4 --nodes 2 -o "$W/ref" "$W"/in/*.f32 > /dev/null || fail "reference encode"
TVPAL_ENCODE_FAULT_AFTER=5 "$ENC" --axes xyz -q --dims $D --window 4 --nodes 2 -o "$W/ds" "$W"/in/*.f32 > /dev/null 2>&1
rc=$?
[ $rc -ne 0 ] && ok "interrupted run exits $rc" || fail "fault hook did not stop the encoder"
[ ! -e "$W/ds" ] && [ -d "$W/ds.partial" ] && ok "only ds.partial exists" \
    || fail "after interruption: $(ls "$W")"
expect_exit 2 "manifest.txt" "$INFO" "$W/ds"
"$ENC" --axes xyz --dims $D --window 4 --nodes 2 -o "$W/ds" "$W"/in/*.f32 > "$W/o.txt" 2> "$W/e.txt" \
    || fail "rerun failed: $(cat "$W/e.txt")"
grep -q "resuming .* timestep 5 of 12" "$W/e.txt" && ok "rerun resumed at step 5" \
    || fail "rerun did not resume: $(cat "$W/e.txt")"
diff -r "$W/ref" "$W/ds" > /dev/null && ok "resumed output identical" \
    || fail "resumed output differs"
[ ! -e "$W/ds.partial" ] && ok "partial directory gone" || fail "ds.partial remains"
# Killed after the last step, before the shards were finished (packed).
TVPAL_ENCODE_FAULT_AFTER=12 "$ENC" --axes xyz -q --dims $D --window 4 --nodes 2 -o "$W/dp" "$W"/in/*.f32 > /dev/null 2>&1
"$ENC" --axes xyz --dims $D --window 4 --nodes 2 -o "$W/dp" "$W"/in/*.f32 > /dev/null 2> "$W/e.txt" \
    || fail "rerun dp: $(cat "$W/e.txt")"
grep -q "every step is encoded; finishing" "$W/e.txt" && diff -r "$W/ref" "$W/dp" > /dev/null \
    && ok "resumed at the finish: packed output identical" || fail "finish resume: $(cat "$W/e.txt")"
# A --table f32 partial output is not resumed as --table auto (the job's
# fingerprint has the table format).
TVPAL_ENCODE_FAULT_AFTER=5 "$ENC" --axes xyz -q --dims $D --window 4 --nodes 2 --table f32 -o "$W/dt" "$W"/in/*.f32 > /dev/null 2>&1
"$ENC" --axes xyz -q --dims $D --window 4 --nodes 2 -o "$W/dt" "$W"/in/*.f32 > /dev/null 2> "$W/e.txt" || fail "rerun dt"
! grep -q resuming "$W/e.txt" && diff -r "$W/ref" "$W/dt" > /dev/null \
    && ok "--table f32 partial not resumed by --table auto" || fail "table format fingerprint: $(cat "$W/e.txt")"
# A partial output of another job (different window) is started over.
TVPAL_ENCODE_FAULT_AFTER=3 "$ENC" --axes xyz -q --dims $D --window 2 -o "$W/d2" "$W"/in/*.f32 > /dev/null 2>&1
"$ENC" --axes xyz -q --dims $D --window 4 -o "$W/d2" "$W"/in/*.f32 > /dev/null 2> "$W/e.txt" || fail "rerun d2"
! grep -q resuming "$W/e.txt" && "$INFO" "$W/d2" --verify > /dev/null \
    && grep -q "^window = 4" "$W/d2/manifest.txt" && ok "other job's partial discarded" \
    || fail "stale partial handling"
# A damaged partial output is started over too.
TVPAL_ENCODE_FAULT_AFTER=6 "$ENC" --axes xyz -q --dims $D --window 4 -o "$W/d3" "$W"/in/*.f32 > /dev/null 2>&1
truncate -s 8192 "$W/d3.partial/node-0/axis-y.tvps"
"$ENC" --axes xyz -q --dims $D --window 4 -o "$W/d3" "$W"/in/*.f32 > /dev/null 2> "$W/e.txt" || fail "rerun d3"
"$ENC" --axes xyz -q --dims $D --window 4 -o "$W/d4" "$W"/in/*.f32 > /dev/null
diff -r "$W/d3" "$W/d4" > /dev/null && grep -q "starting the job over" "$W/e.txt" \
    && ok "damaged partial restarted, output correct" || fail "damaged partial: $(cat "$W/e.txt")"
# --checkpoint-every: killed after step 7 without saving its checkpoint.
TVPAL_ENCODE_FAULT=nosave TVPAL_ENCODE_FAULT_AFTER=7 "$ENC" --checkpoint-every 0 -q --dims $D --window 4 -o "$W/c0" "$W"/in/*.f32 > /dev/null 2>&1
"$ENC" --dims $D --window 4 -o "$W/c0" "$W"/in/*.f32 > /dev/null 2> "$W/e.txt" || fail "rerun c0: $(cat "$W/e.txt")"
"$ENC" -q --dims $D --window 4 -o "$W/cref" "$W"/in/*.f32 > /dev/null || fail "reference z encode"
grep -q "resuming .* timestep 6 of 12" "$W/e.txt" && diff -r "$W/cref" "$W/c0" > /dev/null \
    && ok "--checkpoint-every 0: resumed at the step before the unsaved one" || fail "checkpoint-every 0: $(cat "$W/e.txt")"
TVPAL_ENCODE_FAULT=nosave TVPAL_ENCODE_FAULT_AFTER=7 "$ENC" --checkpoint-every 3600 -q --dims $D --window 4 -o "$W/c1" "$W"/in/*.f32 > /dev/null 2>&1
[ -d "$W/c1.partial" ] && [ ! -e "$W/c1.partial/checkpoint" ] && ok "--checkpoint-every 3600: no checkpoint within the hour" \
    || fail "checkpoint-every 3600 saved one: $(ls "$W/c1.partial")"
"$ENC" --dims $D --window 4 -o "$W/c1" "$W"/in/*.f32 > /dev/null 2> "$W/e.txt" || fail "rerun c1: $(cat "$W/e.txt")"
! grep -q resuming "$W/e.txt" && diff -r "$W/cref" "$W/c1" > /dev/null \
    && ok "no checkpoint: the job starts over, output identical" || fail "checkpoint-every 3600: $(cat "$W/e.txt")"
expect_exit 2 "checkpoint-every" "$ENC" --checkpoint-every -1 --dims $D -o "$W/cx" "$W"/in/*.f32

# A .pvd whose DataSet files are rewritten between the runs (same size,
# same modification time: only their bytes differ) starts over: the
# checkpoint names every file the collection lists, with a CRC of its
# head.  It resumed with old and new steps mixed.  And the same job
# untouched still resumes.
vti_series() {   # DIR SEED: 12 raw-appended .vti files of D and a .pvd
    "$PY" - "$1" "$2" "$D" <<'PY'
import os, struct, sys
d, seed, dims = sys.argv[1], int(sys.argv[2]), [int(v) for v in sys.argv[3].split("x")]
os.makedirs(d, exist_ok=True)
nx, ny, nz = dims
n = nx * ny * nz
sets = []
for t in range(12):
    vals = [float((i * 7 + t * 13 + seed) % 101) for i in range(n)]
    head = ('<?xml version="1.0"?>\n<VTKFile type="ImageData" version="1.0" '
            'byte_order="LittleEndian" header_type="UInt64">\n<ImageData WholeExtent='
            '"0 %d 0 %d 0 %d" Origin="0 0 0" Spacing="1 1 1">\n<Piece Extent="0 %d 0 %d 0 %d">'
            '<PointData Scalars="v"><DataArray type="Float32" Name="v" format="appended" '
            'offset="0"/></PointData></Piece></ImageData>\n<AppendedData encoding="raw">\n_'
            % (nx - 1, ny - 1, nz - 1, nx - 1, ny - 1, nz - 1))
    with open("%s/s%02d.vti" % (d, t), "wb") as f:
        f.write(head.encode() + struct.pack("<Q", 4 * n) + struct.pack("<%df" % n, *vals))
        f.write(b"\n</AppendedData>\n</VTKFile>\n")
    sets.append('<DataSet timestep="%d" file="s%02d.vti"/>' % (t, t))
open(d + "/s.pvd", "w").write('<?xml version="1.0"?>\n<VTKFile type="Collection" '
    'version="0.1"><Collection>\n' + "\n".join(sets) + '\n</Collection></VTKFile>\n')
PY
}
vti_series "$W/pa" 1 && vti_series "$W/pb" 2 || fail "vti series"
"$ENC" --axes xyz -q --window 4 -o "$W/pref" "$W/pb/s.pvd" > /dev/null || fail "pvd reference"
TVPAL_ENCODE_FAULT_AFTER=5 "$ENC" --axes xyz -q --window 4 -o "$W/pv" "$W/pa/s.pvd" > /dev/null 2>&1
for f in "$W"/pa/s*.vti; do   # the new bytes, the old size and time
    touch -r "$f" "$W/t.stamp" && cp "$W/pb/$(basename "$f")" "$f" && touch -r "$W/t.stamp" "$f"
done
"$ENC" --axes xyz --window 4 -o "$W/pv" "$W/pa/s.pvd" > /dev/null 2> "$W/e.txt" || fail "pvd rerun: $(cat "$W/e.txt")"
! grep -q resuming "$W/e.txt" && diff -r -x manifest.txt "$W/pref" "$W/pv" > /dev/null \
    && ok "rewritten DataSets: the job starts over, the new steps only" \
    || fail "rewritten DataSets resumed: $(grep resuming "$W/e.txt")"
rm -rf "$W/pv"
TVPAL_ENCODE_FAULT_AFTER=5 "$ENC" --axes xyz -q --window 4 -o "$W/pv" "$W/pb/s.pvd" > /dev/null 2>&1
"$ENC" --axes xyz --window 4 -o "$W/pv" "$W/pb/s.pvd" > /dev/null 2> "$W/e.txt" || fail "pvd resume"
grep -q "resuming .* timestep 5 of 12" "$W/e.txt" && diff -r "$W/pref" "$W/pv" > /dev/null \
    && ok "an untouched .pvd job resumes, output identical" || fail "pvd resume: $(cat "$W/e.txt")"
finish
