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
timings=()
run_start=$SECONDS
logdir=build/test-logs
mkdir -p "$logdir"
rm -f "$logdir"/*.result

run_suite() { # variant name command...
    local variant=$1 name=$2
    shift 2
    local log="$logdir/$variant-$name.log"
    local t0=${EPOCHREALTIME/,/.}
    "$@" >"$log" 2>&1
    local rc=$?
    local t1=${EPOCHREALTIME/,/.}
    # CPU: this subshell's reaped children (the suite and every process it
    # waited for, daemons and their workers included), user + system
    # (`times` must run in this shell, not in a forked pipeline)
    local cpu
    times >"$log.times"
    cpu=$(awk 'NR == 2 { n = split($0, f, " "); s = 0
        for (i = 1; i <= n; i++) { split(f[i], p, "m"); s += p[1] * 60 + p[2] } printf "%.1f", s }' "$log.times")
    rm -f "$log.times"
    local wall
    wall=$(awk -v a="$t0" -v b="$t1" 'BEGIN { printf "%.1f", b - a }')
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
    echo "$ok $nok $wall $cpu" >"$logdir/$variant-$name.result"
    # one write, so that lines of suites running side by side do not mix
    local out
    out=$(printf '%-8s %-32s %4d passed %3d failed  %6.1fs wall %6.1fs cpu' "$variant" "$name" "$ok" "$nok" "$wall" "$cpu")
    if [ "$nok" -ne 0 ]; then
        out+=$'\n'$(grep -E '^not ok|ERROR|Sanitizer|runtime error' "$log" | head -20 | sed 's/^/    /')
        out+=$'\n'"    --- last 20 lines of $log:"
        out+=$'\n'$(tail -n 20 "$log" | sed 's/^/    /')
    fi
    printf '%s\n' "$out"
}

# The queue: every suite of every variant, as "variant name kind path".
queue=()
for variant in $variants; do
    for t in "$ROOT/build/$variant"/tests/test_*; do
        [ -x "$t" ] || continue
        name=$(basename "$t")
        [ -n "$only" ] && [[ "$name" != *$only* ]] && continue
        queue+=("$variant $name bin $t")
    done
    for s in tests/cli/*.sh tests/build/*.sh tests/integration/*.sh; do
        [ -f "$s" ] || continue
        name=$(basename "$s" .sh)
        [ "$name" = lib ] && continue # shared helpers, sourced by the suites
        [ -n "$only" ] && [[ "$name" != *$only* ]] && continue
        queue+=("$variant $name sh $s")
    done
done

# What a suite costs, for the schedule: a shell suite may say it in a
# line near its top (the first 20 lines),
#     # run.sh: weight W seconds S asan A
# W, the cores it keeps busy while it runs (default 1: a cmocka program,
# a suite that computes; a suite that mostly waits on its daemons weighs
# less, and more of them run side by side); S, its wall seconds on an
# idle machine in the release variant (default 5), A in the ASan variant
# (default 3 S).
# The wall seconds of the last run on this machine, when there was one
# (build/test-logs/last-times), stand for S.
# "# run.sh: alone" (a suite whose verdicts would time the daemon against
# a wall clock it shares) still runs with nothing beside it, after the
# others; no suite needs it today.
# A cmocka program says it in its source, tests/unit/NAME.c, as a comment
# line "/* run.sh: ... */".  A suite of tests/integration/ weighs 0.5 by
# default (it mostly waits on its daemons).
header_of() { # kind path: the suite's "run.sh:" words
    if [ "$1" = sh ]; then
        head -20 "$2" | sed -n 's/^# run\.sh: //p'
    else
        local src=tests/unit/$(basename "$2").c
        [ -f "$src" ] && head -30 "$src" | sed -n 's|^/\* run\.sh: \(.*\) \*/$|\1|p'
    fi
}
declare -A last_wall=()
if [ -f "$logdir/last-times" ]; then
    while read -r v nm w _; do last_wall[$v/$nm]=$w; done <"$logdir/last-times"
