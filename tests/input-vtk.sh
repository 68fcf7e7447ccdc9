#!/bin/sh
# input-vtk: .pvd collections, .pvti pieces and legacy .vtk files encode to
# exactly the shards of raw files of the same numbers (tests/make-vtk.py):
# a .pvd gives its steps in timestep order and its times in the manifest;
# a bad file exits 2 naming it (and the file it lists) and leaves nothing
# behind.
. "$(dirname "$0")/lib.sh"
"$PY" "$TVPAL_SRCDIR/tests/make-vtk.py" "$W/gen" > /dev/null 2> "$W/e.txt" || { fail "make-vtk: $(cat "$W/e.txt")"; finish; }
G=$W/gen
vti=1
if "$INFO" --inspect "$G/series.pvd" 2>&1 | grep -q "built without VTK"; then
    echo "built without VTK ImageData support: .pvd and .pvti skipped"; vti=0
fi

# same_shards NAME RAWDIR ENCDIR
same_shards() {
    s=1
    for a in x y z; do cmp -s "$2/node-0/axis-$a.tvps" "$3/node-0/axis-$a.tvps" || s=0; done
    [ $s = 1 ] && ok "$1: shards identical to raw" || fail "$1: shards differ from raw"
}

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
expect_exit 2 "no point SCALARS zzz \(point SCALARS: a, b\)" "$ENC" --axes xyz -q --var zzz -o "$W/bad" "$G/two-scalars.vtk"
[ ! -e "$W/bad" ] && [ ! -e "$W/bad.partial" ] || fail "bad .vtk: output left"
finish
