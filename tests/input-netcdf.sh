#!/bin/sh
# input-netcdf: NetCDF files made by ncgen from CDL (classic, 64-bit
# offset, NetCDF-4 with zlib chunks; one file with a time dimension, or a
# series of files) encode to exactly the shards of raw files of the same
# numbers, and tvpal-report measures them against the same reader; bad
# input (unknown variable, contradicting --dims, fill values without
# --nan-as) exits 2 naming what was wrong and leaves nothing behind; the
# real files in ../shared/data/netcdf encode (skipped where absent).
. "$(dirname "$0")/lib.sh"
if ! command -v ncgen > /dev/null; then echo "no ncgen (netcdf-bin): skipped"; exit 77; fi
D=9x7x5
T=3
# The numbers: a smooth field with a moving bump, float32-exact in CDL
# (written with 9 significant digits, read back as the same float).
"$PY" - "$W" $D $T <<'PY' || exit 99
import struct, sys
w, dims, T = sys.argv[1], [int(v) for v in sys.argv[2].split("x")], int(sys.argv[3])
nx, ny, nz = dims
def val(t, x, y, z):
    f = struct.unpack("<f", struct.pack("<f", 10.0 + x * 0.5 + y * 0.25 - z + 3.0 * (x == t + 2) * (y == 3)))[0]
    return f
def cdl(name, steps, fmt_fill=False):
    lines = ["netcdf %s {" % name, "dimensions:", " time = UNLIMITED ;",
             " z = %d ;" % nz, " y = %d ;" % ny, " x = %d ;" % nx, "variables:",
             " double time(time) ;", '  time:units = "hours since 2005-08-28 00:00:00" ;',
             " float x(x) ;", " float y(y) ;", " float z(z) ;",
             " float temp(time, z, y, x) ;", '  temp:units = "K" ;']
    if fmt_fill:
        lines.append("  temp:_FillValue = -9999.f ;")
    lines += [" float other(z, y, x) ;", "data:",
              " time = %s ;" % ", ".join(str(3 * t) for t in steps),
              " x = %s ;" % ", ".join(str(0.5 * i) for i in range(nx)),
              " y = %s ;" % ", ".join(str(2.0 * i) for i in range(ny)),
              " z = %s ;" % ", ".join(str(1.0 + i) for i in range(nz))]
    vals = []
    for t in steps:
        for z in range(nz):
            for y in range(ny):
                for x in range(nx):
                    v = val(t, x, y, z)
                    if fmt_fill and t == 1 and (x, y, z) == (4, 2, 1):
                        v = -9999.0
                    vals.append("%.9g" % v)
    lines.append(" temp = %s ;" % ", ".join(vals))
    lines.append(" other = %s ;" % ", ".join("1" for _ in range(nx * ny * nz)))
    lines.append("}")
    return "\n".join(lines) + "\n"
open("%s/all.cdl" % w, "w").write(cdl("all", range(T)))
open("%s/a.cdl" % w, "w").write(cdl("a", range(2)))
open("%s/b.cdl" % w, "w").write(cdl("b", range(2, T)))
open("%s/fill.cdl" % w, "w").write(cdl("fill", range(T), True))
for t in range(T):
    with open("%s/raw_t%d.f32" % (w, t), "wb") as f:
        for z in range(nz):
            for y in range(ny):
                for x in range(nx):
                    f.write(struct.pack("<f", val(t, x, y, z)))
PY
for k in nc3 nc6 nc4; do
    ncgen -k $k -o "$W/all-$k.nc" "$W/all.cdl" || { fail "ncgen -k $k"; continue; }
done
ncgen -k nc4 -o "$W/a.nc" "$W/a.cdl" && ncgen -k nc4 -o "$W/b.nc" "$W/b.cdl" || fail "ncgen series"
ncgen -k nc4 -o "$W/fill.nc" "$W/fill.cdl" || fail "ncgen fill"
"$ENC" --axes xyz -q --dims $D --window 2 -o "$W/raw" "$W"/raw_t*.f32 > /dev/null || { fail "raw encode"; finish; }
if "$INFO" --inspect "$W/all-nc4.nc" 2>&1 | grep -q "built without NetCDF"; then
    echo "built without NetCDF: skipped (and tvpal-info says so)"; exit 77
