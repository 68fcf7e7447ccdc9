# lib.sh: helpers for the shell tests (sourced).  Exit codes follow automake:
# 0 pass, 77 skip, 99 hard error, anything else fail.
set -u
: "${TVPAL_BUILDDIR:=$(cd "$(dirname "$0")/.." && pwd)}"
: "${TVPAL_SRCDIR:=$TVPAL_BUILDDIR}"
ENC=$TVPAL_BUILDDIR/encoder/tvpal-encode
DEC=$TVPAL_BUILDDIR/encoder/tvpal-decode
INFO=$TVPAL_BUILDDIR/encoder/tvpal-info
REP=$TVPAL_BUILDDIR/encoder/tvpal-report
GEN=$TVPAL_BUILDDIR/samples/tvpal-gen
if [ -x /usr/bin/python3 ]; then PY=${PYTHON:-/usr/bin/python3}; else PY=${PYTHON:-python3}; fi
test_name=$(basename "$0" .sh)
W=$TVPAL_BUILDDIR/tests/work/$test_name
rm -rf "$W" && mkdir -p "$W" || exit 99
failures=0

# Open MPI on one machine: the shared-memory transport only.  Otherwise
# every rank probes UCX and the network in MPI_Init, a quarter of the time
# an mpirun of a few ranks takes here; no test depends on the transport.
# Settings the caller has made win.
export OMPI_MCA_pml="${OMPI_MCA_pml:-ob1}" OMPI_MCA_btl="${OMPI_MCA_btl:-self,vader}"

# third_party_leaks: called by a test that starts Open MPI or a window
# (GLFW and X11 under Xvfb).  Those libraries unload the plugins that
# allocated before LeakSanitizer runs at exit, so it can neither name nor
# suppress (tests/lsan.supp) what they keep.  In a sanitizer build
# (scripts/check-sanitize sets ASAN_OPTIONS) the test's processes run with
# leak checking off, AddressSanitizer and UBSan still on; elsewhere this
# changes nothing.
third_party_leaks() {
    [ -n "${ASAN_OPTIONS:-}" ] && export ASAN_OPTIONS="$ASAN_OPTIONS:detect_leaks=0"
    return 0
}

fail() { echo "FAIL: $*" >&2; failures=$((failures + 1)); }
ok() { echo "ok: $*"; }
finish() {
    if [ "$failures" -ne 0 ]; then
        echo "$test_name: $failures failure(s)" >&2
        exit 1
    fi
    rm -rf "$W"
    exit 0
}

# expect_exit CODE PATTERN CMD...: CMD must exit with CODE and print PATTERN
# (grep -E) on stderr, within TVPAL_EXPECT_TIMEOUT seconds (default 120):
# bad input gets a message and an exit, never a hang or a signal.
expect_exit() {
    local want=$1 pat=$2 rc
    shift 2
    timeout -k 5 "${TVPAL_EXPECT_TIMEOUT:-120}" "$@" > "$W/out.txt" 2> "$W/err.txt"
    rc=$?
    if [ "$rc" -eq 124 ] || [ "$rc" -eq 137 ]; then
        fail "hung (killed after ${TVPAL_EXPECT_TIMEOUT:-120} s): $*"
    elif [ "$rc" -ge 128 ]; then
        fail "died of signal $((rc - 128)) (expected exit $want): $*"; sed 's/^/    /' "$W/err.txt" >&2
    elif [ "$rc" -ne "$want" ]; then
        fail "exit $rc (expected $want): $*"; sed 's/^/    /' "$W/err.txt" >&2
    elif ! grep -Eq -- "$pat" "$W/err.txt"; then
        fail "stderr lacks /$pat/: $*"; sed 's/^/    /' "$W/err.txt" >&2
    else
        ok "exit $want /$pat/: $(basename "$1") ${2:-} ${3:-}"
    fi
}

