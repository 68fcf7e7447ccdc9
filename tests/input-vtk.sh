#!/bin/sh
# input-vtk: .pvd collections, .pvti pieces and legacy .vtk files encode to
# exactly the shards of raw files of the same numbers (tests/make-vtk.py):
# a .pvd gives its steps in timestep order and its times in the manifest;
# a bad file exits 2 naming it (and the file it lists) and leaves nothing
# behind; legacy vectors from VTK's writer (VECTORS, SCALARS of 3, FIELD
# arrays) encode with --magnitude to the shards of raw files of their
# lengths computed in numpy, whole and in boxes, and are refused without.
. "$(dirname "$0")/lib.sh"
# The VTK fixtures (tests/vtkfix.py) for the Python below.
export PYTHONPATH="$TVPAL_SRCDIR/tests${PYTHONPATH:+:$PYTHONPATH}"
"$PY" "$TVPAL_SRCDIR/tests/make-vtk.py" "$W/gen" > /dev/null 2> "$W/e.txt" || { fail "make-vtk: $(cat "$W/e.txt")"; finish; }
G=$W/gen
vti=1
if "$INFO" --inspect "$G/series.pvd" 2>&1 | grep -q "built without VTK"; then
    echo "built without VTK ImageData support: .pvd and .pvti skipped"; vti=0
fi


# enc NAME EXPECTED.f32... -- INPUT...: raw and input encodings, compared.
enc() {
    name=$1; shift
    raws=""
    while [ "$1" != "--" ]; do raws="$raws $1"; shift; done
    shift
    rm -rf "$W/r" "$W/v"
    "$ENC" --axes xyz -q --dims 5x4x3 --window 2 -o "$W/r" $raws > /dev/null 2> "$W/re.txt" || { fail "$name raw: $(cat "$W/re.txt")"; return; }
    "$ENC" --axes xyz -q --window 2 -o "$W/v" "$@" > /dev/null 2> "$W/ve.txt" || { fail "$name: $(cat "$W/ve.txt")"; return; }
    same_shards "$name" "$W/r" "$W/v"
}

if [ $vti = 1 ]; then
    enc series.pvd "$G/series-1.f32" "$G/series-2.f32" "$G/series-3.f32" -- "$G/series.pvd"
    grep -qx "times = 0.5 1 2.5" "$W/v/manifest.txt" && ok "series.pvd: times = 0.5 1 2.5" \
        || fail "series.pvd: manifest times: $(grep times "$W/v/manifest.txt")"
    enc unsorted.pvd "$G/series-1.f32" "$G/series-2.f32" "$G/series-3.f32" -- "$G/unsorted.pvd"
    grep -qx "times = 0.5 1 2.5" "$W/v/manifest.txt" && ok "unsorted.pvd: sorted by timestep" \
        || fail "unsorted.pvd: manifest times: $(grep times "$W/v/manifest.txt")"
    enc pieces.pvti "$G/pieces.f32" "$G/pieces.f32" -- "$G/pieces.pvti" "$G/pieces.pvti"
    enc "pieces.pvti --var w" "$G/pieces-w.f32" "$G/pieces-w.f32" -- --var w "$G/pieces.pvti" "$G/pieces.pvti"
    "$INFO" --inspect "$G/series.pvd" > "$W/i.txt" 2>&1 && grep -q "^$G/series.pvd: vti (VTK collection .pvd, 3 DataSets" "$W/i.txt" \
        && grep -q "^timestep 2.5 $G/series/step-2.vti" "$W/i.txt" && ok "--inspect series.pvd" || fail "--inspect .pvd: $(cat "$W/i.txt")"
    "$INFO" --inspect "$G/pieces.pvti" > "$W/i.txt" 2>&1 && grep -q "vti (VTK XML PImageData" "$W/i.txt" \
        && grep -q "^piece pieces/p0.vti extent 0 2 0 1 0 2" "$W/i.txt" && ok "--inspect pieces.pvti" || fail "--inspect .pvti: $(cat "$W/i.txt")"
    expect_exit 2 "bad-missing.pvd: its DataSet .*no-such-step.vti" "$ENC" --axes xyz -q -o "$W/bad" "$G/bad-missing.pvd"
    expect_exit 2 "multi-part collections are not supported" "$ENC" --axes xyz -q -o "$W/bad" "$G/bad-parts.pvd"
    expect_exit 2 "no-such-piece.vti: No such file.*a piece of .*bad-piece.pvti" "$ENC" --axes xyz -q -o "$W/bad" "$G/bad-piece.pvti"
    expect_exit 2 "bad-hole.pvti: the Pieces do not cover" "$ENC" --axes xyz -q -o "$W/bad" "$G/bad-hole.pvti"
    [ ! -e "$W/bad" ] && [ ! -e "$W/bad.partial" ] || fail "bad .pvd/.pvti: output left"
