#!/bin/sh
# layers: every include of the tree follows LAYERS.md (a folder includes
# only its own headers and those of the folders its rule names; external
# libraries only in their adapter files; file names unique), and the check
# itself fails on a planted violation of each kind.
. "$(dirname "$0")/lib.sh"

# check_tree ROOT: prints one line per violation; exit 0 when none.
check_tree() {
    root=$1
    rules=$(sed -n '/<!-- rules begin/,/<!-- rules end/p' "$root/LAYERS.md" | grep -v '^<!--\|^```')
    adapters=$(sed -n '/<!-- adapters begin/,/<!-- adapters end/p' "$root/LAYERS.md" | grep -v '^<!--\|^```')
    [ -n "$rules" ] && [ -n "$adapters" ] || { echo "LAYERS.md: no rules block"; return 1; }
    folders=$(echo "$rules" | awk '{print $1}')
    (cd "$root" && find $folders tests -maxdepth 1 -type f \( -name '*.c' -o -name '*.h' \)) \
        | sort > "$W/files"
    # file name -> folder; names must be unique
    awk -F/ '{n=$NF; d=$0; sub("/[^/]*$", "", d); print n, d}' "$W/files" | sort > "$W/names"
    awk '{print $1}' "$W/names" | uniq -d | sed 's/^/not unique: /'
    bad=0
    while read -r f; do
        dir=${f%/*}
        allowed=$(echo "$rules" | awk -v d="$dir" '$1 == d {$1 = ""; print}')
        # quoted includes: a file of the tree, in an allowed folder
        sed -n 's/^[ \t]*#[ \t]*include[ \t]*"\([^"]*\)".*/\1/p' "$root/$f" | while read -r h; do
            [ "$h" = config.h ] && continue
            hd=$(awk -v n="$h" '$1 == n {print $2}' "$W/names")
            if [ -z "$hd" ]; then
                echo "$f: includes \"$h\", which is not a file of the tree"
                continue
            fi
            [ "$hd" = "$dir" ] && continue
            [ "$dir" = tests ] && continue
            case " $allowed " in
            *" $hd "*) ;;
            *) echo "$f: includes $hd/$h; $dir may include only:${allowed:- nothing}" ;;
            esac
        done
        # angle includes of external libraries: only in their adapters
        sed -n 's/^[ \t]*#[ \t]*include[ \t]*<\([^>]*\)>.*/\1/p' "$root/$f" | while read -r h; do
            echo "$adapters" | while read -r pre who; do
                case "$h" in
                "$pre"*)
                    case " $who " in
                    *" $f "*) ;;
                    *) echo "$f: includes <$h>; only the adapter may (${who})" ;;
                    esac ;;
                esac
            done
        done
    done < "$W/files"
    # encoder/: tvpal-encode's modules include only those below them
    modules=$(sed -n '/<!-- modules begin/,/<!-- modules end/p' "$root/LAYERS.md" | grep -v '^<!--\|^```')
    grep '^encoder/[^/]*$' "$W/files" | while read -r f; do
        base=$(basename "$f"); base=${base%.*}
        mine=$(echo "$modules" | awk -v m="$base" '$1 == m {print NR}')
        sed -n 's/^[ \t]*#[ \t]*include[ \t]*"\([^"]*\)\.h".*/\1/p' "$root/$f" | while read -r h; do
            theirs=$(echo "$modules" | awk -v m="$h" '$1 == m {print NR}')
            [ -z "$theirs" ] && continue
            [ "$h" = "$base" ] && continue
            if [ -z "$mine" ]; then
                echo "$f: includes $h.h, a module of tvpal-encode (LAYERS.md)"
            elif [ "$theirs" -ge "$mine" ]; then
                echo "$f: includes $h.h, a module above $base (LAYERS.md: modules)"
            fi
        done
    done
}

out=$(check_tree "$TVPAL_SRCDIR")
cp "$W/files" "$W/tree" || exit 99
if [ -z "$out" ]; then
    ok "the tree follows LAYERS.md ($(wc -l < "$W/files") files)"
else
    fail "layering:"; echo "$out" | sed 's/^/    /' >&2
fi

# The check must catch each kind of violation: plant one in a copy.
plant() { # plant NAME FILE LINE: copy the tree, add LINE to FILE, expect PATTERN
    rm -rf "$W/t" && mkdir -p "$W/t" || exit 99
    (cd "$TVPAL_SRCDIR" && tar cf - LAYERS.md $(cat "$W/tree")) \
        | (cd "$W/t" && tar xf -) || exit 99
    [ -n "$3" ] && echo "$3" >> "$W/t/$2"
    [ -n "${5:-}" ] && cp "$W/t/$2" "$W/t/$5"
    got=$(check_tree "$W/t")
    if echo "$got" | grep -q -- "$4"; then ok "planted: $1"; else fail "planted $1 not caught: $got"; fi
}
plant "lower layer includes a higher one" common/base/tvpal_error.c '#include "tvpal_format.h"' 'may include only'
plant "encoder includes the player" encoder/tvpal-info.c '#include "tvpal_player.h"' 'may include only'
plant "player includes the encoder's codec" player/core/tvpal_view.c '#include "tvpal_dct.h"' 'may include only'
plant "mpi.h outside its adapter" player/app/tvpal-play.c '#include <mpi.h>' 'only the adapter'
plant "GL in the core" player/core/tvpal_player.c '#include <GL/gl.h>' 'only the adapter'
plant "liburing in a test" tests/test-sw.c '#include <liburing.h>' 'only the adapter'
plant "an unknown header" player/core/tvpal_tf.c '#include "tvpal_nope.h"' 'not a file of the tree'
plant "a module calls back up" encoder/encode_source.c '#include "encode_cluster.h"' 'a module above encode_source'
plant "another program uses tvpal-encode's modules" encoder/tvpal-info.c '#include "encode.h"' 'a module of tvpal-encode'
plant "a duplicate file name" common/base/tvpal_fs.h '' 'not unique' player/core/tvpal_fs.h
finish
