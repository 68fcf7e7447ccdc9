#!/bin/sh
# input-hdf5: HDF5 files written with the HDF5 C API (test-hdf5 --make: a
# rank-4 chunked gzip dataset in a group next to another dataset, a series
# of rank-3 files) encode to exactly the shards of raw files of the same
# numbers, and tvpal-report measures them against the same reader;
# tvpal-info --inspect lists the datasets; bad input (unknown dataset, two
# candidates, rank 2, fill values without --nan-as, a damaged file) exits 2
# naming the file and the dataset and leaves nothing behind.
. "$(dirname "$0")/lib.sh"
MK=$TVPAL_BUILDDIR/tests/test-hdf5
"$MK" --make "$W"; rc=$?
[ "$rc" -eq 77 ] && { echo "built without HDF5 (libhdf5-dev): skipped"; exit 77; }
[ "$rc" -eq 0 ] || { echo "test-hdf5 --make failed ($rc)"; exit 99; }
D=9x7x5
"$ENC" --axes xyz -q --dims $D --window 2 -o "$W/raw" "$W"/raw_t*.f32 > /dev/null || { fail "raw encode"; finish; }
"$INFO" --inspect "$W/all.h5" > "$W/inspect.txt" 2>&1 \
    && grep -q '^.*all.h5: hdf5$' "$W/inspect.txt" \
    && grep -qx '/sim/other (5, 7, 9) double units=""' "$W/inspect.txt" \
    && grep -qx '/sim/temp (3, 5, 7, 9) float units="K"' "$W/inspect.txt" \
    && ok "--inspect lists /sim/temp and /sim/other" || fail "--inspect: $(cat "$W/inspect.txt")"
"$ENC" --axes xyz -q --var /sim/temp --window 2 -o "$W/ds-all" "$W/all.h5" > /dev/null 2> "$W/e.txt" \
    || fail "all.h5 encode: $(cat "$W/e.txt")"
shards_same "$W/raw" "$W/ds-all" && ok "rank 4, chunked gzip: shards identical to raw" || fail "all.h5: shards differ from raw"
grep -q "^source_format = hdf5" "$W/ds-all/manifest.txt" && grep -q "^source_var = /sim/temp" "$W/ds-all/manifest.txt" \
    && ok "manifest names format and dataset" || fail "manifest: $(grep '^source' "$W/ds-all/manifest.txt")"
"$ENC" --axes xyz -q --format hdf5 --var sim/temp --window 2 -o "$W/ds-forced" "$W/all.h5" > /dev/null 2> "$W/e.txt" \
    && shards_same "$W/raw" "$W/ds-forced" && ok "--format hdf5, relative path" || fail "--format hdf5: $(cat "$W/e.txt")"
"$ENC" --axes xyz -q --window 2 -o "$W/ds-series" "$W"/s0.h5 "$W"/s1.h5 "$W"/s2.h5 > /dev/null 2> "$W/e.txt" \
    || fail "series encode: $(cat "$W/e.txt")"
shards_same "$W/raw" "$W/ds-series" && ok "series of rank-3 files, the only dataset: shards identical to raw" \
    || fail "series shards differ"
grep -q "^source_var = /temp" "$W/ds-series/manifest.txt" && ok "series: the only dataset /temp" || fail "series var"
# A NetCDF-4 file is NetCDF to the encoder, with --var T and with --var
# /T (its root group's variable, as an HDF5 path names it: CF times,
# coordinates, units and packing kept), unless --var is a dataset inside a
# group (then HDF5: the same values, the same shards).
if command -v ncgen > /dev/null; then
    printf 'netcdf n {\ndimensions:\n z = 2 ;\n y = 3 ;\n x = 4 ;\nvariables:\n float T(z, y, x) ;\ndata:\n T = %s ;\ngroup: g {\nvariables:\n float T(z, y, x) ;\ndata:\n T = %s ;\n}\n}\n' \
        "$(seq -s ', ' 1 24)" "$(seq -s ', ' 1 24)" > "$W/n.cdl" && ncgen -k nc4 -o "$W/n.nc" "$W/n.cdl" || fail "ncgen"
    "$ENC" --axes xyz -q --var T -o "$W/nc-as-nc" "$W/n.nc" "$W/n.nc" > /dev/null 2> "$W/e.txt" \
        && grep -q "^source_format = netcdf" "$W/nc-as-nc/manifest.txt" \
        && ok "NetCDF-4 with --var T: read as NetCDF" || fail "NetCDF-4 as NetCDF: $(cat "$W/e.txt")"
    "$ENC" --axes xyz -q --var /g/T -o "$W/nc-as-h5" "$W/n.nc" "$W/n.nc" > /dev/null 2> "$W/e.txt" \
        && grep -q "^source_format = hdf5" "$W/nc-as-h5/manifest.txt" \
        && "$REP" -q "$W/nc-as-h5" > /dev/null 2>> "$W/e.txt" \
        && ok "NetCDF-4 with --var /g/T: read as HDF5, and reported" || fail "NetCDF-4 as HDF5: $(cat "$W/e.txt")"
    same=1
    for a in x y z; do cmp -s "$W/nc-as-nc/node-0/axis-$a.tvps" "$W/nc-as-h5/node-0/axis-$a.tvps" || same=0; done
    [ $same = 1 ] && ok "both readers give the same shards" || fail "NetCDF and HDF5 readings differ"
    # CF: a time coordinate, float32 coordinates, packed int16 in K.
    cat > "$W/cf.cdl" <<'CDL'
