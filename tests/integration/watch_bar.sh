#!/usr/bin/env bash
# `shapematch watch` on a terminal shows the same bar as `run` (issue 10):
# it reads the job's goals from its status document (maxIter,
# tolBoundary) and, under an 80-column pseudo-terminal (script -qec),
# draws "[####....]  NN%  iter N  rms ...  ETA Ts" within 79 columns,
# redrawn in place, ending at 100% when the iteration cap ends the job;
# not on a terminal, plain lines with no bar.
source "$(dirname "$0")/lib.sh"

if ! command -v script >/dev/null; then
    not_ok "script(1) is installed"
    exit 1
fi
if ! make_case; then
    not_ok "gmsh builds the test meshes" "$(tail -5 "$WORK/case/gmsh.log")"
    exit 1
fi
if ! start_daemon bar --workers 1 --worker-threads 1; then
    not_ok "the daemon starts"
    exit 1
fi
ok "the daemon starts"

# 40 iterations, no other stop: the cap is the goal
PARAMS="$BALL_PARAMS, \"max_iter\": 40, \"tol_step\": 1e-15, \"tol_stall\": 0, \"tol_boundary\": 1e-12}"
ID=$(submit "$DISK" "$BOX" "$BOXSOL" "$PARAMS")
if [ -n "$ID" ] && wait_final "$ID" 120 && state_is "$ID" successful; then
    ok "the job runs (successful)"
else
    not_ok "the job runs" "id '$ID', state $(job_state "$ID")" "$(cat "$WORK/submit.out")"
    exit 1
fi
doc=$(hcurl "$BASE/v1/jobs/$ID")
[ "$(jq -r '"\(.maxIter) \(.tolBoundary)"' <<<"$doc")" = "40 1e-12" ] &&
    ok "the status document carries maxIter and tolBoundary" ||
    not_ok "the status document carries maxIter and tolBoundary" "$doc"

script -qec "stty cols 80; $BIN/shapematch watch --server $BASE $ID" /dev/null >"$WORK/tty.log" 2>&1
rc=$?
tr '\r' '\n' <"$WORK/tty.log" | sed 's/\x1b\[K//g' >"$WORK/tty.lines"
last=$(grep -E '^\[' "$WORK/tty.lines" | tail -1)
if [ "$rc" = 0 ] && grep -q $'\r' "$WORK/tty.log" &&
    grep -qE '^\[[#.]{10}\] +[0-9]+%  iter [0-9]+  r->t rms [^ ]+  t->r rms [^ ]+  .*ETA [0-9]+s' "$WORK/tty.lines" &&
    [ -z "$(grep -E '^\[' "$WORK/tty.lines" | awk 'length($0) > 79')" ] &&
    [ "${last#\[##########\] 100%}" != "$last" ]; then
    ok "watch on an 80-column terminal: the bar with percentage, both RMS distances and ETA within 79 columns, ending at 100% ('$last')"
else
    not_ok "watch on a terminal shows the bar" "exit $rc" "$(tail -c 600 "$WORK/tty.lines")"
fi

"$BIN/shapematch" watch --server "$BASE" "$ID" >"$WORK/plain.out" 2>"$WORK/plain.err"
rc=$?
if [ "$rc" = 0 ] && ! grep -q $'\r' "$WORK/plain.err" && ! grep -q '^\[' "$WORK/plain.err" &&
    grep -q '^iter ' "$WORK/plain.err"; then
    ok "watch not on a terminal: plain lines, no bar"
else
    not_ok "watch not on a terminal: plain lines" "exit $rc" "$(head -c 600 "$WORK/plain.err")"
fi

reports_clean && ok "no sanitizer report" || not_ok "no sanitizer report"
stop_daemon
echo "1..$n"
