#!/bin/sh
# files: today's readers against the committed corpus tests/files/ (see its
# README.md): every good-* dataset verifies and decodes, step by step and
# axis by axis, to the SHA-256 in SHA256SUMS; good-manifest-variants.txt
# decodes as good-1-basic; every bad-* file, planted in a copy of
# good-1-basic (bad-u16-*: of good-2-u16-nodes, bad-auto-*: of good-5-auto,
# bad-group-*: of good-9-group,
# bad-coded-t2-*: of good-7-coded-t2, other bad-coded-*: of good-6-coded),
# is refused by tvpal-info --verify and tvpal-decode with the exit code and
# the message that the README's table gives.
. "$(dirname "$0")/lib.sh"
F=$TVPAL_SRCDIR/tests/files
[ -f "$F/SHA256SUMS" ] || { echo "no corpus at $F" >&2; exit 99; }
sha() {
    if command -v sha256sum > /dev/null 2>&1; then sha256sum | cut -d' ' -f1
    else $PY -c 'import hashlib, sys; print(hashlib.sha256(sys.stdin.buffer.read()).hexdigest())'
    fi
}
# copy DATASET DEST: a writable copy (the source tree is read-only under
# distcheck).
copy() { rm -rf "$2" && cp -R "$1" "$2" && chmod -R u+w "$2"; }
# sums DIR NAME: one "HASH  NAME/A/T" line per stored axis and step of DIR
# (the manifest's axes key, FORMAT.md 2.2; all three without it).
sums() {
    steps=$(sed -n 's/^steps = //p' "$F/$2/manifest.txt")
    axes=$(sed -n 's/^axes = //p' "$F/$2/manifest.txt" | sed 's/[^xyz]//g; s/./& /g')
    for a in ${axes:-x y z}; do
        t=0
        while [ "$t" -lt "$steps" ]; do
            h=$("$DEC" "$1" --step $t --axis $a -o - | sha) || h=decode-failed
            echo "$h  $2/$a/$t"
            t=$((t + 1))
        done
    done
}
# good DIR NAME: DIR verifies and decodes to NAME's lines of SHA256SUMS,
# and refuses to decode an axis it does not store.
good() {
    axes=$(sed -n 's/^axes = //p' "$F/$2/manifest.txt" | sed 's/[^xyz]//g; s/./& /g')
    if "$INFO" "$1" --verify > "$W/v.txt" 2>&1 && grep -q "^verify: ok" "$W/v.txt"; then
        ok "$3 verifies"
    else
        fail "$3 does not verify:"; sed 's/^/    /' "$W/v.txt" >&2
    fi
    # An axis the dataset does not store is refused, naming what it has.
    for a in x y z; do
        case " ${axes:-x y z} " in *" $a "*) continue ;; esac
        expect_exit 2 "--axis $a: .* stores axes [xyz]+ only" "$DEC" "$1" --step 0 --axis $a -o -
    done
    sums "$1" "$2" > "$W/got.txt"
    grep "  $2/" "$F/SHA256SUMS" > "$W/want.txt"
    n=$(wc -l < "$W/want.txt")
    if [ "$n" -gt 0 ] && cmp -s "$W/want.txt" "$W/got.txt"; then
        ok "$3 decodes to SHA256SUMS ($n volumes)"
    else
        fail "$3 decodes differently:"; diff "$W/want.txt" "$W/got.txt" >&2
    fi
}
for d in "$F"/good-*/; do
    name=$(basename "$d")
    copy "$d" "$W/$name"
    good "$W/$name" "$name" "$name"
done
copy "$F/good-1-basic" "$W/ds"
cp "$F/good-manifest-variants.txt" "$W/ds/manifest.txt"
good "$W/ds" good-1-basic "good-manifest-variants.txt"

# The README's table: file, verify exit, decode step, decode exit, pattern.
sed -n '/^<!-- expect begin/,/^<!-- expect end/p' "$F/README.md" |
    grep -v '^<!--' | grep -v '^```' > "$W/expect.txt"
[ -s "$W/expect.txt" ] || fail "no expectation table in README.md"
for f in "$F"/bad-*; do
    b=$(basename "$f")
    grep -q "^$b " "$W/expect.txt" || fail "$b has no row in README.md"
done
while read -r file vrc step drc pat; do
    [ -f "$F/$file" ] || { fail "$file: listed in README.md, not in the corpus"; continue; }
    case $file in
    bad-u16-*) base=good-2-u16-nodes ;;
    bad-auto-*) base=good-5-auto ;;
    bad-group-*) base=good-9-group ;;
    bad-coded-t2-*) base=good-7-coded-t2 ;;
    bad-coded-*) base=good-6-coded ;;
    *) base=good-1-basic ;;
    esac
    copy "$F/$base" "$W/ds"
    case $file in
    *.tvps) cp "$F/$file" "$W/ds/node-0/axis-z.tvps" ;;
    *.txt) cp "$F/$file" "$W/ds/manifest.txt" ;;
    *) fail "$file: neither .tvps nor .txt"; continue ;;
    esac
    "$INFO" "$W/ds" --verify > "$W/out.txt" 2>&1
    rc=$?
    if [ "$rc" -ne "$vrc" ]; then
        fail "$file: tvpal-info --verify exit $rc, expected $vrc"; sed 's/^/    /' "$W/out.txt" >&2
    elif ! grep -Eq -- "$pat" "$W/out.txt"; then
        fail "$file: tvpal-info --verify lacks /$pat/"; sed 's/^/    /' "$W/out.txt" >&2
    else
        ok "$file: tvpal-info --verify exit $rc"
    fi
    rm -f "$W/x.f32"
    "$DEC" "$W/ds" --step "$step" --axis z -o "$W/x.f32" > /dev/null 2> "$W/err.txt"
    rc=$?
    if [ "$rc" -ne "$drc" ]; then
        fail "$file: tvpal-decode --step $step exit $rc, expected $drc"; sed 's/^/    /' "$W/err.txt" >&2
    elif ! grep -Eq -- "$pat" "$W/err.txt"; then
        fail "$file: tvpal-decode lacks /$pat/"; sed 's/^/    /' "$W/err.txt" >&2
    elif [ -e "$W/x.f32" ]; then
        fail "$file: tvpal-decode wrote output"
    else
        ok "$file: tvpal-decode exit $rc: $(head -n 1 "$W/err.txt")"
    fi
done < "$W/expect.txt"
finish
