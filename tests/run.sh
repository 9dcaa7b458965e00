#!/usr/bin/env bash
# Runs every test suite in both build variants and prints one summary line
# "N passed, N failed".  Every suite speaks TAP ("ok N - name" /
# "not ok N - name"): cmocka programs through CMOCKA_MESSAGE_OUTPUT=TAP,
# shell suites by printing the lines themselves.  A suite that exits
# non-zero without reporting a failure (a crash, a sanitizer report)
# counts as one failed test.
set -u
cd "$(dirname "$0")/.."
ROOT=$PWD
variants=${SM_TEST_VARIANTS:-"release asan"}
only=${SM_TEST_ONLY:-}
passed=0
failed=0
failures=()
logdir=build/test-logs
mkdir -p "$logdir"

run_suite() { # variant name command...
    local variant=$1 name=$2
    shift 2
    local log="$logdir/$variant-$name.log"
    local start=$SECONDS
    "$@" >"$log" 2>&1
    local rc=$?
    local ok nok
    ok=$(grep -cE '^ok ' "$log")
    # a skipped test is neither (cmocka's TAP writes it "not ok N # SKIP")
    nok=$(grep -E '^not ok ' "$log" | grep -cv '# SKIP')
    if [ "$rc" -ne 0 ] && [ "$nok" -eq 0 ]; then
        nok=1
        echo "not ok - $name exited with status $rc" >>"$log"
    fi
    if [ "$ok" -eq 0 ] && [ "$nok" -eq 0 ]; then
        nok=1
        echo "not ok - $name reported no test" >>"$log"
    fi
    passed=$((passed + ok))
    failed=$((failed + nok))
    printf '%-8s %-32s %4d passed %3d failed  %4ds\n' "$variant" "$name" "$ok" "$nok" $((SECONDS - start))
    if [ "$nok" -ne 0 ]; then
        failures+=("$variant/$name")
        grep -E '^not ok|ERROR|Sanitizer|runtime error' "$log" | head -20 | sed 's/^/    /'
        echo "    (full log: $log)"
    fi
}

for variant in $variants; do
    bin="$ROOT/build/$variant"
    export SM_BIN="$bin" SM_VARIANT="$variant" SM_ROOT="$ROOT"
    export CMOCKA_MESSAGE_OUTPUT=TAP
    export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1:abort_on_error=0:halt_on_error=1}
    export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}
    for t in "$bin"/tests/test_*; do
        [ -x "$t" ] || continue
        name=$(basename "$t")
        [ -n "$only" ] && [[ "$name" != *$only* ]] && continue
        run_suite "$variant" "$name" "$t"
    done
    for s in tests/cli/*.sh tests/build/*.sh tests/integration/*.sh; do
        [ -f "$s" ] || continue
        name=$(basename "$s" .sh)
        [ "$name" = lib ] && continue # shared helpers, sourced by the suites
        [ -n "$only" ] && [[ "$name" != *$only* ]] && continue
        run_suite "$variant" "$name" bash "$s"
    done
done

if [ "${#failures[@]}" -ne 0 ]; then
    echo "failed suites: ${failures[*]}"
fi
echo "$passed passed, $failed failed"
[ "$failed" -eq 0 ]
