#!/bin/sh
# input-files: the hostile simulation files of tests/files/inputs (see its
# README.md) are refused as its table says: tvpal-encode --force over a
# good dataset exits with the listed status and message naming the file,
# and leaves the good dataset byte for byte as it was, with no
# OUTDIR.partial or OUTDIR.old behind; without --force into a new OUTDIR,
# nothing is left.  NetCDF cases are CDL turned into files by ncgen (skipped
# out loud where netcdf-bin or the NetCDF reader is missing).
. "$(dirname "$0")/lib.sh"
F=$TVPAL_SRCDIR/tests/files/inputs
[ -f "$F/README.md" ] || { echo "no corpus at $F" >&2; exit 99; }
cp -R "$F" "$W/in" && chmod -R u+w "$W/in" || exit 99
"$GEN" --field blobs --dims 4x3x2 --steps 3 -o "$W/src" > /dev/null || fail gen
"$ENC" -q --dims 4x3x2 --window 2 -o "$W/keep" "$W"/src/*.f32 > /dev/null || fail "encode good"
sed -n '/^<!-- expect begin/,/^<!-- expect end/p' "$F/README.md" |
    grep -v '^<!--' | grep -v '^```' > "$W/expect.txt"
[ -s "$W/expect.txt" ] || fail "no expectation table in README.md"
for f in "$F"/bad-*; do
    grep -q "^$(basename "$f") " "$W/expect.txt" || fail "$(basename "$f") has no row in README.md"
done
netcdf=1
command -v ncgen > /dev/null 2>&1 || { echo "ncgen (netcdf-bin) not installed: the NetCDF cases are skipped"; netcdf=0; }
if [ $netcdf = 1 ] && ncgen -o "$W/probe.nc" "$W/in/bad-nc-z-nan.cdl" &&
   "$ENC" -q -o "$W/probe" "$W/probe.nc" 2>&1 | grep -q "built without NetCDF"; then
    echo "built without libnetcdf: the NetCDF cases are skipped"; netcdf=0
fi
while read -r file code pat; do
    in=$W/in/$file
    case $file in
    *.cdl)
        [ $netcdf = 1 ] || continue
        in=$W/in/${file%.cdl}.nc
        ncgen -o "$in" "$W/in/$file" || { fail "ncgen $file"; continue; } ;;
    esac
    rm -rf "$W/ds" "$W/ds.partial" "$W/ds.old" && cp -R "$W/keep" "$W/ds"
    expect_exit "$code" "$pat" "$ENC" -q -f -o "$W/ds" "$in"
    grep -q "$(basename "$in")" "$W/err.txt" || fail "$file: the message does not name the file"
    if diff -r "$W/keep" "$W/ds" > /dev/null && [ ! -e "$W/ds.partial" ] && [ ! -e "$W/ds.old" ]; then
        ok "$file: the dataset it was to replace is as it was"
    else
        fail "$file: the dataset it was to replace changed, or output was left"
    fi
    expect_exit "$code" "$pat" "$ENC" -q -o "$W/new" "$in"
    [ ! -e "$W/new" ] && [ ! -e "$W/new.partial" ] && ok "$file: nothing left" \
        || fail "$file: output left behind"
done < "$W/expect.txt"
finish
