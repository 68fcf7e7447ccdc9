#!/bin/sh
# input-vti: VTK XML ImageData files encode to exactly the shards of raw
# files of the same numbers: the generated .vti of every encoding
# (tests/make-vti.py) and the real viscous-fingers series as delivered
# (20 zlib-compressed appended .vti files from ../shared/data, skipped where
# absent) against run01's raw steps 1..20; tvpal-report reads them again;
# the FieldData TimeValue of files from VTK's own writer are the times;
# a broken file exits 2 naming it and leaves nothing behind.
. "$(dirname "$0")/lib.sh"
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
    case $(basename "$v") in bad-*) continue ;; esac
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
if "$PY" -c "import vtkmodules.vtkIOXML" 2> /dev/null; then
    mkdir -p "$W/tv"
    "$PY" - "$W/tv" <<'PY' > "$W/tv.txt" 2>&1 || fail "vtk writer: $(cat "$W/tv.txt")"
import sys
from vtkmodules.vtkCommonDataModel import vtkImageData
from vtkmodules.vtkCommonCore import vtkDoubleArray, vtkFloatArray
from vtkmodules.vtkIOXML import vtkXMLImageDataWriter
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
        w = vtkXMLImageDataWriter()
        w.SetFileName("%s/%s_%d.vti" % (out, mode, k))
        w.SetInputData(im)
        if mode == "raw":
            w.SetDataModeToAppended()
            w.EncodeAppendedDataOff()
        elif mode == "binary":
            w.SetDataModeToBinary()
        elif mode == "ascii":
            w.SetDataModeToAscii()
        if not w.Write():
            sys.exit("write failed")
PY
    for mode in appended raw binary ascii; do
        rm -rf "$W/tv.ds"
        "$ENC" -q -o "$W/tv.ds" "$W"/tv/${mode}_*.vti > /dev/null 2> "$W/e.txt" || { fail "TimeValue $mode: $(cat "$W/e.txt")"; continue; }
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
    echo "no VTK for Python (python3-vtk9): the TimeValue files are not checked"
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