fi

enc ascii-float.vtk "$G/ascii-float.f32" "$G/ascii-float.f32" -- "$G/ascii-float.vtk" "$G/ascii-float.vtk"
enc binary-float.vtk "$G/binary-float.f32" "$G/binary-float.f32" -- "$G/binary-float.vtk" "$G/binary-float.vtk"
enc binary-short.vtk "$G/binary-short.f32" "$G/binary-short.f32" -- "$G/binary-short.vtk" "$G/binary-short.vtk"
enc two-scalars.vtk "$G/two-scalars.f32" "$G/two-scalars.f32" -- "$G/two-scalars.vtk" "$G/two-scalars.vtk"
enc "two-scalars.vtk --var b" "$G/two-scalars-b.f32" "$G/two-scalars-b.f32" -- --var b "$G/two-scalars.vtk" "$G/two-scalars.vtk"
enc "--format vtk" "$G/binary-float.f32" "$G/binary-float.f32" -- --format vtk "$G/binary-float.vtk" "$G/binary-float.vtk"
"$INFO" --inspect "$G/two-scalars.vtk" > "$W/i.txt" 2>&1 && grep -q "vtk (legacy VTK 3.0, BINARY big-endian, STRUCTURED_POINTS)" "$W/i.txt" \
    && grep -q "^b double components=1" "$W/i.txt" && ok "--inspect two-scalars.vtk" || fail "--inspect .vtk: $(cat "$W/i.txt")"
for v in "$G"/bad-*.vtk; do
    expect_exit 2 "$(basename "$v")" "$ENC" --axes xyz -q -o "$W/bad" "$v"
    [ ! -e "$W/bad" ] && [ ! -e "$W/bad.partial" ] || fail "$(basename "$v"): output left"
done
expect_exit 2 "DATASET POLYDATA: only STRUCTURED_POINTS" "$ENC" --axes xyz -q -o "$W/bad" "$G/bad-polydata.vtk"
expect_exit 2 "no point array zzz \(point arrays: a, vel \(VECTORS\), b\)" "$ENC" --axes xyz -q --var zzz -o "$W/bad" "$G/two-scalars.vtk"
[ ! -e "$W/bad" ] && [ ! -e "$W/bad.partial" ] || fail "bad .vtk: output left"

# Vectors (--magnitude) in legacy files from VTK's own writers
# (vtkStructuredPointsWriter, vtkDataSetWriter), ASCII and BINARY: a float32
# velocity as the active Vectors (VECTORS) or the active Scalars (SCALARS
# velocity float 3), a float64 grad of 2 components and a float32 p (both
# FIELD arrays of the POINT_DATA; the vectors' component names make VTK
# write METADATA after them, inside the FIELD too).  VTK's ASCII has 6
# digits, not the arrays' values: vec.py reads every file back with VTK's
# reader and writes FILE.NAME.f32 of what it read, the vectors' lengths as
# numpy computes them (float64 squares summed in component order, the root
# rounded to float32).
cat > "$W/vec.py" <<'PY'
import sys
import numpy as np
from vtkmodules.vtkCommonDataModel import vtkImageData
from vtkmodules.util.numpy_support import numpy_to_vtk
from vtkmodules.util.numpy_support import vtk_to_numpy
from vtkmodules.vtkIOLegacy import (vtkDataSetReader, vtkDataSetWriter,
                                    vtkStructuredPointsWriter)
from vtkfix import fields, lengths
out = sys.argv[1]


def references(path):
    """path.NAME.f32 of what VTK's reader reads from path."""
    r = vtkDataSetReader()
    r.SetFileName(path)
    r.ReadAllScalarsOn()
    r.ReadAllVectorsOn()
    r.ReadAllFieldsOn()
    r.Update()
    pd = r.GetOutput().GetPointData()
    for name in ("velocity", "grad", "p"):
        arr = vtk_to_numpy(pd.GetArray(name))
        ref = lengths(arr) if arr.ndim > 1 else arr.astype(np.float32)
        ref.tofile("%s.%s.f32" % (path, name))


