#!/bin/sh
# fuzz-replay: every fuzz harness of tests/fuzz/, built with replay.c by the
# normal compiler, over its seed corpus (tests/fuzz/corpus/NAME) and its
# reproducers (tests/fuzz/crashes/NAME): none may abort or crash.  In a
# sanitizer build (scripts/check-sanitize) the netcdf and hdf5 harnesses
# run with the suppressions scripts/fuzz uses for them (tests/fuzz/*.supp:
# leaks and faults inside libhdf5/libnetcdf on damaged files) and with
# allocations a damaged header asks for refused rather than fatal.
. "${TVPAL_SRCDIR:-.}/tests/lib.sh"
S=$TVPAL_SRCDIR/tests/fuzz
for name in manifest shard record dataset tf_text tf_paraview raw vti vti_set vtk \
            netcdf hdf5 checkpoint; do
    bin=$TVPAL_BUILDDIR/tests/fuzz/replay-$name
    if [ ! -x "$bin" ]; then fail "$bin not built"; continue; fi
    set --
    for d in "$S/corpus/$name" "$S/crashes/$name"; do
        [ -d "$d" ] && set -- "$@" "$d"
    done
    if [ $# = 0 ]; then fail "no corpus for $name"; continue; fi
    env=""
    case $name in netcdf | hdf5)
        env="ASAN_OPTIONS=${ASAN_OPTIONS:+$ASAN_OPTIONS:}allocator_may_return_null=1:suppressions=$S/asan.supp
             LSAN_OPTIONS=suppressions=$S/lsan.supp" ;;
    esac
    if env $env TMPDIR=$W "$bin" "$@" > "$W/out.txt" 2>&1; then
        ok "$(cat "$W/out.txt")"
    else
        fail "replay-$name exit $?:"; sed 's/^/    /' "$W/out.txt" >&2
    fi
done
finish