fi
"$INFO" --inspect "$W/all-nc4.nc" > "$W/inspect.txt" 2>&1 && grep -q "temp" "$W/inspect.txt" \
    && grep -q "other" "$W/inspect.txt" && ok "--inspect lists temp and other" \
    || fail "--inspect: $(cat "$W/inspect.txt")"
for k in nc3 nc6 nc4; do
    "$ENC" --axes xyz -q --var temp --window 2 -o "$W/ds-$k" "$W/all-$k.nc" > /dev/null 2> "$W/e.txt" \
        || { fail "$k encode: $(cat "$W/e.txt")"; continue; }
    shards_same "$W/raw" "$W/ds-$k" && ok "$k: shards identical to raw" || fail "$k: shards differ from raw"
    grep -q "^source_format = netcdf" "$W/ds-$k/manifest.txt" && grep -q "^source_var = temp" "$W/ds-$k/manifest.txt" \
        && grep -qx "units = K" "$W/ds-$k/manifest.txt" \
        && ok "$k: manifest names format, variable and its units" || fail "$k: manifest"
done
"$ENC" --axes xyz -q --var temp --window 2 -o "$W/ds-series" "$W/a.nc" "$W/b.nc" > /dev/null 2> "$W/e.txt" \
    || fail "series encode: $(cat "$W/e.txt")"
shards_same "$W/raw" "$W/ds-series" && ok "series of 2 + 1 steps: shards identical to raw" || fail "series shards differ"
grep -q "^source_layout = series" "$W/ds-series/manifest.txt" && ok "series layout" || fail "series layout"
"$ENC" --axes z -q --var temp --window 2 --units "degC" -o "$W/ds-units" "$W/all-nc4.nc" > /dev/null 2> "$W/e.txt" \
    && grep -qx "units = degC" "$W/ds-units/manifest.txt" && ok "--units overrides the attribute" \
    || fail "--units: $(cat "$W/e.txt") $(grep units "$W/ds-units/manifest.txt")"
lr=$("$REP" -q "$W/raw") && ln=$("$REP" -q "$W/ds-nc4") || fail "report"
[ "$(kv psnr "$lr")" = "$(kv psnr "$ln")" ] && [ "$(kv rmse "$lr")" = "$(kv rmse "$ln")" ] \
    && ok "report: psnr $(kv psnr "$ln") as from raw" || fail "report differs: $lr / $ln"
ls=$("$REP" -q "$W/ds-series") && [ "$(kv psnr "$ls")" = "$(kv psnr "$lr")" ] \
    && ok "report on the series" || fail "series report: $ls"
# Bad input: exit 2, a message naming the file and the variable, nothing left.
nothing_left() { [ ! -e "$W/bad" ] && [ ! -e "$W/bad.partial" ] && ok "nothing left ($1)" || fail "output left ($1)"; }
expect_exit 2 "nope.*temp|temp.*nope" "$ENC" --axes xyz -q --var nope -o "$W/bad" "$W/all-nc4.nc"; nothing_left "unknown var"
expect_exit 2 "temp" "$ENC" --axes xyz -q -o "$W/bad" "$W/all-nc4.nc"; nothing_left "two candidates"
expect_exit 2 "9x7x5.*--dims|--dims.*9x7x5" "$ENC" --axes xyz -q --var temp --dims 9x7x6 -o "$W/bad" "$W/all-nc4.nc"
nothing_left "contradicting --dims"
expect_exit 2 "--steps and --endian" "$ENC" --axes xyz -q --var temp --steps 3 -o "$W/bad" "$W/all-nc4.nc"; nothing_left "--steps"
# A _FillValue is missing: NaN after decoding, there and nowhere else.
line=$("$ENC" --axes xyz -q --var temp --window 2 -o "$W/ds-miss" "$W/fill.nc" 2> "$W/e.txt") \
    && [ "$(kv missing "$line")" = 1 ] && ok "fill value encoded as missing" \
    || fail "fill value: $line $(cat "$W/e.txt")"