nx, ny, nz = map(int, sys.argv[2:5])
n = nx * ny * nz
for k in range(3):
    vel, grad, p = fields(21 + k, n)
    for active in ("vectors", "scalars"):
        im = vtkImageData()
        im.SetDimensions(nx, ny, nz)
        for name, arr in (("velocity", vel), ("grad", grad), ("p", p)):
            a = numpy_to_vtk(arr, deep=1)
            a.SetName(name)
            for c in range(a.GetNumberOfComponents() if arr.ndim > 1 else 0):
                a.SetComponentName(c, "%s_%d" % (name, c))  # METADATA
            if name != "velocity":
                im.GetPointData().AddArray(a)
            elif active == "vectors":
                im.GetPointData().SetVectors(a)
            else:
                im.GetPointData().SetScalars(a)
        for mode in ("ascii", "binary"):
            w = (vtkStructuredPointsWriter() if active == "vectors"
                 else vtkDataSetWriter())
            path = "%s/%s-%s_%d.vtk" % (out, active, mode, k)
            w.SetFileName(path)
            w.SetInputData(im)
            if mode == "binary":
                w.SetFileTypeToBinary()
            if not w.Write():
                sys.exit("write failed")
            references(path)
    lengths(vel).tofile("%s/velocity_%d.f32" % (out, k))
PY
if "$PY" -c "import numpy, vtkmodules.vtkIOLegacy, vtkmodules.util.numpy_support" 2> /dev/null; then
    V=$W/vec
    mkdir -p "$V"
    "$PY" "$W/vec.py" "$V" 24 20 16 > "$W/vec.txt" 2>&1 || fail "vtk writer: $(cat "$W/vec.txt")"
    grep -q "^VECTORS velocity float" "$V/vectors-ascii_0.vtk" && grep -q "^SCALARS velocity float 3" "$V/scalars-ascii_0.vtk" &&
        grep -q "^grad 2 " "$V/vectors-ascii_0.vtk" && grep -q "^grad_1$" "$V/vectors-ascii_0.vtk" || fail "VTK's writer: not the layout this test expects: $(head -n 12 "$V/vectors-ascii_0.vtk")"
    for f in vectors-binary scalars-binary; do   # BINARY: the arrays' values
        cmp -s "$V/${f}_1.vtk.velocity.f32" "$V/velocity_1.f32" || fail "$f: VTK's reader reads other values"
    done
    for f in vectors-ascii vectors-binary scalars-ascii scalars-binary; do
        vec_enc "velocity ($f .vtk from VTK's writer) --magnitude" 24x20x16 "$V"/${f}_[012].vtk.velocity.f32 -- \
            --magnitude "$V"/${f}_[012].vtk
    done
    magnitude_read_back velocity
    for f in vectors-ascii vectors-binary; do
        vec_enc "FIELD grad (double, 2 components, $f) --magnitude" 24x20x16 "$V"/${f}_[012].vtk.grad.f32 -- \
            --magnitude --var grad "$V"/${f}_[012].vtk
        vec_enc "FIELD p ($f): a scalar FIELD array" 24x20x16 "$V"/${f}_[012].vtk.p.f32 -- \
            --var p "$V"/${f}_[012].vtk
    done
    expect_exit 2 "VECTORS velocity has 3 components.*--magnitude encodes the vector's length" \
        "$ENC" -q -o "$W/bad" "$V"/vectors-binary_0.vtk
    expect_exit 2 "SCALARS velocity has 3 components.*--magnitude" "$ENC" -q -o "$W/bad" "$V"/scalars-ascii_0.vtk
    expect_exit 2 "FIELD grad has 2 components.*--magnitude" "$ENC" -q --var grad -o "$W/bad" "$V"/vectors-ascii_0.vtk
    [ ! -e "$W/bad" ] && [ ! -e "$W/bad.partial" ] || fail "vector without --magnitude: output left"
    # Boxes: a memory limit a little over the least the encoder takes makes
    # a plan of many passes, each reading boxes of the steps (BINARY rows
    # of whole points, ASCII values in order).
    rm -rf "$V" && mkdir -p "$V"
    "$PY" "$W/vec.py" "$V" 64 48 40 > "$W/vec.txt" 2>&1 || fail "vtk writer: $(cat "$W/vec.txt")"
    for f in vectors-binary scalars-ascii; do
        m=$("$ENC" --axes xyz -j 1 --mem-limit 1M --magnitude --window 2 -o "$W/none" "$V"/${f}_[012].vtk 2>&1 |
            sed -n 's/.*give --mem-limit \([0-9]*\)K.*/\1/p')
        [ -n "$m" ] || { fail "$f: no least --mem-limit"; continue; }
        vec_enc "velocity ($f .vtk) in boxes under --mem-limit $((m + 512))K" 64x48x40 "$V"/${f}_[012].vtk.velocity.f32 -- \
            -j 1 --mem-limit "$((m + 512))K" --magnitude "$V"/${f}_[012].vtk
        p=$(sed -n 's/.*passes=\([0-9]*\).*/\1/p' "$W/vm.out")
        [ "${p:-0}" -gt 3 ] && ok "$f: $p passes of boxes" || fail "$f: only ${p:-?} passes under $((m + 512))K"
    done
else
    echo "no numpy or VTK for Python (python3-numpy, python3-vtk9): the --magnitude part is skipped"
fi
finish
