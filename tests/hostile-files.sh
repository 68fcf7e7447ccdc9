#!/bin/sh
# hostile-files: inputs that are not regular files are refused at once
# (exit 2, a message naming the file), never read forever or waited on: a
# FIFO and a character device like /dev/zero (both made in the test's own
# directory) as a transfer function, a --times list, a manifest, a raw
# input and a tvpal-report reference; a text input beyond 64 MiB is
# refused; the device node is left as it was.  timing.csv has one row per
# frame drawn even when tvpal-play is killed.  Outputs: every program writes
# through one routine (a unique temporary renamed over the target), so a
# device node, FIFO or symbolic link at the target is refused and left as
# it was, a link planted at a predictable temporary name redirects
# nothing, and tvpal-decode and tvpal-report refuse to write inside the
# dataset they read.  Files named inside others (a .pvd's DataSets, a
# .pvti's pieces, the files of a series after the first) are checked as
# top-level inputs are.  A .vti that shrinks while it is read (truncated by
# tests/fault.so at a set byte, and in a race with truncate) gets a message
# naming it, never SIGBUS.  An encode that fails after writing (the new
# dataset or a level does not read back, the rename into place fails: made
# to fail by tests/fault.so) leaves the dataset it was to replace as it was.
# One encode at a time writes an OUTDIR.partial (a lock file beside it).
. "$(dirname "$0")/lib.sh"
PLAY=$TVPAL_BUILDDIR/player/app/tvpal-play
D=8x6x5
"$GEN" --field blobs --dims $D --steps 4 -o "$W/in" > /dev/null || fail gen
"$ENC" -q --dims $D --window 2 -o "$W/ds" "$W"/in/*.f32 > /dev/null || fail encode
mkfifo "$W/fifo" || { echo "no mkfifo"; exit 99; }
nodes="$W/fifo"
if mknod "$W/zero" c 1 5 2> /dev/null; then nodes="$nodes $W/zero"; else
    echo "mknod not permitted (not root): the character-device cases are skipped"; fi
T="timeout 20"
for n in $nodes; do
    what=$(basename "$n")
    if [ -x "$PLAY" ]; then
        expect_exit 2 "$what: cannot read: not a regular file" $T "$PLAY" "$W/ds" --headless --tf "$n"
    fi
    expect_exit 2 "$what: not a regular file" $T "$ENC" -q --dims $D --times "$n" -o "$W/o" "$W"/in/*.f32
    expect_exit 2 "$what" $T "$ENC" -q --dims $D -o "$W/o" "$W/in/blobs_t0000.f32" "$n"
    expect_exit 2 "$what: cannot read input: not a regular file" $T "$ENC" -q -o "$W/o" "$n"
    expect_exit 2 "$what: not a regular file" $T "$REP" -q "$W/ds" --reference "$W"/in/blobs_t000[012].f32 "$n"
    rm -rf "$W/dsm" && cp -r "$W/ds" "$W/dsm" && rm "$W/dsm/manifest.txt" && ln -s "$n" "$W/dsm/manifest.txt"
    expect_exit 2 "not a regular file" $T "$INFO" "$W/dsm"
    expect_exit 2 "not a regular file" $T "$DEC" "$W/dsm" --step 0 -o "$W/x.f32"
done
[ -c "$W/zero" ] || [ ! -e "$W/zero" ] && ok "device node untouched" || fail "device node replaced"
[ -p "$W/fifo" ] && ok "FIFO untouched" || fail "FIFO replaced"
# A reference cut short: a clear error (under scripts/check-sanitize, with
# LeakSanitizer on, nothing leaked on that path).
head -c 100 "$W/in/blobs_t0001.f32" > "$W/short.f32"
expect_exit 2 "short.f32: timestep 1: file is shorter than expected" \
    $T "$REP" -q "$W/ds" --reference "$W/in/blobs_t0000.f32" "$W/short.f32" "$W"/in/blobs_t000[23].f32
# A text input beyond 64 MiB (sparse).
truncate -s 65M "$W/big.tf"
if [ -x "$PLAY" ]; then
    expect_exit 2 "big.tf: cannot read: 68157440 bytes; a text input is at most 64 MiB" $T "$PLAY" "$W/ds" --headless --tf "$W/big.tf"
fi
expect_exit 2 "big.tf: 68157440 bytes" $T "$ENC" -q --dims $D --times "$W/big.tf" -o "$W/o" "$W"/in/*.f32
[ ! -e "$W/o" ] && [ ! -e "$W/o.partial" ] && ok "nothing left behind" || fail "output left behind"
# Outputs.
echo victim > "$W/victim"
if [ -c "$W/zero" ] && mknod "$W/null" c 1 3 2> /dev/null; then
    expect_exit 2 "null: exists and is not a regular file \(a character device\)" \
        $T "$DEC" "$W/ds" --step 0 -o "$W/null"
    [ -c "$W/null" ] && ok "decode: device node left alone" || fail "decode replaced the device node"
    expect_exit 1 "null: exists and is not a regular file" $T "$REP" -q "$W/ds" --csv "$W/null"
    expect_exit 1 "null: exists and is not a regular file" $T "$GEN" --field blobs --dims $D --steps 2 --single "$W/null"
    [ -c "$W/null" ] && ok "report, gen: device node left alone" || fail "device node replaced"
fi
expect_exit 2 "fifo: exists and is not a regular file \(a FIFO\)" $T "$DEC" "$W/ds" --step 0 -o "$W/fifo"
ln -s "$W/victim" "$W/link.f32"
expect_exit 2 "link.f32: exists and is not a regular file \(a symbolic link\)" $T "$DEC" "$W/ds" --step 0 -o "$W/link.f32"
ln -s "$W/victim" "$W/out.f32.tmp"
$T "$DEC" "$W/ds" --step 0 -o "$W/out.f32" 2> "$W/e.txt" && [ "$(stat -c %s "$W/out.f32")" = 960 ] \
    && ok "a link planted at OUT.tmp redirects nothing" || fail "decode with a planted OUT.tmp: $(cat "$W/e.txt")"
[ "$(cat "$W/victim")" = victim ] && ok "the link's target is untouched" || fail "victim overwritten"
ls "$W" | grep -q '^out\.f32\.......$' && fail "temporary left behind" || ok "no temporary left"
expect_exit 2 "inside the dataset" $T "$DEC" "$W/ds" --step 0 -o "$W/ds/manifest.txt"
expect_exit 2 "inside the dataset" $T "$DEC" "$W/ds" --step 0 -o "$W/ds/node-0/axis-z.tvps"
expect_exit 1 "inside the dataset" $T "$REP" -q "$W/ds" --csv "$W/ds/node-0/axis-x.tvps"
"$INFO" "$W/ds" --verify > /dev/null 2>&1 && ok "the dataset is intact" || fail "the dataset was damaged"
if [ -x "$PLAY" ]; then
    mkdir -p "$W/frames" && mkfifo "$W/frames/timing.csv"
    expect_exit 2 "timing.csv: exists and is not a regular file \(a FIFO\)" \
        $T "$PLAY" "$W/ds" --headless -q --size 16x16 -o "$W/frames"
    rm -f "$W/frames/timing.csv" && ln -s "$W/victim" "$W/frames/t0000.png"
    $T "$PLAY" "$W/ds" --headless -q --size 16x16 -o "$W/frames" > /dev/null 2> "$W/e.txt"
    grep -q "t0000.png: exists and is not a regular file (a symbolic link)" "$W/e.txt" \
        && [ "$(cat "$W/victim")" = victim ] && ok "play: a link at a frame's name is refused" \
        || fail "play frame link: $(cat "$W/e.txt")"
fi
# Files named inside others go through the same checks as a top-level
# input: a FIFO as a .pvd's DataSet or a .pvti's piece is refused at once
# (it blocked the encoder for ever).
vti_file() {   # PATH NX NY NZ: a float32 .vti with raw appended data
    "$PY" - "$@" <<'PY'
import struct, sys
p, nx, ny, nz = sys.argv[1], *map(int, sys.argv[2:])
n = nx * ny * nz
head = ('<?xml version="1.0"?>\n<VTKFile type="ImageData" version="1.0" '
        'byte_order="LittleEndian" header_type="UInt64">\n'
        '<ImageData WholeExtent="0 %d 0 %d 0 %d" Origin="0 0 0" Spacing="1 1 1">\n'
        '<Piece Extent="0 %d 0 %d 0 %d"><PointData Scalars="v">'
        '<DataArray type="Float32" Name="v" format="appended" offset="0"/>'
        '</PointData></Piece></ImageData>\n<AppendedData encoding="raw">\n_'
        % (nx - 1, ny - 1, nz - 1, nx - 1, ny - 1, nz - 1))
with open(p, "wb") as f:
    f.write(head.encode())
    f.write(struct.pack("<Q", 4 * n))
    row = struct.pack("<%df" % nx, *[float(i % 7) for i in range(nx)])
    f.write(row * (ny * nz))
    f.write(b"\n</AppendedData>\n</VTKFile>\n")
PY
}
mkdir -p "$W/coll" && vti_file "$W/coll/a.vti" 4 3 2 && mkfifo "$W/coll/f.vti" || fail "collection files"
cat > "$W/coll/s.pvd" <<'XML'
<?xml version="1.0"?>
<VTKFile type="Collection" version="0.1"><Collection>
<DataSet timestep="0" file="a.vti"/><DataSet timestep="1" file="f.vti"/>
</Collection></VTKFile>
XML
cat > "$W/coll/p.pvti" <<'XML'
<?xml version="1.0"?>
<VTKFile type="PImageData" version="1.0" byte_order="LittleEndian">
<PImageData WholeExtent="0 3 0 2 0 1" Origin="0 0 0" Spacing="1 1 1">
<PPointData Scalars="v"><PDataArray type="Float32" Name="v"/></PPointData>
<Piece Extent="0 3 0 2 0 1" Source="f.vti"/></PImageData></VTKFile>
XML
expect_exit 2 "s.pvd: its DataSet .*f.vti: not a regular file \(a FIFO\)" $T "$ENC" -q -o "$W/o" "$W/coll/s.pvd"
expect_exit 2 "f.vti: not a regular file \(a FIFO\).*a piece of .*p.pvti" $T "$ENC" -q -o "$W/o" "$W/coll/p.pvti"
expect_exit 2 "f.vti: not a regular file \(a FIFO\)" $T "$ENC" -q -o "$W/o" "$W/coll/a.vti" "$W/coll/f.vti"
# Collections that list themselves or each other are refused by name,
# never followed (tvpal-info --inspect overflowed its stack).
printf '<?xml version="1.0"?>\n<VTKFile type="Collection" version="0.1"><Collection>\n<DataSet timestep="0" file="%s"/>\n</Collection></VTKFile>\n' self.pvd > "$W/coll/self.pvd"
printf '<?xml version="1.0"?>\n<VTKFile type="Collection" version="0.1"><Collection>\n<DataSet timestep="0" file="%s"/>\n</Collection></VTKFile>\n' m2.pvd > "$W/coll/m1.pvd"
printf '<?xml version="1.0"?>\n<VTKFile type="Collection" version="0.1"><Collection>\n<DataSet timestep="0" file="%s"/>\n</Collection></VTKFile>\n' m1.pvd > "$W/coll/m2.pvd"
for c in self m1; do
    expect_exit 2 "a \.pvd collection .* where an ImageData file was expected \(listed in .*$c\.pvd\)" \
        $T "$INFO" --inspect "$W/coll/$c.pvd"
    expect_exit 2 "where an ImageData file was expected" $T "$ENC" -q -o "$W/o" "$W/coll/$c.pvd"
done
# A file of another format in a series is named (a legacy .vtk after a
# .vti was parsed as XML: "not well-formed"); an input file given where a
# dataset is expected is called a file, once (the path came twice).
printf '# vtk DataFile Version 3.0\nx\nASCII\nDATASET STRUCTURED_POINTS\nDIMENSIONS 4 3 2\nORIGIN 0 0 0\nSPACING 1 1 1\nPOINT_DATA 24\nSCALARS v float 1\nLOOKUP_TABLE default\n%s\n' "$(seq -s ' ' 1 24)" > "$W/coll/b.vtk"
expect_exit 2 "b\.vtk: a vtk file in a series of vti files \(.*a\.vti is one\)" $T "$ENC" -q -o "$W/o" "$W/coll/a.vti" "$W/coll/b.vtk"
for cmd in "$INFO" "$DEC --step 0 -o $W/x.f32"; do
    set -- $cmd
    prog=$1; shift
    expect_exit 2 "a\.vti: a file, not a dataset directory \(an input file\? tvpal-info --inspect" \
        $T "$prog" "$W/coll/a.vti" "$@"
    grep -q "manifest.txt" "$W/err.txt" && fail "$(basename "$prog"): names manifest.txt of a file" \
        || ok "$(basename "$prog"): a file given as a dataset, said once"
done
[ ! -e "$W/o" ] && [ ! -e "$W/o.partial" ] && ok "collections: nothing left behind" || fail "output left behind"

# A file that shrinks while the encoder reads it (a simulation rewriting
# its output, a copy in progress): a message naming it and exit 2, never
# SIGBUS.  Deterministic first, with tests/fault.so truncating the file
# at the data's first read past its middle; then as a race, truncated by
# another process while it is read.
SHIM=$TVPAL_BUILDDIR/tests/fault.so
# env LD_PRELOAD=... (ASan: its runtime is then not first, which it allows)
ASAN_SHIM="${ASAN_OPTIONS:+$ASAN_OPTIONS:}verify_asan_link_order=0"
vti_file "$W/big.vti" 128 128 64 || fail "big vti"
if [ -f "$SHIM" ]; then
    env LD_PRELOAD="$SHIM" ASAN_OPTIONS="$ASAN_SHIM" TVPAL_FAULT=shrink:big.vti TVPAL_SHRINK_AT=2000000 \
        $T "$ENC" -q -o "$W/o" "$W/big.vti" > "$W/out.txt" 2> "$W/err.txt"
    rc=$?
    [ $rc -eq 2 ] && grep -q "big.vti: its data: the file ends at byte 2000000, before byte .*: it shrank while being read" "$W/err.txt" \
        && [ ! -e "$W/o" ] && ok "a .vti that shrinks as it is read: exit 2, named" \
        || { fail "shrinking .vti: exit $rc"; sed 's/^/    /' "$W/err.txt" >&2; }
else
    fail "tests/fault.so not built"
fi
for i in 1 2 3 4 5; do
    vti_file "$W/race.vti" 128 128 128 || fail "race vti"
    rm -rf "$W/o" "$W/o.partial"
    "$ENC" -q -o "$W/o" "$W/race.vti" > /dev/null 2> "$W/err.txt" &
    pid=$!
    sleep "0.0$((2 * i))"
    truncate -s 1000 "$W/race.vti"
    wait $pid
    rc=$?
    if [ $rc -ge 128 ]; then
        fail "truncated while read (round $i): died of signal $((rc - 128))"
    elif [ $rc -ne 0 ] && ! grep -q "race.vti" "$W/err.txt"; then
        fail "truncated while read (round $i): exit $rc without naming the file: $(cat "$W/err.txt")"
    else
        ok "truncated while read (round $i): exit $rc: $(head -c 160 "$W/err.txt")"
    fi
done

# An encode that fails after it has written leaves the dataset it was to
# replace (--force) as it was: the new dataset does not read back (its
# manifest cannot be opened), a level does not, or the rename into place
# fails (the old one is put back).  tests/fault.so makes the call fail.
if [ -f "$SHIM" ]; then
    rm -rf "$W/keep" && cp -R "$W/ds" "$W/keep"
    expect_exit 1 "written dataset does not verify: .*the existing dataset is left as it was" \
        env LD_PRELOAD="$SHIM" ASAN_OPTIONS="$ASAN_SHIM" TVPAL_FAULT=open:ds.partial/manifest.txt $T "$ENC" -q -f --dims $D --window 2 -o "$W/ds" "$W"/in/*.f32
    diff -r "$W/keep" "$W/ds" > /dev/null && [ ! -e "$W/ds.old" ] \
        && ok "unverified: the old dataset is as it was" || fail "unverified: the old dataset changed"
    expect_exit 1 "does not verify|level 1" \
        env LD_PRELOAD="$SHIM" ASAN_OPTIONS="$ASAN_SHIM" TVPAL_FAULT=open:level-1/manifest.txt $T "$ENC" -q -f --levels 1 --dims $D --window 2 -o "$W/ds" "$W"/in/*.f32
    diff -r "$W/keep" "$W/ds" > /dev/null && ok "a level unverified: the old dataset is as it was" \
        || fail "a level unverified: the old dataset changed"
    expect_exit 1 "ds: cannot replace \(left as it was\)" \
        env LD_PRELOAD="$SHIM" ASAN_OPTIONS="$ASAN_SHIM" TVPAL_FAULT=rename:ds.partial $T "$ENC" -q -f --dims $D --window 2 -o "$W/ds" "$W"/in/*.f32
    diff -r "$W/keep" "$W/ds" > /dev/null && [ ! -e "$W/ds.old" ] \
        && ok "rename failed: the old dataset is back" || fail "rename failed: the old dataset changed or is gone"
    "$INFO" "$W/ds" --verify > /dev/null 2>&1 && ok "the dataset still verifies" || fail "the dataset does not verify"
fi

# One job at a time writes OUTDIR.partial: a lock held (here by flock(1))
# stops a second encode at once, saying so; two encodes of one OUTDIR
# started together leave one good dataset (before, their shards mixed
# into one that did not verify), the other saying why it stopped.
if command -v flock > /dev/null; then
    flock "$W/lk.partial.lock" sleep 30 &
    fpid=$!
    sleep 0.5
    expect_exit 1 "lk\.partial: another encode is writing it \(its lock .*lk\.partial\.lock: held by another process\)" \
        $T "$ENC" -q --dims $D --window 2 -o "$W/lk" "$W"/in/*.f32
    kill $fpid 2> /dev/null; wait $fpid 2> /dev/null
    [ ! -e "$W/lk" ] && [ ! -e "$W/lk.partial" ] && ok "locked out: nothing written" \
        || fail "locked out: output written"
else
    echo "no flock(1) (util-linux): the held-lock case is skipped"
fi
"$GEN" --field turbulence --dims 48x48x48 --steps 24 -o "$W/tw" > /dev/null || fail "gen tw"
"$ENC" -q --dims 48x48x48 -o "$W/two" "$W"/tw/*.f32 > "$W/two1.txt" 2>&1 &
p1=$!
"$ENC" -q --dims 48x48x48 -o "$W/two" "$W"/tw/*.f32 > "$W/two2.txt" 2>&1 &
p2=$!
wait $p1; r1=$?
wait $p2; r2=$?
if [ $((r1 == 0)) -ne $((r2 == 0)) ] && "$INFO" "$W/two" --verify > /dev/null 2>&1 &&
   grep -Eq "another encode is writing it|already exists" "$W/two1.txt" "$W/two2.txt"; then
    ok "two encodes of one OUTDIR: one dataset that verifies (exits $r1, $r2), the other said why"
else
    fail "two encodes of one OUTDIR: exits $r1 and $r2: $(cat "$W/two1.txt" "$W/two2.txt")"
fi
[ ! -e "$W/two.partial" ] && [ ! -e "$W/two.partial.lock" ] && ok "no partial output or lock left" \
    || fail "left: $(ls -d "$W"/two.* 2> /dev/null)"

# timing.csv as the frames go: kill tvpal-play after some frames.
if [ -x "$PLAY" ]; then
    "$GEN" --field blobs --dims 32x32x32 --steps 400 -o "$W/long" > /dev/null || fail "gen long"
    "$ENC" -q --dims 32x32x32 --window 4 -o "$W/dl" "$W"/long/*.f32 > /dev/null || fail "encode long"
    "$PLAY" "$W/dl" --headless -q --size 64x64 --repeat 20 -o "$W/fr" > /dev/null 2>&1 &
    pid=$!
    i=0
    while [ $i -lt 100 ] && [ "$(ls "$W/fr" 2> /dev/null | grep -c png)" -lt 3 ]; do sleep 0.1; i=$((i + 1)); done
    kill -9 $pid 2> /dev/null
    wait $pid 2> /dev/null
    frames=$(ls "$W/fr" | grep -c png)
    rows=$(($(wc -l < "$W/fr/timing.csv") - 1))
    [ "$frames" -ge 3 ] && [ "$rows" -ge $((frames - 1)) ] && [ "$rows" -le "$frames" ] \
        && ok "killed after $frames frames: timing.csv has $rows rows" \
        || fail "killed after $frames frames: timing.csv has $rows rows"
fi
finish