nan_exactly "$W/ds-miss" 1 9x7x5 "4,2,1"
nan_exactly "$W/ds-miss" 0 9x7x5 ""
"$ENC" --axes xyz -q --var temp --window 2 --nan-as 10 -o "$W/ds-fill" "$W/fill.nc" > /dev/null 2> "$W/e.txt" \
    && ok "fill value with --nan-as" || fail "--nan-as: $(cat "$W/e.txt")"
"$REP" -q "$W/ds-fill" > /dev/null 2> "$W/e.txt" && ok "report with --nan-as" || fail "report --nan-as: $(cat "$W/e.txt")"
# A classic header that counts more than the file holds (libnetcdf would
# allocate gigabytes for it): refused before the library sees it, within
# 1 GB of address space (not under AddressSanitizer, whose shadow memory
# needs more: there the sanitizer's own allocation limits watch instead).
lim='ulimit -v 1000000;'
[ -n "${ASAN_OPTIONS+x}" ] && lim=
for f in netcdf-libnetcdf-8GB-malloc netcdf-libnetcdf-attr-oom; do
    cp "$TVPAL_SRCDIR/tests/fuzz/corpus/netcdf/$f" "$W/$f.nc"
    expect_exit 2 "$f.nc: a NetCDF header that counts more items than the file's [0-9]+ bytes can hold" \
        sh -c "$lim"' exec "$@"' sh "$ENC" --axes xyz -q -o "$W/bad" "$W/$f.nc"
    nothing_left "forged counts ($f)"
done
printf 'CDF\001garbage' > "$W/trunc.nc"
expect_exit 2 "trunc.nc" "$ENC" --axes xyz -q -o "$W/bad" "$W/trunc.nc"; nothing_left "corrupt file"
# Real model output.
S=${TVPAL_SHARED:-$TVPAL_SRCDIR/../shared}/data/netcdf
if [ -r "$S/mercator_sample.nc" ] && [ -r "$S/contour.cdf" ]; then
    "$ENC" --axes xyz -q --var T -o "$W/wrf" "$S/mercator_sample.nc" > "$W/o.txt" 2> "$W/e.txt" \
        && grep -q "^dims = 48x48x14" "$W/wrf/manifest.txt" && grep -q "^steps = 4" "$W/wrf/manifest.txt" \
        && ok "WRF T: 48x48x14, 4 steps" || fail "WRF: $(cat "$W/e.txt")"
    l=$("$REP" -q "$W/wrf") && ge "$(kv psnr "$l")" 30 && ok "WRF report psnr $(kv psnr "$l")" || fail "WRF report: $l"
    "$ENC" --axes xyz -q --var T --nan-as 0 -o "$W/contour" "$S/contour.cdf" > /dev/null 2> "$W/e.txt" \
        && grep -q "^dims = 36x33x10" "$W/contour/manifest.txt" && grep -q "^steps = 7" "$W/contour/manifest.txt" \
        && ok "contour T: 36x33x10, 7 steps" || fail "contour: $(cat "$W/e.txt")"
    grep -q "the z axis (level) is not evenly spaced" "$W/e.txt" && ok "warning: pressure levels not evenly spaced" \
        || fail "no spacing warning: $(cat "$W/e.txt")"
    grep -q "^times = 0 6 12 24 30 36 48$" "$W/contour/manifest.txt" && grep -q "^time_units = hours$" "$W/contour/manifest.txt" \
        && ok "contour: times from frtime" || fail "contour times: $(grep '^time' "$W/contour/manifest.txt")"
    # Its Z has fill values (T has none): missing values, as many as ncdump
    # (netcdf-bin's own reader) shows ("_" or outside valid_range -150..5000),
    # and NaN after decoding at exactly those voxels of step 0.
    "$ENC" --axes xyz -q --var Z -o "$W/contour-miss" "$S/contour.cdf" > /dev/null 2> "$W/e.txt" || fail "contour missing: $(cat "$W/e.txt")"
    "$DEC" "$W/contour-miss" --step 0 --axis z -o "$W/c0.f32" || fail "contour decode"
    ncdump -v Z "$S/contour.cdf" > "$W/c.cdl" || fail ncdump
    got=$(sed -n 's/^missing = //p' "$W/contour-miss/manifest.txt")
    "$PY" - "$W/c.cdl" "$W/c0.f32" "$got" <<'PY' && ok "contour: $got missing values, where ncdump has them" || fail "contour missing values"
