# Preamble of the CLI suites (tests/cli/*.sh; sourced, not run): strict
# variables, ROOT (the repository), BIN (the shapematch program of the
# variant under test), WORK (a fresh folder, removed on exit) and the TAP
# helpers of tests/lib/tap.sh (ok, not_ok, skip, check), and expect_ok /
# expect_fail below.
# Env: SM_BIN (directory of the built binaries), SM_ROOT (repo root).
set -u
ROOT=${SM_ROOT:-$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)}
BIN=${SM_BIN:-$ROOT/build/release}/shapematch
WORK=$(mktemp -d "${TMPDIR:-/tmp}/sm-cli-$(basename "$0" .sh).XXXXXX")
trap 'rm -rf "$WORK"' EXIT
source "$ROOT/tests/lib/tap.sh"

# expect_ok DESC CMD...: ok when CMD succeeds (its output in the detail)
expect_ok() {
    local desc=$1 out
    shift
    if out=$("$@" 2>&1); then ok "$desc"; else not_ok "$desc" "$out"; fi
}
# expect_fail DESC RC PATTERN CMD...: CMD exits RC with PATTERN on stderr
expect_fail() {
    local desc=$1 want=$2 pat=$3 rc=0
    shift 3
    "$@" >"$WORK/out.txt" 2>"$WORK/err.txt" || rc=$?
    if [ "$rc" = "$want" ] && grep -q -- "$pat" "$WORK/err.txt"; then
        ok "$desc"
    else
        not_ok "$desc" "exit $rc (want $want); stderr: $(head -c 400 "$WORK/err.txt")"
    fi
}
