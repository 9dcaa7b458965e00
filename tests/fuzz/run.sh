#!/usr/bin/env bash
# Runs libFuzzer targets (build/fuzz/fuzz_*) and prints one TAP line per
# target with its executions, executions per second, coverage (libFuzzer's
# edge counter "cov" and feature counter "ft") and crashes.
#   tests/fuzz/run.sh SECONDS target...   fuzz each target for SECONDS
#   tests/fuzz/run.sh 0 target...         replay the seed corpus only
# FUZZ_WORKERS=N (default 1) runs N fuzzing processes per target at once
# on the same corpus (libFuzzer reloads what the others add): the line
# then gives the sum of their executions, their exec/s summed (the rate
# per process is that divided by N) and the best cov and ft of them.
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
workers=${FUZZ_WORKERS:-1}
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
        rc=$?
        logs=("$log")
    else
        # -max_len keeps inputs near the size of the seeds (almost all
        # under 2 KB): the readers' cost per byte is tested by the
        # benchmarks, not here, and a parser's time per input grows with it.
        pids=()
        logs=()
        for ((w = 0; w < workers; w++)); do
            wlog=$log
            [ "$w" -gt 0 ] && wlog=$dir/logs/$target.$w.log
            logs+=("$wlog")
            "$bin" -max_total_time="$seconds" -max_len=4096 -rss_limit_mb=2048 \
                -timeout=20 -print_final_stats=1 -reload=1 \
                -artifact_prefix="$dir/artifacts/$target-" \
                "$corpus" "$dir/seeds/$name" >"$wlog" 2>&1 &
            pids+=($!)
        done
        rc=0
        for pid in "${pids[@]}"; do
            wait "$pid" || rc=$?
        done
    fi
    runs=0 cov=0 ft=0
    for wlog in "${logs[@]}"; do
        r=$(grep -oE 'stat::number_of_executed_units: *[0-9]+' "$wlog" | grep -oE '[0-9]+$' | tail -1)
        [ -n "$r" ] || r=$(grep -oE '^#[0-9]+' "$wlog" | tail -1 | tr -d '#')
        c=$(grep -oE 'cov: [0-9]+' "$wlog" | tail -1 | grep -oE '[0-9]+')
        f=$(grep -oE 'ft: [0-9]+' "$wlog" | tail -1 | grep -oE '[0-9]+')
        runs=$((runs + ${r:-0}))
        [ "${c:-0}" -gt "$cov" ] && cov=$c
        [ "${f:-0}" -gt "$ft" ] && ft=$f
    done
    rate=
    [ "$seconds" != 0 ] && rate=", $((runs / seconds)) exec/s"
    [ "$seconds" != 0 ] && [ "$workers" -gt 1 ] && rate="$rate ($workers workers)"
    if [ "$rc" -eq 0 ]; then
        echo "ok $n - $target: $runs executions$rate, cov $cov, ft $ft, 0 crashes"
    else
        failed=$((failed + 1))
        echo "not ok $n - $target: exit $rc after $runs executions (log: ${logs[*]})"
        grep -hE 'ERROR|runtime error|SUMMARY|Test unit written' "${logs[@]}" | head -8 | sed 's/^/# /'
    fi
done
echo "1..$n"
[ "$failed" -eq 0 ]