netcdf cf {
dimensions:
  time = UNLIMITED ; z = 3 ; y = 4 ; x = 5 ;
variables:
  double time(time) ; time:units = "hours since 2005-08-28 00:00:00" ;
  float z(z) ; float y(y) ; float x(x) ;
  short T(time, z, y, x) ; T:scale_factor = 0.01 ; T:add_offset = 273.0 ; T:units = "K" ;
data:
  time = 0, 6, 12 ;
  z = 0, 0.5, 1 ; y = 0, 2, 4, 6 ; x = 10, 12, 14, 16, 18 ;
CDL
    printf '  T = %s ;\n}\n' "$(seq -s ', ' 0 179)" >> "$W/cf.cdl"
    ncgen -k nc4 -o "$W/cf.nc" "$W/cf.cdl" || fail "ncgen cf"
    "$ENC" -q --var T -o "$W/cf-name" "$W/cf.nc" > /dev/null 2> "$W/e.txt" || fail "cf --var T: $(cat "$W/e.txt")"
    "$ENC" -q --var /T -o "$W/cf-path" "$W/cf.nc" > /dev/null 2> "$W/e.txt" || fail "cf --var /T: $(cat "$W/e.txt")"
    keys='^(source_format|source_var|units|spacing|origin|times|time_units|value_min|value_max) '
    grep -E "$keys" "$W/cf-path/manifest.txt" > "$W/cf-path.keys" 2> /dev/null
    if grep -E "$keys" "$W/cf-name/manifest.txt" 2> /dev/null | cmp -s - "$W/cf-path.keys" &&
        grep -q "^times = 0 6 12$" "$W/cf-path.keys" && grep -q "^spacing = 2 2 0.5$" "$W/cf-path.keys" &&
        grep -q "^units = K$" "$W/cf-path.keys" && grep -q "^value_min = 273$" "$W/cf-path.keys"; then
        ok "CF NetCDF-4 with --var /T: times, spacing, units and unpacked values as --var T"
    else
        fail "CF NetCDF-4 --var /T: $(tr '\n' ';' < "$W/cf-path.keys")"
    fi
fi
lr=$("$REP" -q "$W/raw") && lh=$("$REP" -q "$W/ds-all") || fail "report"
[ "$(kv psnr "$lr")" = "$(kv psnr "$lh")" ] && [ "$(kv rmse "$lr")" = "$(kv rmse "$lh")" ] \
    && ok "report: psnr $(kv psnr "$lh") as from raw" || fail "report differs: $lr / $lh"
ls=$("$REP" -q "$W/ds-series") && [ "$(kv psnr "$ls")" = "$(kv psnr "$lr")" ] \
    && ok "report on the series" || fail "series report: $ls"
# Bad input: exit 2, a message naming the file and the dataset, nothing left.
bad() { expect_exit "$@"; cat "$W/err.txt" >> "$W/all-err.txt"; }
nothing_left() { [ ! -e "$W/bad" ] && [ ! -e "$W/bad.partial" ] && ok "nothing left ($1)" || fail "output left ($1)"; }
bad 2 "all.h5.*/sim/nope.*/sim/temp" "$ENC" --axes xyz -q --var /sim/nope -o "$W/bad" "$W/all.h5"; nothing_left "unknown dataset"
bad 2 "all.h5.*2 datasets.*/sim/other \(5, 7, 9\).*/sim/temp \(3, 5, 7, 9\)" "$ENC" --axes xyz -q -o "$W/bad" "$W/all.h5"
nothing_left "two candidates"
bad 2 "flat.h5.*/flat \(7, 9\).*rank 2" "$ENC" --axes xyz -q --var /flat -o "$W/bad" "$W/flat.h5"; nothing_left "rank 2"
bad 2 "9x7x5.*--dims|--dims.*9x7x5" "$ENC" --axes xyz -q --var /sim/temp --dims 9x7x6 -o "$W/bad" "$W/all.h5"
nothing_left "contradicting --dims"
line=$("$ENC" --axes xyz -q --var /sim/temp --window 2 -o "$W/ds-miss" "$W/fill.h5" 2> "$W/e.txt") \
    && [ "$(kv missing "$line")" = 1 ] && ok "fill value encoded as missing" \
    || fail "fill value: $line $(cat "$W/e.txt")"
nan_exactly "$W/ds-miss" 1 9x7x5 "4,2,1"
"$ENC" --axes xyz -q --var /sim/temp --window 2 --nan-as 10 -o "$W/ds-fill" "$W/fill.h5" > /dev/null 2> "$W/e.txt" \
    && ok "fill value with --nan-as" || fail "--nan-as: $(cat "$W/e.txt")"
bad 2 "bad.h5.*damaged" "$ENC" --axes xyz -q -o "$W/bad" "$W/bad.h5"; nothing_left "damaged file"
bad 2 "bad.h5.*damaged" "$INFO" --inspect "$W/bad.h5"
bad 2 "raw_t0.f32.*not an HDF5 file" "$ENC" --axes xyz -q --format hdf5 -o "$W/bad" "$W/raw_t0.f32"; nothing_left "not HDF5"
# units as h5py writes them: a variable-length UTF-8 string never reached
# the manifest, a fixed-length one (numpy bytes) lost its last character.
if "$PY" -c "import h5py" 2> /dev/null; then
    "$PY" - "$W/h5py.h5" <<'PY' || fail "h5py"
import sys, h5py, numpy as np
with h5py.File(sys.argv[1], "w") as f:
    f.create_dataset("T", data=np.arange(24, dtype="f4").reshape(2, 3, 4)).attrs["units"] = "K"
    f.create_dataset("R", data=np.arange(24, dtype="f4").reshape(2, 3, 4)).attrs["units"] = np.bytes_("kg m-3")
    # CF packing: int16 counts 0..920 in steps of 40, K = counts * 0.01 + 273.15
    p = f.create_dataset("P", data=(np.arange(24, dtype="i2") * 40).reshape(2, 3, 4))
    p.attrs["scale_factor"] = np.float32(0.01)
    p.attrs["add_offset"] = np.float32(273.15)
    p.attrs["units"] = "K"
PY
    for vu in "T K" "R kg m-3"; do
        set -- $vu
        v=$1; shift
        rm -rf "$W/hu"
        "$ENC" -q --var "/$v" -o "$W/hu" "$W/h5py.h5" > /dev/null 2>> "$W/all-err.txt" || fail "encode h5py /$v"
        grep -qx "units = $*" "$W/hu/manifest.txt" && ok "h5py units of /$v: $*" \
            || fail "h5py units of /$v: $(grep '^units' "$W/hu/manifest.txt")"
    done
    # packed values unpacked, as the NetCDF reader unpacks them (they were
    # encoded as the raw counts 0..920)
    rm -rf "$W/hp"
    "$ENC" -q --var /P -o "$W/hp" "$W/h5py.h5" > /dev/null 2>> "$W/all-err.txt" || fail "encode h5py /P"
    lo=$(sed -n 's/^value_min = //p' "$W/hp/manifest.txt"); hi=$(sed -n 's/^value_max = //p' "$W/hp/manifest.txt")
    awk -v a="$lo" -v b="$hi" 'BEGIN { exit !(a > 273.149 && a < 273.151 && b > 282.349 && b < 282.351) }' \
        && grep -qx "type = f32" "$W/hp/manifest.txt" \
        && ok "h5py packed int16 (scale_factor, add_offset): $lo .. $hi K" \
        || fail "h5py packed: $lo .. $hi"
else
    echo "no h5py (python3-h5py): the h5py units case is skipped"
fi
# HDF5 never prints its own error stack
grep -q "HDF5-DIAG" "$W/all-err.txt" && fail "HDF5 printed its error stack" || ok "no HDF5 error stack on stderr"
finish
