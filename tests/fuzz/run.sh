#!/usr/bin/env bash
# Runs libFuzzer targets (build/fuzz/fuzz_*) and prints one TAP line per
# target with its executions, coverage (libFuzzer's edge counter "cov" and
# feature counter "ft") and crashes.
#   tests/fuzz/run.sh SECONDS target...   fuzz each target for SECONDS
#   tests/fuzz/run.sh 0 target...         replay the seed corpus only
# The working corpus build/fuzz/corpus/<target>/ grows between runs; a
# crashing input is saved as build/fuzz/artifacts/<target>-crash-*: turn it
# into a case of tests/data/malformed/ (or the target's seeds) once fixed.
set -u
cd "$(dirname "$0")/../.."
seconds=$1
shift
dir=build/fuzz
tests/fuzz/seeds.sh "$dir/seeds" || exit 1
mkdir -p "$dir/corpus" "$dir/artifacts" "$dir/logs"
n=0
failed=0
for target in "$@"; do
    name=${target#fuzz_}
    n=$((n + 1))
    bin=$dir/$target
    log=$dir/logs/$target.log
    corpus=$dir/corpus/$name
    mkdir -p "$corpus"
    if [ "$seconds" = 0 ]; then
        "$bin" -runs=0 -rss_limit_mb=2048 -timeout=20 \
            -artifact_prefix="$dir/artifacts/$target-" \
            "$dir/seeds/$name" "$corpus" >"$log" 2>&1
    else
        # -max_len keeps inputs near the size of the seeds (a few KB): the
        # readers' cost per byte is tested by the benchmarks, not here.
        "$bin" -max_total_time="$seconds" -max_len=8192 -rss_limit_mb=2048 \
            -timeout=20 -print_final_stats=1 \
            -artifact_prefix="$dir/artifacts/$target-" \
            "$corpus" "$dir/seeds/$name" >"$log" 2>&1
    fi
    rc=$?
    runs=$(grep -oE 'stat::number_of_executed_units: *[0-9]+' "$log" | grep -oE '[0-9]+$' | tail -1)
    [ -n "$runs" ] || runs=$(grep -oE '^#[0-9]+' "$log" | tail -1 | tr -d '#')
    cov=$(grep -oE 'cov: [0-9]+' "$log" | tail -1 | grep -oE '[0-9]+')
    ft=$(grep -oE 'ft: [0-9]+' "$log" | tail -1 | grep -oE '[0-9]+')
    if [ "$rc" -eq 0 ]; then
        echo "ok $n - $target: ${runs:-?} executions, cov ${cov:-?}, ft ${ft:-?}, 0 crashes"
    else
        failed=$((failed + 1))
        echo "not ok $n - $target: exit $rc after ${runs:-?} executions (log: $log)"
        grep -E 'ERROR|runtime error|SUMMARY|Test unit written' "$log" | head -8 | sed 's/^/# /'
    fi
done
echo "1..$n"
[ "$failed" -eq 0 ]
