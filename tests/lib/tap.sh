# TAP output for the shell suites (sourced, not run): ok, not_ok, skip,
# check.  Sets n (tests so far) and failed (failures so far).
# SM_TEST_TIMING=1 prints the elapsed time after each ok line.
n=0
failed=0
TAP_T0=${EPOCHREALTIME/,/.}
ok() {
    n=$((n + 1))
    echo "ok $n - $1"
    if [ -n "${SM_TEST_TIMING:-}" ]; then
        awk -v a="$TAP_T0" -v b="${EPOCHREALTIME/,/.}" 'BEGIN { printf "# at %.2f s\n", b - a }'
    fi
    return 0
}
# not_ok DESC [DETAIL...]: each detail is printed as a TAP comment
not_ok() {
    n=$((n + 1))
    failed=$((failed + 1))
    echo "not ok $n - $1"
    shift
    local line
    for line in "$@"; do printf '%s\n' "$line" | head -c 3000 | sed 's/^/#   /'; done
}
skip() { n=$((n + 1)); echo "ok $n # SKIP $1"; }
# check DESC COMMAND...: ok when the command succeeds
check() {
    local desc=$1
    shift
    if "$@"; then ok "$desc"; else not_ok "$desc" "failed: $*"; fi
}