# sweep_opts SWEEP: tvpal-play's options for a sweep of views written
# AX,AY/SPIN/A:B: --rotate AX,AY, then --spin SPIN degrees about the
# screen's y each frame, over steps A..B (a view per frame: one start of
# the player, or of mpirun, draws them all).
sweep_opts() { echo "$1" | awk -F/ '{ printf "--rotate %s --spin %s --steps %s", $1, $2, $3 }'; }

# pngdiff_dirs REF OUT: tests/pngdiff.py's line (max=M differing=S) for
# every frame of REF against OUT's frame of the same name, in one start
# of python.  Non-zero, with nothing printed, when REF has no frame, OUT
# lacks one or a comparison fails.
pngdiff_dirs() {
    local ref=$1 out=$2 f n=0 res
    set --
    for f in "$ref"/*.png; do
        [ -f "$f" ] && [ -f "$out/${f##*/}" ] || return 1
        set -- "$@" "$f" "$out/${f##*/}"
        n=$((n + 1))
    done
    res=$("$PY" "$TVPAL_SRCDIR/tests/pngdiff.py" "$@") || return 1
    [ "$(printf '%s\n' "$res" | grep -c '^max=')" -eq "$n" ] || return 1
    printf '%s\n' "$res"
}

# kv KEY LINE: value of key=value in LINE.
kv() { printf '%s\n' "$2" | tr ' ' '\n' | sed -n "s/^$1=//p"; }

# ge A B: A >= B (floats; "inf" is infinite).
ge() { awk -v a="$1" -v b="$2" 'BEGIN { if (a == "inf") exit 0; exit !(a + 0 >= b + 0) }'; }

