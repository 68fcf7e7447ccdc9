#!/bin/sh
# encode-memory: tvpal-encode under --mem-limit.  A limit too small for
# one slice per pass is refused up front (exit 2, naming the smallest that
# works, nothing written); a tiny limit (many passes over slabs of slices)
# gives output byte-identical to the unlimited encode, for N = 1, 4, 8,
# T < N, --nodes 2, a NetCDF input and missing values, with the measured
# peak resident memory (getrusage of the child) under the limit; an
# interrupted multi-pass encode resumes to the same bytes; progress lines
# come within a step.
. "$(dirname "$0")/lib.sh"
CHECK=$TVPAL_BUILDDIR/tests/tvpal-check
D=96x80x64
"$GEN" --field turbulence --dims $D --steps 9 -o "$W/in" > /dev/null || fail gen

# passes_of OUT: the passes= figure of a summary line
passes_of() { sed -n 's/.*passes=\([0-9]*\).*/\1/p' "$1"; }

# tight ARGS...: a limit in MiB a little over the smallest the encoder
# accepts for ARGS (from its refusal of 1M), well under one pass's ring
# (MARGIN MiB over, default 3).
tight() {
    m=$("$ENC" --axes xyz -j 1 --mem-limit 1M "$@" -o "$W/none" 2>&1 | sed -n 's/.*give --mem-limit \([0-9]*\)K.*/\1/p')
    echo "$((m + ${MARGIN:-3} * 1024))K"
}

# limited NAME ARGS...: encodes into $W/NAME under a tight limit, compares
# with the unlimited encode of the same ARGS, and checks the peak memory.
limited() {
    name=$1; shift
    lim=$(tight "$@")
    "$ENC" --axes xyz -q "$@" -o "$W/$name.ref" > /dev/null || { fail "$name: unlimited encode"; return; }
    "$CHECK" peakrss "$ENC" --axes xyz -j 1 --mem-limit "$lim" "$@" -o "$W/$name" \
        > "$W/$name.out" 2> "$W/$name.err" || { fail "$name: limited encode: $(cat "$W/$name.err")"; return; }
    p=$(passes_of "$W/$name.out")
    kb=$(sed -n 's/^maxrss_kb=//p' "$W/$name.err")
    limkb=${lim%K}
    diff -r "$W/$name.ref" "$W/$name" > /dev/null \
        && ok "$name: $p passes under $lim, output identical" \
        || fail "$name: output differs from the unlimited encode"
    [ "${p:-0}" -gt 3 ] || fail "$name: only ${p:-?} passes under $lim"
    if [ -n "${ASAN_OPTIONS:-}" ]; then
        # AddressSanitizer's shadow memory and quarantine are not the
        # encoder's: the plain build's run holds the limit.
        echo "note: $name: peak ${kb:-?} KiB not compared under AddressSanitizer"
    elif [ -n "$kb" ] && [ "$kb" -le "$limkb" ]; then
        ok "$name: peak ${kb} KiB <= $lim"
    else
        fail "$name: peak ${kb:-?} KiB over the limit $lim"
    fi
    grep -q "plan: .* passes (x [0-9]*, y [0-9]*, z [0-9]*), reading the input" "$W/$name.err" \
        || fail "$name: no plan line: $(cat "$W/$name.err")"
}