fi
# cost VARIANT NAME KIND PATH: prints "SECONDS_TENTHS WEIGHT_HUNDREDTHS ALONE"
cost() {
    local h w=1 secs=5 alone=0
    [[ $4 == */tests/integration/* || $4 == tests/integration/* ]] && w=0.5
    h=$(header_of "$3" "$4")
    [[ $h == *alone* ]] && alone=1
    [[ $h =~ weight\ ([0-9.]+) ]] && w=${BASH_REMATCH[1]}
    [[ $h =~ seconds\ ([0-9.]+) ]] && secs=${BASH_REMATCH[1]}
    if [ "$1" = asan ]; then
        secs=$(awk -v s="$secs" 'BEGIN { print s * 3 }')
        [[ $h =~ asan\ ([0-9.]+) ]] && secs=${BASH_REMATCH[1]}
    fi
    [ -n "${last_wall[$1/$2]:-}" ] && secs=${last_wall[$1/$2]}
    awk -v s="$secs" -v w="$w" -v a="$alone" 'BEGIN { printf "%d %d %d\n", s * 10, w * 100, a }'
}

start_suite() { # variant name kind path
    local variant=$1 name=$2 kind=$3 path=$4
    (
        export SM_BIN="$ROOT/build/$variant" SM_VARIANT="$variant" SM_ROOT="$ROOT"
        export CMOCKA_MESSAGE_OUTPUT=TAP
        export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1:abort_on_error=0:halt_on_error=1}
        export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}
        if [ "$kind" = bin ]; then
            run_suite "$variant" "$name" "$path"
        else
            run_suite "$variant" "$name" bash "$path"
        fi
    )
}

# The schedule: the longest suites first (the critical path), side by side
# while the weights of those running add up to at most SM_TEST_JOBS cores
# (default: one per core), and at most 4 suites a core at once (daemons,
# ports, memory); one always runs, whatever its weight.
cores=${SM_TEST_JOBS:-$(nproc)}
cap=$((cores * 100))
max_running=$((cores * 4))
order=()
alone=()
declare -A weight_of=()
while IFS='|' read -r _ w a entry; do
    if [ "$a" = 1 ]; then
        alone+=("$entry")
    else
        order+=("$entry")
        weight_of[$entry]=$w
    fi
done < <(for entry in "${queue[@]}"; do
    read -r variant name kind path <<<"$entry"
    read -r t w a < <(cost "$variant" "$name" "$kind" "$path")
    echo "$t|$w|$a|$entry"
done | sort -t'|' -k1,1 -n -r)
load=0
running=0
declare -A pid_weight=()
for entry in ${order[@]+"${order[@]}"}; do
    read -r variant name kind path <<<"$entry"
    w=${weight_of[$entry]}
    while [ "$running" -gt 0 ] && { [ $((load + w)) -gt "$cap" ] || [ "$running" -ge "$max_running" ]; }; do
        done_pid=
        wait -n -p done_pid || [ -n "$done_pid" ] || break
        [ -n "${pid_weight[$done_pid]+set}" ] || continue # not a suite
        load=$((load - ${pid_weight[$done_pid]}))
        unset "pid_weight[$done_pid]"
        running=$((running - 1))
    done
    start_suite "$variant" "$name" "$kind" "$path" &
    pid_weight[$!]=$w
    load=$((load + w))
    running=$((running + 1))
done
wait
for entry in ${alone[@]+"${alone[@]}"}; do
    read -r variant name kind path <<<"$entry"
    start_suite "$variant" "$name" "$kind" "$path"
done

# Each suite left its counts in its .result file (a background suite cannot
# add to this shell's variables).
for entry in "${queue[@]}"; do
    read -r variant name kind path <<<"$entry"
    res="$logdir/$variant-$name.result"
    if [ ! -f "$res" ]; then
        failed=$((failed + 1))
        failures+=("$variant/$name")
        continue
    fi
    read -r ok nok wall cpu <"$res"
    passed=$((passed + ok))
    failed=$((failed + nok))
    [ "$nok" -ne 0 ] && failures+=("$variant/$name")
    timings+=("$wall $cpu $variant/$name")
    echo "$variant $name $wall $cpu" >>"$logdir/last-times.new"
done
# the next run's order (only a whole run's: a narrowed one keeps the last)
[ -z "$only" ] && [ "$variants" = "release asan" ] && mv "$logdir/last-times.new" "$logdir/last-times"
rm -f "$logdir/last-times.new"

# Where the time went: the slowest suites (wall, and the CPU they used;
# a suite far below its wall mostly waits on its daemons) and the totals.
if [ "${#timings[@]}" -ne 0 ]; then
    echo "slowest suites (wall s, cpu s):"
    printf '%s\n' "${timings[@]}" | sort -k1,1 -g -r | head -n "${SM_TEST_SLOWEST:-10}" |
        awk '{ printf "  %7.1f %7.1f  %s\n", $1, $2, $3 }'
    # the machine's load says how far the figures can be compared
    read -r load1 _ load15 _ </proc/loadavg
    printf '%s\n' "${timings[@]}" | awk -v w=$((SECONDS - run_start)) -v l1="$load1" -v l15="$load15" \
        '{ c += $2 } END { printf "suites: %.0f s of CPU in %d s of wall; load average %s (1 min), %s (15 min)\n", c, w, l1, l15 }'
fi
if [ "${#failures[@]}" -ne 0 ]; then
    echo "failed suites: ${failures[*]}"
fi
echo "$passed passed, $failed failed"
[ "$failed" -eq 0 ]
