#!/usr/bin/env bash
# TAP tests of what libshapematch.a exports (the idea of jansson's
# check-exports): the global symbols it defines (nm -g --defined-only)
# must be exactly the committed list core/exports.txt, so that a symbol
# appearing or disappearing is a decision, not an accident; all of them
# are functions (core has no globals) and carry the sm_ prefix.
#
# After an intended change of the API, regenerate the list from a fresh
# build and commit it:
#   make release && tests/cli/exports.sh --update
# (--update keeps the comment lines at the top of the list.)
# Env: SM_BIN (directory of the built binaries), SM_ROOT (repo root).
set -u
ROOT=${SM_ROOT:-$(cd "$(dirname "$0")/../.." && pwd)}
LIB=${SM_BIN:-$ROOT/build/release}/libshapematch.a
LIST=$ROOT/core/exports.txt

# "TYPE NAME" of every global symbol defined in the archive, sorted
defined() {
    nm -g --defined-only "$LIB" | awk 'NF == 3 { print $2, $3 }' | LC_ALL=C sort -k2 -u
}
listed() {
    grep -v '^#' "$LIST" | grep -v '^[[:space:]]*$'
}

if [ "${1:-}" = --update ]; then
    [ -f "$LIB" ] || { echo "exports: $LIB not built (make release first)" >&2; exit 1; }
    tmp=$(mktemp)
    { [ -f "$LIST" ] && grep '^#' "$LIST"; defined | awk '{ print $2 }'; } >"$tmp"
    mv "$tmp" "$LIST"
    echo "exports: wrote $(listed | wc -l) symbols of $LIB to $LIST"
    exit 0
fi

source "$ROOT/tests/lib/tap.sh"

if [ ! -f "$LIB" ]; then
    not_ok "libshapematch.a is built" "missing: $LIB"
    exit 1
fi
ok "libshapematch.a is built ($LIB)"
if [ ! -f "$LIST" ]; then
    not_ok "core/exports.txt exists" "create it with: tests/cli/exports.sh --update"
    exit 1
fi
ok "core/exports.txt exists"

syms=$(defined)
if [ -z "$syms" ]; then
    not_ok "nm lists the symbols of libshapematch.a"
    exit 1
fi
ok "nm lists $(printf '%s\n' "$syms" | wc -l) global symbols of libshapematch.a"

# sorted, no duplicates: the list diffs cleanly and merges cleanly
if listed | LC_ALL=C sort -c -u 2>/dev/null; then
    ok "core/exports.txt is sorted without duplicates"
else
    not_ok "core/exports.txt is sorted without duplicates" \
        "$(listed | LC_ALL=C sort -c -u 2>&1)" "regenerate: tests/cli/exports.sh --update"
fi

# the comparison itself
added=$(LC_ALL=C comm -13 <(listed | LC_ALL=C sort -u) <(printf '%s\n' "$syms" | awk '{ print $2 }'))
removed=$(LC_ALL=C comm -23 <(listed | LC_ALL=C sort -u) <(printf '%s\n' "$syms" | awk '{ print $2 }'))
if [ -z "$added" ] && [ -z "$removed" ]; then
    ok "libshapematch.a exports exactly the symbols of core/exports.txt"
else
    not_ok "libshapematch.a exports exactly the symbols of core/exports.txt" \
        "$( [ -n "$added" ] && printf '+ %s (exported, not listed)\n' $added)" \
        "$( [ -n "$removed" ] && printf -- '- %s (listed, no longer exported)\n' $removed)" \
        "if the change is intended: tests/cli/exports.sh --update, and commit core/exports.txt;" \
        "if not: make the new function static, or restore the one that went"
fi

# no globals in core: every exported symbol is code (T), none is data
data=$(printf '%s\n' "$syms" | awk '$1 != "T" { print $1, $2 }')
if [ -z "$data" ]; then
    ok "every exported symbol is a function (no global data in core)"
else
    not_ok "every exported symbol is a function (no global data in core)" "$data"
fi

# one namespace: sm_ (public and library-internal alike; sm__ marks the
# internal helpers shared between the files of one part)
foreign=$(printf '%s\n' "$syms" | awk '$2 !~ /^sm_/ { print $2 }')
if [ -z "$foreign" ]; then
    ok "every exported symbol starts with sm_"
else
    not_ok "every exported symbol starts with sm_" "$foreign"
fi

[ "$failed" -eq 0 ]
