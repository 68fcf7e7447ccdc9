#!/bin/sh
# input-vti: VTK XML ImageData files encode to exactly the shards of raw
# files of the same numbers: the generated .vti of every encoding
# (tests/make-vti.py) and the real viscous-fingers series as delivered
# (20 zlib-compressed appended .vti files from ../shared/data, skipped where
# absent) against run01's raw steps 1..20; tvpal-report reads them again;
# the FieldData TimeValue of files from VTK's own writer are the times;
# a broken file exits 2 naming it and leaves nothing behind; vector arrays
# from VTK's writer encode with --magnitude to the shards of raw files of
# their lengths computed in numpy, whole and in the boxes of a multi-pass
# memory plan, and are refused without it.
. "$(dirname "$0")/lib.sh"
# The VTK fixtures (tests/vtkfix.py) for the Python below.
export PYTHONPATH="$TVPAL_SRCDIR/tests${PYTHONPATH:+:$PYTHONPATH}"
"$PY" "$TVPAL_SRCDIR/tests/make-vti.py" "$W/gen" > /dev/null 2> "$W/e.txt" || { fail "make-vti: $(cat "$W/e.txt")"; finish; }
first=$(ls "$W"/gen/*.vti | head -n 1)
if "$INFO" --inspect "$first" 2>&1 | grep -q "built without VTK"; then
    echo "built without VTK ImageData support: skipped"; exit 77
fi
"$INFO" --inspect "$first" > "$W/i.txt" 2>&1 && grep -q "^$first: vti" "$W/i.txt" && ok "--inspect: vti" \
    || fail "--inspect: $(cat "$W/i.txt")"
# Every good generated file is one timestep: a 2-step series of the file
# with itself encodes as the raw expected values twice.
n=0
for v in "$W"/gen/*.vti; do
    # (vec-*: vectors, whose lengths test-vti reads with magnitude)
    case $(basename "$v") in bad-*|vec-*) continue ;; esac
    raw=${v%.vti}.f32
    [ -r "$raw" ] || continue
    D=$("$INFO" --inspect "$v" | sed -n 's/^extent .*(\([0-9]*x[0-9]*x[0-9]*\)).*/\1/p')
    [ -n "$D" ] || { fail "$(basename "$v"): no dims in --inspect"; continue; }
    rm -rf "$W/r" "$W/v"
    if ! "$ENC" --axes xyz -q --dims $D --window 2 -o "$W/r" "$raw" "$raw" > /dev/null 2> "$W/re.txt"; then
        # Values the encoder refuses (infinity) are refused alike.
        grep -q "infinite value" "$W/re.txt" && expect_exit 2 "infinite value" "$ENC" --axes xyz -q -o "$W/v" "$v" \
            || fail "$(basename "$v"): raw encode: $(cat "$W/re.txt")"
        continue
    fi
    "$ENC" --axes xyz -q --window 2 -o "$W/v" "$v" "$v" > /dev/null 2> "$W/e.txt" || { fail "$(basename "$v"): $(cat "$W/e.txt")"; continue; }
    same=1
    for a in x y z; do cmp -s "$W/r/node-0/axis-$a.tvps" "$W/v/node-0/axis-$a.tvps" || same=0; done
    [ $same = 1 ] && n=$((n + 1)) || fail "$(basename "$v"): shards differ from raw"
done
[ $n -ge 5 ] && ok "$n generated .vti encodings: shards identical to raw" || fail "only $n .vti compared"
for v in "$W"/gen/bad-*.vti; do
    [ -e "$v" ] || continue
    expect_exit 2 "$(basename "$v")" "$ENC" --axes xyz -q -o "$W/bad" "$v"
    [ ! -e "$W/bad" ] && [ ! -e "$W/bad.partial" ] || fail "$(basename "$v"): output left"
done
# ParaView's time: the FieldData TimeValue that VTK's own writer
# (vtkXMLImageDataWriter, python3-vtk9) puts in each file of a series, in
# each of its data modes, becomes the dataset's times; a .pvd's timesteps
# win over them, as in ParaView.
if "$PY" -c "import numpy, vtkmodules.vtkIOXML" 2> /dev/null; then
    mkdir -p "$W/tv"
    "$PY" - "$W/tv" <<'PY' > "$W/tv.txt" 2>&1 || fail "vtk writer: $(cat "$W/tv.txt")"
import sys
from vtkmodules.vtkCommonDataModel import vtkImageData
from vtkmodules.vtkCommonCore import vtkDoubleArray, vtkFloatArray
from vtkfix import write_vti
out = sys.argv[1]
for mode in ("appended", "raw", "binary", "ascii"):
    for k, t in enumerate((0.5, 1.25, 2.0 + 1e-12)):
        im = vtkImageData()
        im.SetDimensions(6, 5, 4)
        im.SetSpacing(0.5, 0.5, 2.0)
        v = vtkFloatArray()
        v.SetName("theta")
        for i in range(6 * 5 * 4):
            v.InsertNextValue(280.0 + (i * (k + 3)) % 17)
        im.GetPointData().SetScalars(v)
        tv = vtkDoubleArray()
        tv.SetName("TimeValue")
        tv.InsertNextValue(t)
        im.GetFieldData().AddArray(tv)
        write_vti(im, "%s/%s_%d.vti" % (out, mode, k), mode)
PY
    for mode in appended raw binary ascii; do
        rm -rf "$W/tv.ds"
        # Named relative to the current directory (the series finds them
        # again by absolute path): ratio_input counts each file once.
        line=$(cd "$W/tv" && "$ENC" -q -o "$W/tv.ds" ${mode}_*.vti 2> "$W/e.txt") || { fail "TimeValue $mode: $(cat "$W/e.txt")"; continue; }
        # ratio_input: the three files' bytes (each once) over the dataset's.
        in=$(cat "$W"/tv/${mode}_*.vti | wc -c)
        awk -v r="$(kv ratio_input "$line")" -v i="$in" -v d="$(kv bytes "$line")" \
            'BEGIN { e = i / d; exit !(r > 0 && (r - e) ^ 2 < (1e-3 * e + 5e-4) ^ 2) }' ||
            fail "TimeValue ($mode): ratio_input $(kv ratio_input "$line"), $in / $(kv bytes "$line") expected"
        t=$(sed -n 's/^times = //p' "$W/tv.ds/manifest.txt")
        [ "$t" = "0.5 1.25 2.0000000000010001" ] && ok "TimeValue ($mode .vti from VTK's writer): times = $t" ||
            fail "TimeValue ($mode): times = '$t', 0.5 1.25 2.0000000000010001 expected (float64, whole)"
    done
    # A .pvd naming the files: its timesteps, not their TimeValues.
    { echo '<VTKFile type="Collection" version="0.1"><Collection>'
      for k in 0 1 2; do echo "<DataSet timestep=\"$((k * 10))\" file=\"raw_$k.vti\"/>"; done
      echo '</Collection></VTKFile>'; } > "$W/tv/s.pvd"
    rm -rf "$W/tv.ds"
    "$ENC" -q -o "$W/tv.ds" "$W/tv/s.pvd" > /dev/null 2> "$W/e.txt" || fail "pvd over TimeValue: $(cat "$W/e.txt")"
    t=$(sed -n 's/^times = //p' "$W/tv.ds/manifest.txt" 2> /dev/null)
    [ "$t" = "0 10 20" ] && ok "a .pvd's timesteps win over the files' TimeValue" || fail "pvd times '$t'"
else
    echo "no VTK for Python or numpy (python3-vtk9, python3-numpy): the TimeValue files are not checked"
fi
# Vectors (--magnitude): VTK's writer (vtkXMLImageDataWriter) puts a
# float32 velocity (the active Vectors), a float64 grad of 2 components and
# a float32 p into each file of 3 steps, in each data mode; vec.py writes
# their lengths as numpy computes them (float64 squares summed in component
# order, the root rounded to float32) and p into raw files.
cat > "$W/vec.py" <<'PY'
import sys
from vtkmodules.vtkCommonDataModel import vtkImageData
from vtkmodules.util.numpy_support import numpy_to_vtk
from vtkfix import fields, lengths, write_vti
out, modes = sys.argv[1], sys.argv[5].split(",")
nx, ny, nz = map(int, sys.argv[2:5])
n = nx * ny * nz
for k in range(3):
    vel, grad, p = fields(11 + k, n)
    im = vtkImageData()
    im.SetDimensions(nx, ny, nz)
    for name, arr in (("velocity", vel), ("grad", grad), ("p", p)):
        a = numpy_to_vtk(arr, deep=1)
        a.SetName(name)
        if name == "velocity":
            im.GetPointData().SetVectors(a)
        else:
            im.GetPointData().AddArray(a)
    for mode in modes:
        write_vti(im, "%s/%s_%d.vti" % (out, mode, k), mode)
    for name, arr in (("velocity", vel), ("grad", grad)):
        lengths(arr).tofile("%s/%s_%d.f32" % (out, name, k))
    p.tofile("%s/p_%d.f32" % (out, k))
PY
if "$PY" -c "import numpy, vtkmodules.vtkIOXML, vtkmodules.util.numpy_support" 2> /dev/null; then
    V=$W/vec
    mkdir -p "$V"
    "$PY" "$W/vec.py" "$V" 24 20 16 appended,raw,binary,ascii > "$W/vec.txt" 2>&1 || fail "vtk writer: $(cat "$W/vec.txt")"
    for mode in appended raw binary ascii; do
        vec_enc "velocity ($mode .vti from VTK's writer) --magnitude" 24x20x16 "$V"/velocity_[012].f32 -- \
            --magnitude "$V"/${mode}_[012].vti
    done
    magnitude_read_back velocity
    vec_enc "grad (Float64, 2 components) --magnitude" 24x20x16 "$V"/grad_[012].f32 -- \
        --magnitude --var grad "$V"/binary_[012].vti
    grep -qx "source_var = grad (magnitude)" "$W/vm/manifest.txt" || fail "grad: $(grep source_var "$W/vm/manifest.txt")"
    vec_enc "scalar p with --magnitude: as it is" 24x20x16 "$V"/p_[012].f32 -- \
        --magnitude --var p "$V"/appended_[012].vti
    grep -qx "source_var = p" "$W/vm/manifest.txt" && ok "source_var = p (a scalar array, as read)" \
        || fail "p: $(grep source_var "$W/vm/manifest.txt")"
    expect_exit 2 "array velocity has 3 components.*--magnitude encodes the vector's length" \
        "$ENC" -q -o "$W/bad" "$V"/appended_0.vti
    expect_exit 2 "array grad has 2 components.*--magnitude" "$ENC" -q --var grad -o "$W/bad" "$V"/ascii_0.vti
    [ ! -e "$W/bad" ] && [ ! -e "$W/bad.partial" ] || fail "vector without --magnitude: output left"
    # Boxes: a memory limit a little over the least the encoder takes makes
    # a plan of many passes, each reading boxes of the steps
    # (tvpal_input_read_box: raw rows, zlib blocks that cut points).
    rm -rf "$V" && mkdir -p "$V"
    "$PY" "$W/vec.py" "$V" 64 48 40 appended,raw > "$W/vec.txt" 2>&1 || fail "vtk writer: $(cat "$W/vec.txt")"
    for mode in appended raw; do
        m=$("$ENC" --axes xyz -j 1 --mem-limit 1M --magnitude --window 2 -o "$W/none" "$V"/${mode}_[012].vti 2>&1 |
            sed -n 's/.*give --mem-limit \([0-9]*\)K.*/\1/p')
        [ -n "$m" ] || { fail "$mode: no least --mem-limit"; continue; }
        vec_enc "velocity ($mode .vti) in boxes under --mem-limit $((m + 512))K" 64x48x40 "$V"/velocity_[012].f32 -- \
            -j 1 --mem-limit "$((m + 512))K" --magnitude "$V"/${mode}_[012].vti
        p=$(sed -n 's/.*passes=\([0-9]*\).*/\1/p' "$W/vm.out")
        [ "${p:-0}" -gt 3 ] && ok "$mode: $p passes of boxes" || fail "$mode: only ${p:-?} passes under $((m + 512))K"
    done
    # Interrupted in a later pass: a rerun without --magnitude is refused
    # and keeps the partial output; with it, the job resumes to the same
    # shards.
    lim=$((m + 512))K
    rm -rf "$W/res" "$W/res.partial"
    TVPAL_ENCODE_FAULT_AFTER=20 "$ENC" --axes xyz -q -j 1 --mem-limit $lim --window 2 --magnitude \
        -o "$W/res" "$V"/raw_[012].vti > /dev/null 2>&1
    [ -d "$W/res.partial" ] && [ ! -e "$W/res" ] || fail "interrupted --magnitude encode left $(ls -d "$W"/res*)"
    expect_exit 2 "array velocity has 3 components" "$ENC" --axes xyz -q -j 1 --mem-limit $lim --window 2 \
        -o "$W/res" "$V"/raw_[012].vti
    [ -d "$W/res.partial" ] || fail "the refused rerun removed the partial output"
    "$ENC" --axes xyz -j 1 --mem-limit $lim --window 2 --magnitude -o "$W/res" "$V"/raw_[012].vti \
        > /dev/null 2> "$W/res.err" || fail "resume: $(cat "$W/res.err")"
    grep -q "resuming .* at pass [2-9]" "$W/res.err" && same_shards "interrupted --magnitude encode, resumed" "$W/vr" "$W/res" \
        || fail "--magnitude resume: $(cat "$W/res.err")"
else
    echo "no numpy or VTK for Python (python3-numpy, python3-vtk9): the --magnitude part is skipped"
fi
S=${TVPAL_SHARED:-$TVPAL_SRCDIR/../shared}/data
if [ -d "$S/viscous-fingers-run01-vti" ] && [ -r "$S/viscous-fingers-run01/density_t001.f32" ]; then
    raws=""
    for k in $(seq 1 20); do raws="$raws $(printf '%s/viscous-fingers-run01/density_t%03d.f32' "$S" $k)"; done
    "$ENC" --axes xyz -q --dims 64x64x64 --window 4 -o "$W/vf-raw" $raws > /dev/null || fail "vf raw"
    "$ENC" --axes xyz -q --window 4 -o "$W/vf-vti" "$S"/viscous-fingers-run01-vti/*.vti > /dev/null 2> "$W/e.txt" \
        || fail "vf vti: $(cat "$W/e.txt")"
    same=1
    for a in x y z; do cmp -s "$W/vf-raw/node-0/axis-$a.tvps" "$W/vf-vti/node-0/axis-$a.tvps" || same=0; done
    [ $same = 1 ] && ok "viscous fingers: 20 .vti give the shards of the raw steps" || fail "viscous fingers shards differ"
    l1=$("$REP" -q "$W/vf-raw") && l2=$("$REP" -q "$W/vf-vti") && [ "$(kv psnr "$l1")" = "$(kv psnr "$l2")" ] \
        && ok "report on the .vti dataset: psnr $(kv psnr "$l2")" || fail "report: $l1 / $l2"
else
    echo "no $S/viscous-fingers-run01-vti: the real-data part is skipped"
fi
finish