import math, re, struct, sys
text = open(sys.argv[1]).read().split(" Z =", 1)[1].split(";", 1)[0]
vals = [t for t in re.split(r"[,\s]+", text) if t]
miss = [t == "_" or not (-150 <= float(t) <= 5000) for t in vals]
n0 = 36 * 33 * 10
b = open(sys.argv[2], "rb").read()
dec = struct.unpack("<%df" % (len(b) // 4), b)
where = [math.isnan(v) for v in dec]
print("ncdump: %d of %d missing, %d at step 0; manifest %s; decoded step 0: %d NaN"
      % (sum(miss), len(vals), sum(miss[:n0]), sys.argv[3], sum(where)))
sys.exit(0 if sum(miss) == int(sys.argv[3]) and where == miss[:n0] and sum(miss) > 0 else 1)
PY
    l=$("$REP" -q "$W/contour-miss") && [ "$(kv missing "$l")" = "$got" ] && [ "$(kv missing_mismatch "$l")" = 0 ] \
        && ok "contour report: psnr $(kv psnr "$l") without the $got missing values" || fail "contour report: $l"
else
    echo "no $S: the real-data part is skipped"
fi
# Times across files must increase, as --times must: files whose times
# overlap or repeat, or that run backwards, are refused naming both.
for pair in "a 0,3 b 3,6 overlap" "c 0,3 d 0,3 repeat" "e 6,9 f 0,3 backwards"; do
    set -- $pair
    for f in "$1 $2" "$3 $4"; do
        set -- $f
        printf 'netcdf %s {\ndimensions:\n time = 2 ; z = 1 ; y = 2 ; x = 2 ;\nvariables:\n double time(time) ;\n  time:units = "hours since 2000-01-01" ;\n float v(time, z, y, x) ;\ndata:\n time = %s ;\n v = 1, 2, 3, 4, 5, 6, 7, 8 ;\n}\n' "$1" "$2" > "$W/tm-$1.cdl"
        ncgen -o "$W/tm-$1.nc" "$W/tm-$1.cdl" || fail "ncgen $1"
    done
done
expect_exit 2 "tm-b.nc: the time of step 2 \(3, .*tm-b.nc\) is not after step 1's \(3, .*tm-a.nc\)" \
    "$ENC" -q -o "$W/tm" "$W/tm-a.nc" "$W/tm-b.nc"
expect_exit 2 "tm-d.nc: the time of step 2 \(0, .*\) is not after step 1's \(3, .*tm-c.nc\)" \
    "$ENC" -q -o "$W/tm" "$W/tm-c.nc" "$W/tm-d.nc"
expect_exit 2 "the time of step 2 \(0, .*tm-f.nc\) is not after step 1's \(9, .*tm-e.nc\)" \
    "$ENC" -q -o "$W/tm" "$W/tm-e.nc" "$W/tm-f.nc"
[ ! -e "$W/tm" ] && [ ! -e "$W/tm.partial" ] && ok "times out of order: nothing left" || fail "output left"
# Long variable names (200 characters, the same first 190) are read whole:
# they were cut to 127, so a job on one resumed another's steps and
# tvpal-report looked for the cut name.
a=$(printf 'v%.0s' $(seq 1 190))
"$PY" - "$W/long.cdl" "$a" <<'PY'
import sys
a = sys.argv[2]
open(sys.argv[1], "w").write("""netcdf long {
dimensions:
 t = 6 ; z = 2 ; y = 3 ; x = 4 ;
variables:
 float %sAAAAAAAAAA(t, z, y, x) ;
 float %sBBBBBBBBBB(t, z, y, x) ;
data:
 %sAAAAAAAAAA = %s ;
 %sBBBBBBBBBB = %s ;
}
""" % (a, a, a, ", ".join(str(i % 17) for i in range(144)), a,
       ", ".join(str(i % 13 + 100) for i in range(144))))
PY
ncgen -o "$W/long.nc" "$W/long.cdl" || fail "ncgen long"
TVPAL_ENCODE_FAULT_AFTER=3 "$ENC" -q --var "${a}AAAAAAAAAA" --window 2 -o "$W/lv" "$W/long.nc" > /dev/null 2>&1
"$ENC" --var "${a}BBBBBBBBBB" --window 2 -o "$W/lv" "$W/long.nc" > /dev/null 2> "$W/lv.err"
if ! grep -q resuming "$W/lv.err" && grep -q "^source_var = ${a}BBBBBBBBBB$" "$W/lv/manifest.txt" &&
   "$REP" -q "$W/lv" > "$W/lv.rep" 2>&1; then
    ok "200-character variable names: read whole, no resume of the other's job, report reads it"
else
    fail "long variable names: $(cat "$W/lv.err" "$W/lv.rep" 2> /dev/null | head -n 5)"
fi
# Evenly spaced float32 coordinates are even at their own precision (x in
# float32 steps of 0.1, z from 0.035 in steps of 0.2 up to 19.835, as the
# Isabel CF file has them: both were called uneven and drawn with spacing
# 1); a truly uneven axis still warns and falls back.
"$PY" - "$W" <<'PY'
import struct, sys
f32 = lambda v: struct.unpack("<f", struct.pack("<f", v))[0]
z = [f32(f32(0.035) + f32(i * f32(0.2))) for i in range(100)]
x = [f32(i * 0.1) for i in range(8)]
for name, xs in (("even32", ", ".join(repr(v) for v in x)),
                 ("uneven", "0, 0.1, 0.2, 0.35, 0.4, 0.5, 0.6, 0.7")):
    open("%s/%s.cdl" % (sys.argv[1], name), "w").write(
        "netcdf %s {\ndimensions: z = 100 ; y = 2 ; x = 8 ;\n"
        "variables: float z(z) ; float y(y) ; float x(x) ; float v(z, y, x) ;\n"
        "data: z = %s ;\n y = 0, 1 ;\n x = %s ;\n v = %s ;\n}\n"
        % (name, ", ".join(repr(v) for v in z), xs,
           ", ".join(str(i % 7) for i in range(1600))))
PY
for n in even32 uneven; do
    ncgen -o "$W/$n.nc" "$W/$n.cdl" || fail "ncgen $n"
    "$ENC" -q -o "$W/$n" "$W/$n.nc" > /dev/null 2> "$W/$n.err" || fail "encode $n: $(cat "$W/$n.err")"
done
sp=$(sed -n 's/^spacing = //p' "$W/even32/manifest.txt")
echo "$sp" | awk '{ exit !($1 > 0.0999999 && $1 < 0.1000001 && $3 > 0.1999999 && $3 < 0.2000001) }' \
    && [ ! -s "$W/even32.err" ] && ok "float32 coordinates in steps of 0.1 and 0.2: spacing $sp, no warning" \
    || fail "float32 coordinates: spacing $sp $(cat "$W/even32.err")"
grep -q "the x axis (x) is not evenly spaced" "$W/uneven.err" && grep -q "^spacing = 1 1 0.2" "$W/uneven/manifest.txt" \
    && ok "a truly uneven axis: warned, spacing 1" || fail "uneven axis: $(cat "$W/uneven.err")"
# A missing_value list of 20 values (more than the 15 read before, when the
# whole list was ignored and its values became data): the voxels of its
# last value are missing.
"$PY" - "$W/m20.cdl" <<'PY'
import sys
vals = ", ".join("%d.f" % (-1000 - i) for i in range(19)) + ", -999.f"
open(sys.argv[1], "w").write("""netcdf m20 {
dimensions:
 z = 2 ; y = 3 ; x = 2 ;
variables:
 float v(z, y, x) ;
  v:missing_value = %s ;
data:
 v = 1, 2, -999, 4, 5, 6, 7, -999, 9, 10, 11, -1005 ;
}
""" % vals)
PY
ncgen -o "$W/m20.nc" "$W/m20.cdl" || fail "ncgen m20"
l=$("$ENC" -q -o "$W/m20" "$W/m20.nc" 2> "$W/m20.err")
[ "$(kv missing "$l")" = 3 ] && ok "missing_value of 20 values: 3 voxels missing" \
    || fail "missing_value of 20 values: $l $(cat "$W/m20.err")"
finish
