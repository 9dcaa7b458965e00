#!/usr/bin/env bash
# TAP tests: every bound of every job parameter through the shapematch
# binary itself (`shapematch run --flag value`).  The cases come from
# the parameter table (tests/unit/test_params.c --cli-cases: the value at
# each bound, just inside and just beyond it, and what the bound's kind
# says of it); test_params checks the same cases against the params
# decoder and the core.  An accepted value gets as far as reading the
# (missing) template: exit 2; a refused one is a usage error: exit 1,
# with a message naming the flag.
# Env: SM_BIN (directory of the built binaries), SM_ROOT (repo root).
set -u
ROOT=${SM_ROOT:-$(cd "$(dirname "$0")/../.." && pwd)}
BINDIR=${SM_BIN:-$ROOT/build/release}
source "$ROOT/tests/lib/tap.sh"
TMP=$(mktemp -d "${TMPDIR:-/tmp}/sm-cli-params.XXXXXX")
trap 'rm -rf "$TMP"' EXIT
cd "$TMP" || exit 1

if ! "$BINDIR/tests/test_params" --cli-cases >cases.txt 2>cases.err; then
    not_ok "test_params --cli-cases lists the cases" "$(head -c 600 cases.err)"
    exit 1
fi
total=$(wc -l <cases.txt)
if [ "$total" -ge 60 ]; then
    ok "the parameter table gives $total bound cases"
else
    not_ok "the parameter table gives at least 60 bound cases (got $total)"
fi

bad=()
while read -r expect inputs flag value extra; do
    if [ "$inputs" = surface ]; then
        # a label map's template: template_size and template_label both apply
        in=(--template-image missing.nii.gz --target-surface missing.stl)
    else
        in=(--template missing.mesh --target-mesh missing.mesh --target-sol missing.sol)
    fi
    # shellcheck disable=SC2086 # extra: "" or "FLAG VALUE"
    "$BINDIR/shapematch" run "${in[@]}" -o out --no-clamp $extra "$flag" "$value" \
        >out.txt 2>err.txt
    rc=$?
    if [ "$expect" = accept ] && { [ "$rc" -ne 2 ] || ! grep -q 'missing' err.txt; }; then
        bad+=("$flag $value: expected accepted (exit 2 on the missing template), got exit $rc: $(head -c 200 err.txt)")
    elif [ "$expect" = refuse ] && { [ "$rc" -ne 1 ] || ! grep -qF -- "$flag" err.txt; }; then
        bad+=("$flag $value: expected refused (exit 1 naming $flag), got exit $rc: $(head -c 200 err.txt)")
    fi
done <cases.txt
if [ "${#bad[@]}" -eq 0 ]; then
    ok "shapematch run accepts and refuses each of the $total values as its bound says"
else
    not_ok "shapematch run accepts and refuses each value as its bound says (${#bad[@]} of $total wrong)" \
        "${bad[@]:0:10}"
fi
[ -e out ] && not_ok "no output directory made" || ok "no output directory made"
echo "1..$n"
[ "$failed" -eq 0 ]