limited n4 --dims $D --window 4 "$W"/in/*.f32
limited n8 --dims $D --window 8 "$W"/in/*.f32
MARGIN=1 limited n1 --dims $D --window 1 "$W"/in/*.f32
limited short --dims $D --window 8 "$W"/in/turbulence_t000[0-2].f32
limited nodes --dims $D --window 4 --nodes 2 "$W"/in/*.f32
limited u16 --dims $D --window 4 --table u16 --refine 2 "$W"/in/*.f32
# Missing values: a value of the field marked missing.
v=$(od -An -tf4 -N4 -j 4000 "$W/in/turbulence_t0003.f32" | tr -d ' ')
limited missing --dims $D --window 4 --missing "$v" "$W"/in/*.f32
grep -q "^missing = [1-9]" "$W/missing/manifest.txt" || fail "missing: no missing values"

# A self-describing input (NetCDF, made by ncgen) read as boxes.
if command -v ncgen > /dev/null 2>&1; then
    {
        echo "netcdf box { dimensions: t = UNLIMITED ; z = 40 ; y = 48 ; x = 64 ;"
        echo "variables: float v(t, z, y, x) ; data: v ="
        awk 'BEGIN { n = 5 * 40 * 48 * 64; for (i = 0; i < n; i++)
            printf "%s%.4f", i ? ", " : "", sin(i * 0.37) * (i % 17) }'
        echo " ; }"
    } > "$W/box.cdl"
    ncgen -o "$W/box.nc" "$W/box.cdl" || fail ncgen
    "$ENC" --axes xyz -q --window 4 -o "$W/nc.ref" "$W/box.nc" > /dev/null || fail "nc ref"
    "$ENC" --axes xyz -q -j 1 --window 4 --mem-limit "$(MARGIN=1 tight --window 4 "$W/box.nc")" \
        -o "$W/nc" "$W/box.nc" > "$W/nc.out" || fail "nc limited"
    diff -r "$W/nc.ref" "$W/nc" > /dev/null && [ "$(passes_of "$W/nc.out")" -gt 3 ] \
        && ok "NetCDF: $(passes_of "$W/nc.out") passes, output identical" \
        || fail "NetCDF under a limit"
else
    echo "note: ncgen not installed: NetCDF box reads not tested"
fi

# --dry-run: the plan of a 2048^3 series (sparse files), nothing written.
for k in 0 1 2 3; do truncate -s $((2048 * 2048 * 2048 * 4)) "$W/sparse$k.f32"; done
"$ENC" --axes xyz --dry-run -j 2 --mem-limit 16G --dims 2048x2048x2048 --window 4 -o "$W/big" \
    "$W"/sparse?.f32 > "$W/plan.out" 2> "$W/plan.err" || fail "dry run: $(cat "$W/plan.err")"
grep -q "^plan .*: passes=[0-9]* passes_x=[0-9]* .*read_factor=" "$W/plan.out" \
    && [ ! -e "$W/big" ] && [ ! -e "$W/big.partial" ] \
    && ok "--dry-run plans 2048^3: $(sed 's/^plan [^:]*: //' "$W/plan.out")" \
    || fail "dry run: $(cat "$W/plan.out" "$W/plan.err")"
rm -f "$W"/sparse?.f32

# Too small: refused before anything is read or written.
expect_exit 2 "too small .* give --mem-limit [0-9]*K or more" \
    "$ENC" --axes xyz -j 1 --mem-limit 1M --dims $D -o "$W/tiny" "$W"/in/*.f32
[ ! -e "$W/tiny" ] && [ ! -e "$W/tiny.partial" ] && ok "nothing written when refused" \
    || fail "refused encode left output"
expect_exit 2 "mem-limit" "$ENC" --axes xyz --mem-limit 12Q --dims $D -o "$W/bad" "$W"/in/*.f32

# Interrupted in the middle of a later pass, then resumed.
L4=$(tight --dims $D --window 4 "$W"/in/*.f32)
TVPAL_ENCODE_FAULT_AFTER=30 "$ENC" --axes xyz -q -j 1 --mem-limit $L4 --dims $D --window 4 \
    -o "$W/res" "$W"/in/*.f32 > /dev/null 2>&1
[ -d "$W/res.partial" ] && [ ! -e "$W/res" ] || fail "interrupted pass left $(ls -d "$W"/res*)"
"$ENC" --axes xyz -j 1 --mem-limit $L4 --dims $D --window 4 -o "$W/res" "$W"/in/*.f32 \
    > /dev/null 2> "$W/res.err" || fail "resume: $(cat "$W/res.err")"
grep -q "resuming .* at pass [2-9]" "$W/res.err" && diff -r "$W/n4.ref" "$W/res" > /dev/null \
    && ok "interrupted multi-pass encode resumed to the same bytes" \
    || fail "multi-pass resume: $(cat "$W/res.err")"
# Another limit is another plan: the partial output is started over.
TVPAL_ENCODE_FAULT_AFTER=15 "$ENC" --axes xyz -q -j 1 --mem-limit $L4 --dims $D --window 4 \
    -o "$W/res2" "$W"/in/*.f32 > /dev/null 2>&1
"$ENC" --axes xyz -j 1 --dims $D --window 4 -o "$W/res2" "$W"/in/*.f32 > /dev/null 2> "$W/res2.err" \
    && ! grep -q resuming "$W/res2.err" && diff -r "$W/n4.ref" "$W/res2" > /dev/null \
    && ok "a partial output of another plan is started over" \
    || fail "plan change: $(cat "$W/res2.err")"

# The default limit heeds the process's own address-space limit (ulimit
# -v): it planned for the machine and ran out of memory halfway.  The
# encoder's own address space is found from a dry run under a large limit,
# then the job runs with 32 MiB more than that (3/4 of it, 24 MiB, is
# over the 19.6 MiB one slice per pass needs and under the 27 MiB of one
# pass; the dry run says the space left to the MiB): it plans passes, finishes,
# and the dataset is byte-identical.  Not under AddressSanitizer (its
# shadow memory takes terabytes of address space).
if [ -n "${ASAN_OPTIONS:-}" ]; then
    echo "note: the ulimit -v case is not run under AddressSanitizer"
else
    big=$((8 << 20))   # KiB
    left=$( (ulimit -v $big && "$ENC" --axes xyz -j 1 --dry-run --dims $D --window 4 -o "$W/ul" "$W"/in/*.f32 2>&1) |
        sed -n 's/.*address space left under ulimit -v (\([0-9.]*\) GiB).*/\1/p' | head -n 1)
    if [ -z "$left" ]; then
        fail "dry run under ulimit -v: no limit from the address space"
    else
        held=$(awk -v b=$big -v l="$left" 'BEGIN { printf "%d", b - l * 1048576 }')
        (ulimit -v $((held + 32 * 1024)) && "$ENC" --axes xyz -j 1 --dims $D --window 4 -o "$W/ul" "$W"/in/*.f32) \
            > /dev/null 2> "$W/ul.err"
        rc=$?
        if [ $rc -eq 0 ] && grep -q "under ulimit -v" "$W/ul.err" && grep -q "passes" "$W/ul.err" &&
           diff -r "$W/n4.ref" "$W/ul" > /dev/null; then
            ok "under ulimit -v ($((held / 1024)) MiB held + 32): $(grep -o '[0-9]* passes' "$W/ul.err" | head -n 1), byte-identical"
        else
            fail "under ulimit -v: exit $rc: $(grep -v '%' "$W/ul.err" | head -n 5)"
        fi
    fi
fi

# Progress within a step: one step of one window, lines every 10 ms.
TVPAL_PROGRESS_INTERVAL=0.01 "$ENC" --axes xyz -j 1 --dims $D --window 1 -o "$W/prog" \
    "$W/in/turbulence_t0000.f32" > /dev/null 2> "$W/prog.err" || fail "progress encode"
n=$(grep -c " 0/1 steps .* Mvox-steps/s" "$W/prog.err")
[ "$n" -ge 1 ] && grep -q "100%  1/1 steps" "$W/prog.err" \
    && ok "$n progress lines within the only step" \
    || fail "no progress within a step: $(cat "$W/prog.err")"
finish
