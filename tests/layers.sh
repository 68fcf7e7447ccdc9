#!/bin/sh
# layers: every include of the tree follows LAYERS.md (a folder includes
# only its own headers and those of the folders its rule names; external
# libraries only in their adapter files; file names unique), and the check
# itself fails on a planted violation of each kind.
. "$(dirname "$0")/lib.sh"

# check_tree ROOT: prints one line per violation; exit 0 when none.  One
# awk pass over LAYERS.md's three blocks, the file list and every file
# (it ran a few processes per include, and took minutes of CPU a suite).
check_tree() {
    root=$1
    sed -n '/<!-- rules begin/,/<!-- rules end/p' "$root/LAYERS.md" | grep -v '^<!--\|^```' > "$W/rules"
    sed -n '/<!-- adapters begin/,/<!-- adapters end/p' "$root/LAYERS.md" | grep -v '^<!--\|^```' > "$W/adapters"
    sed -n '/<!-- modules begin/,/<!-- modules end/p' "$root/LAYERS.md" | grep -v '^<!--\|^```' > "$W/modules"
    [ -s "$W/rules" ] && [ -s "$W/adapters" ] || { echo "LAYERS.md: no rules block"; return 1; }
    folders=$(awk '{print $1}' "$W/rules")
    (cd "$root" && find $folders tests -maxdepth 1 -type f \( -name '*.c' -o -name '*.h' \)) \
        | sort > "$W/files"
    (cd "$root" && awk -v RF="$W/rules" -v AF="$W/adapters" -v MF="$W/modules" \
                       -v LF="$W/files" -f - "$W/rules" "$W/adapters" "$W/modules" \
                       "$W/files" $(cat "$W/files")) <<'AWK'
# The folder of a path, and its name.
function dirname(p) { sub("/[^/]*$", "", p); return p }
function basename(p) { sub(".*/", "", p); return p }
FILENAME == RF { if (NF) { d = $1; $1 = ""; allowed[d] = $0 } next }
FILENAME == AF { if (NF) { na++; pre[na] = $1; w = $0; sub(/^[^ \t]+[ \t]+/, "", w); who[na] = w } next }
FILENAME == MF { if (NF) { nm++; module[$1] = nm } next }
FILENAME == LF {
    n = basename($0)
    if (n in dirof) dup[n] = 1
    dirof[n] = dirname($0)
    next
}
FNR == 1 {
    f = FILENAME; dir = dirname(f)
    base = basename(f); sub(/\.[^.]*$/, "", base)
    # encoder/'s own files are tvpal-encode's modules, in their order
    enc = f ~ /^encoder\/[^\/]*$/
    mine = (base in module) ? module[base] : 0
}
# quoted includes: a file of the tree, in an allowed folder
/^[ \t]*#[ \t]*include[ \t]*"[^"]*"/ {
    h = $0; sub(/^[^"]*"/, "", h); sub(/".*/, "", h)
    if (h != "config.h" && !(h in dup)) {   # a name twice: said at the end
        if (!(h in dirof))
            print f ": includes \"" h "\", which is not a file of the tree"
        else if (dirof[h] != dir && dir != "tests" &&
                 index(" " allowed[dir] " ", " " dirof[h] " ") == 0)
            print f ": includes " dirof[h] "/" h "; " dir " may include only:" \
                  (allowed[dir] == "" ? " nothing" : allowed[dir])
    }
    if (enc && h ~ /\.h$/) {
        m = h; sub(/\.h$/, "", m)
        if ((m in module) && m != base) {
            if (!mine)
                print f ": includes " m ".h, a module of tvpal-encode (LAYERS.md)"
            else if (module[m] >= mine)
                print f ": includes " m ".h, a module above " base " (LAYERS.md: modules)"
        }
    }
    next
}
# angle includes of external libraries: only in their adapters
/^[ \t]*#[ \t]*include[ \t]*<[^>]*>/ {
    h = $0; sub(/^[^<]*</, "", h); sub(/>.*/, "", h)
    for (i = 1; i <= na; i++)
        if (index(h, pre[i]) == 1 && index(" " who[i] " ", " " f " ") == 0)
            print f ": includes <" h ">; only the adapter may (" who[i] ")"
}
END { for (n in dup) print "not unique: " n }
AWK
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