# nan_exactly DATASET STEP DIMS "X,Y,Z ...": every axis of DATASET decodes
# STEP with NaN at exactly the listed voxels (DIMS = NXxNYxNZ; "" = none).
nan_exactly() {
    local a got want
    want=$(printf '%s\n' $4 | sort | tr '\n' ' ')
    for a in x y z; do
        "$DEC" "$1" --step "$2" --axis $a -o "$W/nan-$a.f32" 2> "$W/nan-err.txt" \
            || { fail "decode $1 step $2 axis $a: $(cat "$W/nan-err.txt")"; continue; }
        got=$("$PY" - "$W/nan-$a.f32" "$3" <<'PY'
import math, struct, sys
nx, ny, nz = map(int, sys.argv[2].lower().split("x"))
b = open(sys.argv[1], "rb").read()
v = struct.unpack("<%df" % (len(b) // 4), b)
assert len(v) == nx * ny * nz, "size"
for i, f in enumerate(v):
    if math.isnan(f):
        print("%d,%d,%d" % (i % nx, i // nx % ny, i // (nx * ny)))
PY
)
        got=$(printf '%s\n' $got | sort | tr '\n' ' ')
        [ "$got" = "$want" ] && ok "$(basename "$1") step $2 axis $a: NaN at ${want:-nowhere}" \
            || fail "$(basename "$1") step $2 axis $a: NaN at '$got', expected '$want'"
    done
}

# shards_same A B: datasets A and B have byte-identical shards of node 0,
# every axis (x, y, z); status 0 or 1.
shards_same() {
    for a in x y z; do
        cmp -s "$1/node-0/axis-$a.tvps" "$2/node-0/axis-$a.tvps" || return 1
    done
}

# same_shards NAME RAWDIR ENCDIR: ok or fail as shards_same says.
same_shards() {
    shards_same "$2" "$3" && ok "$1: shards identical to raw" || fail "$1: shards differ from raw"
}

# vec_enc NAME DIMS RAW... -- ENCODE-ARGS...: raw and --magnitude encodes
# (window 2, all axes), compared; the latter stays in $W/vm.
vec_enc() {
    name=$1 dims=$2; shift 2
    raws=""
    while [ "$1" != "--" ]; do raws="$raws $1"; shift; done
    shift
    rm -rf "$W/vr" "$W/vm"
    # shellcheck disable=SC2086
    "$ENC" --axes xyz -q --dims "$dims" --window 2 -o "$W/vr" $raws > /dev/null 2> "$W/e.txt" || { fail "$name raw: $(cat "$W/e.txt")"; return; }
    "$ENC" --axes xyz -q --window 2 -o "$W/vm" "$@" > "$W/vm.out" 2> "$W/e.txt" || { fail "$name: $(cat "$W/e.txt")"; return; }
    same_shards "$name" "$W/vr" "$W/vm"
}

# magnitude_read_back NAME: after vec_enc, $W/vm's source_var says
# "NAME (magnitude)" and tvpal-report, reading the sources back by it,
# finds the errors it finds against the raw lengths ($W/vr).
magnitude_read_back() {
    grep -qx "source_var = $1 (magnitude)" "$W/vm/manifest.txt" && ok "source_var = $1 (magnitude)" \
        || fail "source_var: $(grep source_var "$W/vm/manifest.txt")"
    l1=$("$REP" -q "$W/vr") && l2=$("$REP" -q "$W/vm") && [ "$(kv psnr "$l1")" = "$(kv psnr "$l2")" ] &&
        [ "$(kv max_abs_error "$l1")" = "$(kv max_abs_error "$l2")" ] \
        && ok "tvpal-report reads $1 (magnitude) back: psnr $(kv psnr "$l2")" || fail "report: $l1 / $l2"
}

# frame_rgb DS NAME SIZE TF OPTIONS...: tvpal-play's step 0 of $W/DS,
# SIZExSIZE, no annotations, transfer function TF, as $W/NAME.rgb (raw
# RGB, top row first) and its timing CSV $W/NAME.csv; status 1 (said) when
# it cannot.
frame_rgb() {
    local ds=$1 name=$2 size=$3 tf=$4
    shift 4
    "$PLAY" "$W/$ds" --headless -q --size ${size}x$size --steps 0:0 --annotate none --tf "$tf" \
        --csv "$W/$name.csv" "$@" -o "$W/$name" > /dev/null 2> "$W/$name.err" ||
        { fail "$name: $(cat "$W/$name.err")"; return 1; }
    ffmpeg -v error -y -i "$W/$name/t0000.png" -f rawvideo -pix_fmt rgb24 "$W/$name.rgb" ||
        { fail "$name: decode"; return 1; }
}

# install_lib: libtvpal, its headers and tvpal.pc installed into $W/root
# (make install-... DESTDIR), and pkg-config pointed at them only, as a
# user's program finds an installed library; sets pcdir and libdir.
install_lib() {
    make -s -C "$TVPAL_BUILDDIR" DESTDIR="$W/root" install-libLTLIBRARIES \
        install-includeHEADERS install-pkgconfigDATA > "$W/install.txt" 2>&1 ||
        { cat "$W/install.txt"; return 1; }
    pcdir=$(dirname "$(find "$W/root" -name tvpal.pc | head -n 1)")
    [ -f "$pcdir/tvpal.pc" ] || return 1
    export PKG_CONFIG_PATH="$pcdir" PKG_CONFIG_SYSROOT_DIR="$W/root"
    export PKG_CONFIG_LIBDIR="$pcdir"
    libdir=$(pkg-config --variable=libdir tvpal)
}

# levels_dataset DIMS STEPS LEVELS: turbulence from tvpal-gen, DIMS x
# STEPS, in $W/in (raw floats, kept), encoded with N = 4 and LEVELS
# levels of detail into $W/ds.
levels_dataset() {
    "$GEN" --field turbulence --dims "$1" --steps "$2" -o "$W/in" > /dev/null || fail gen
    "$ENC" -q --dims "$1" --window 4 --levels "$3" -o "$W/ds" "$W"/in/*.f32 > /dev/null || fail encode
}
