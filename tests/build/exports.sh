#!/usr/bin/env bash
# TAP tests of what libshapematch.a exports, checked against the tree
# itself (no hand-kept list): every global symbol the archive defines
# (nm -g --defined-only) is either
#   - public: a function declared in core/include/shapematch/*.h, or
#   - private: named sm__* (shared between the files of the library, not
#     declared in the public headers),
# every function the public headers declare is defined, no public header
# declares an sm__ name, all globals are functions (core has no global
# data) and all carry the sm_ prefix.  A new global function is thus a
# decision: declare it in a public header, or name it sm__ (or make it
# static).  The public headers' declarations are read by the compiler
# (gcc -aux-info), not by a pattern.
#
#   tests/build/exports.sh          the checks (TAP)
#   tests/build/exports.sh --list   the public functions, one a line
# Env: SM_BIN (directory of the built binaries), SM_ROOT (repo root), CC.
set -u
ROOT=${SM_ROOT:-$(cd "$(dirname "$0")/../.." && pwd)}
LIB=${SM_BIN:-$ROOT/build/release}/libshapematch.a
INC=$ROOT/core/include
CC=${CC:-cc}
WORK=$(mktemp -d)
trap 'rm -rf "$WORK"' EXIT

# Functions the public headers declare, from the compiler's own list of
# the prototypes of a file that includes them all.
public_functions() {
    local h
    for h in "$INC"/shapematch/*.h; do
        printf '#include "shapematch/%s"\n' "$(basename "$h")"
    done >"$WORK/all.c"
    "$CC" -std=c11 -D_DEFAULT_SOURCE -D_GNU_SOURCE -I "$INC" -fsyntax-only \
        -aux-info "$WORK/all.aux" "$WORK/all.c" || return 1
    grep -F "$INC/shapematch/" "$WORK/all.aux" |
        sed -nE 's/.*\*\/ extern .*[^a-zA-Z0-9_]([a-zA-Z_][a-zA-Z0-9_]*) \(.*/\1/p' | LC_ALL=C sort -u
}

if [ "${1:-}" = --list ]; then
    public_functions
    exit
fi

source "$ROOT/tests/lib/tap.sh"

if [ ! -f "$LIB" ]; then
    not_ok "libshapematch.a is built" "missing: $LIB"
    exit 1
fi
ok "libshapematch.a is built ($LIB)"

# "TYPE NAME" of every global symbol defined in the archive, sorted
syms=$(nm -g --defined-only "$LIB" | awk 'NF == 3 { print $2, $3 }' | LC_ALL=C sort -k2 -u)
if [ -z "$syms" ]; then
    not_ok "nm lists the symbols of libshapematch.a"
    exit 1
fi
ok "nm lists $(printf '%s\n' "$syms" | wc -l) global symbols of libshapematch.a"
names=$(printf '%s\n' "$syms" | awk '{ print $2 }')

public=$(public_functions)
if [ -z "$public" ]; then
    not_ok "the public headers declare functions ($CC -aux-info)"
    exit 1
fi
ok "the public headers declare $(printf '%s\n' "$public" | wc -l) functions"


# every global is public or sm__
stray=$(LC_ALL=C comm -23 <(printf '%s\n' "$names" | grep -v '^sm__') <(printf '%s\n' "$public"))
if [ -z "$stray" ]; then
    ok "every global symbol is declared in core/include/shapematch/ or named sm__*"
else
    not_ok "every global symbol is declared in core/include/shapematch/ or named sm__*" \
        "$(printf '%s (global, not in a public header)\n' $stray)" \
        "declare it in a public header, rename it sm__*, or make it static"
fi

# every public function exists
missing=$(LC_ALL=C comm -13 <(printf '%s\n' "$names") <(printf '%s\n' "$public"))
if [ -z "$missing" ]; then
    ok "every function of the public headers is defined in libshapematch.a"
else
    not_ok "every function of the public headers is defined in libshapematch.a" \
        "$(printf '%s (declared, not defined)\n' $missing)"
fi

# the public headers never name a private function
leaked=$(printf '%s\n' "$public" | grep '^sm__' || true)
if [ -z "$leaked" ]; then
    ok "no public header declares an sm__ function"
else
    not_ok "no public header declares an sm__ function" "$leaked"
fi

# no globals in core: every exported symbol is code (T), none is data
data=$(printf '%s\n' "$syms" | awk '$1 != "T" { print $1, $2 }')
if [ -z "$data" ]; then
    ok "every exported symbol is a function (no global data in core)"
else
    not_ok "every exported symbol is a function (no global data in core)" "$data"
fi

# one namespace: sm_ (public) and sm__ (library-internal)
foreign=$(printf '%s\n' "$names" | grep -v '^sm_' || true)
if [ -z "$foreign" ]; then
    ok "every exported symbol starts with sm_"
else
    not_ok "every exported symbol starts with sm_" "$foreign"
fi

[ "$failed" -eq 0 ]
