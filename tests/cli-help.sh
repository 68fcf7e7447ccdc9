#!/bin/sh
# cli-help: every program answers --help and --version, rejects unknown
# options with exit 2, and has a man page that documents every option its
# --help lists.
. "$(dirname "$0")/lib.sh"
PLAY=$TVPAL_BUILDDIR/player/app/tvpal-play
for p in "$ENC" "$DEC" "$INFO" "$REP" "$GEN" $( [ -x "$PLAY" ] && echo "$PLAY" ); do
    n=$(basename "$p")
    "$p" --help > "$W/h.txt" 2>&1 && grep -q "^Usage: $n" "$W/h.txt" \
        && ok "$n --help" || fail "$n --help"
    "$p" --version | grep -q "^$n " && ok "$n --version" || fail "$n --version"
    expect_exit 2 "unrecognized|Try" "$p" --no-such-option
    man=$(ls "$TVPAL_SRCDIR"/*/"$n.1" "$TVPAL_SRCDIR"/*/*/"$n.1" 2>/dev/null | head -n 1)
    if [ -n "$man" ] && grep -q '^\.TH' "$man" && grep -q '^\.SH OPTIONS' "$man"; then
        ok "$n.1"
    else
        fail "$n: no man page with .TH and OPTIONS"
    fi
    missing=""
    for o in $(grep -o -- '--[a-z][a-z0-9-]*' "$W/h.txt" | sort -u); do
        grep -q -- "$(echo "$o" | sed 's/-/\\\\-/g')" "$man" 2>/dev/null || missing="$missing $o"
    done
    [ -z "$missing" ] && ok "$n.1 documents every --help option" || fail "$n.1 lacks:$missing"
done
finish
