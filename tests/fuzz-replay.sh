#!/bin/sh
# fuzz-replay: every fuzz harness of tests/fuzz/, built with replay.c by the
# normal compiler, over its seed corpus (tests/fuzz/corpus/NAME) and its
# reproducers (tests/fuzz/crashes/NAME): none may abort or crash.
. "${TVPAL_SRCDIR:-.}/tests/lib.sh"
S=$TVPAL_SRCDIR/tests/fuzz
for name in manifest shard record dataset tf_text tf_paraview raw vti vtk \
            netcdf hdf5; do
    bin=$TVPAL_BUILDDIR/tests/fuzz/replay-$name
    if [ ! -x "$bin" ]; then fail "$bin not built"; continue; fi
    set --
    for d in "$S/corpus/$name" "$S/crashes/$name"; do
        [ -d "$d" ] && set -- "$@" "$d"
    done
    if [ $# = 0 ]; then fail "no corpus for $name"; continue; fi
    if TMPDIR=$W "$bin" "$@" > "$W/out.txt" 2>&1; then
        ok "$(cat "$W/out.txt")"
    else
        fail "replay-$name exit $?:"; sed 's/^/    /' "$W/out.txt" >&2
    fi
done
finish
