# Preamble of the CLI suites (tests/cli/*.sh; sourced, not run): strict
# variables, ROOT (the repository), BIN (the shapematch program of the
# variant under test), WORK (a fresh folder, removed on exit) and the TAP
# helpers of tests/lib/tap.sh (ok, not_ok, skip, check).
# Env: SM_BIN (directory of the built binaries), SM_ROOT (repo root).
set -u
ROOT=${SM_ROOT:-$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)}
BIN=${SM_BIN:-$ROOT/build/release}/shapematch
WORK=$(mktemp -d "${TMPDIR:-/tmp}/sm-cli-$(basename "$0" .sh).XXXXXX")
trap 'rm -rf "$WORK"' EXIT
source "$ROOT/tests/lib/tap.sh"
