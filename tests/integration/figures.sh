#!/usr/bin/env bash
# The same named figures everywhere (issue 33): a job's progress events
# and summary.json carry the two-sided distance (distance.result_to_target
# and .target_to_result: rms, max, p99) and the L2 norm under its own name
# (boundary_l2); what each client prints is read back here and compared,
# number by number at the printed precision, with the document it comes
# from:
#   - `watch` (not a terminal): its last plain line is the last progress
#     event's figures; its closing line the summary's;
#   - `status`: its "last" line the status document's lastProgress, which
#     is the last progress event; its "result" line the summary's;
#   - `shapematch run` locally: the same lines for the same job (one job
#     runner), its closing line the summary it writes;
#   - the job's name (part "name") in the status document, `status`,
#     `list` and watch's lines; a name with a control character is a 422.
# The web app's headline is read by web_app.mjs.
source "$(dirname "$0")/lib.sh"

if ! make_case; then
    not_ok "gmsh builds the test meshes" "$(tail -5 "$WORK/case/gmsh.log")"
    exit 1
fi
start_daemon figures --workers 1 || { not_ok "the daemon starts"; exit 1; }
ok "the daemon starts"

PARAMS="$(quick_params 12)"
ID=$(submit "$DISK" "$BOX" "$BOXSOL" "$PARAMS" -F "name=disk→circle #1")
if [ -n "$ID" ] && wait_final "$ID" $((60 * SLOW)) && state_is "$ID" successful; then
    ok "a named job runs (successful)"
else
    not_ok "the job runs" "id '$ID' state $(job_state "$ID")" "$(cat "$WORK/submit.out")"
    exit 1
fi
hcurl "$BASE/v1/jobs/$ID/results" >"$WORK/summary.json"
hcurl "$BASE/v1/jobs/$ID" >"$WORK/status.json"
"$BIN/shapematch" watch --server "$BASE" --json "$ID" >"$WORK/events.ndjson" 2>/dev/null
jq -c 'select(.type == "progress")' "$WORK/events.ndjson" | tail -1 >"$WORK/last.json"
if jq -e '.distance.result_to_target.rms and .distance.target_to_result.p99 and .distance.method' \
    "$WORK/summary.json" >/dev/null && jq -e '.distance.target_to_result.rms' "$WORK/last.json" >/dev/null; then
    ok "summary.json and the progress events carry the two-sided distance"
else
    not_ok "the distance is on the wire" "$(head -c 600 "$WORK/summary.json")" "$(cat "$WORK/last.json")"
fi

# f FILE JQ-PATH: a number of a document as the clients print it (%.3e)
f() { printf '%.3e' "$(jq -r "$2" "$1")"; }
ev_rt=$(f "$WORK/last.json" .distance.result_to_target.rms)
ev_rtm=$(f "$WORK/last.json" .distance.result_to_target.max)
ev_tr=$(f "$WORK/last.json" .distance.target_to_result.rms)
ev_trm=$(f "$WORK/last.json" .distance.target_to_result.max)
ev_p99=$(f "$WORK/last.json" .distance.target_to_result.p99)
ev_l2=$(f "$WORK/last.json" .boundary_l2)
it=$(jq -r .iteration "$WORK/last.json")
s_figs="result->target RMS $(f "$WORK/summary.json" .distance.result_to_target.rms) (max $(f "$WORK/summary.json" .distance.result_to_target.max)), target->result RMS $(f "$WORK/summary.json" .distance.target_to_result.rms) (max $(f "$WORK/summary.json" .distance.target_to_result.max), p99 $(f "$WORK/summary.json" .distance.target_to_result.p99)); L2 of d on the boundary $(f "$WORK/summary.json" .boundary_l2)"
want_line="iter $it  result->target rms $ev_rt  max $ev_rtm  target->result rms $ev_tr  max $ev_trm  p99 $ev_p99  "

# ---------------------------------------------------------------- watch
"$BIN/shapematch" watch --server "$BASE" "$ID" >/dev/null 2>"$WORK/watch.err"
last_line=$(grep '^iter ' "$WORK/watch.err" | tail -1)
if [ "${last_line#"$want_line"}" != "$last_line" ] && grep -qF "L2 $ev_l2" <<<"$last_line"; then
    ok "watch's last progress line is the last event's figures: '$last_line'"
else
    not_ok "watch's progress line" "got  '$last_line'" "want '$want_line... L2 $ev_l2'"
fi
if grep -qF "job $ID (disk→circle #1) successful: max_iterations after 12 iterations: $s_figs, min quality" \
    "$WORK/watch.err"; then
    ok "watch names the job and closes with the summary's figures"
else
    not_ok "watch's closing line" "$(tail -2 "$WORK/watch.err")" "want: $s_figs"
fi

# ---------------------------------------------------------------- status
"$BIN/shapematch" status --server "$BASE" "$ID" >"$WORK/status.out" 2>&1
want_last="last      iter $it  result->target rms $ev_rt  max $ev_rtm  target->result rms $ev_tr  max $ev_trm  p99 $ev_p99  L2 $(f "$WORK/last.json" .boundary_l2)  J "
if jq -e --slurpfile e "$WORK/last.json" '.lastProgress.distance == $e[0].distance and .lastProgress.boundary_l2 == $e[0].boundary_l2' \
    "$WORK/status.json" >/dev/null && grep -qF "$want_last" "$WORK/status.out"; then
    ok "status: lastProgress is the last event's, and its 'last' line shows those figures"
else
    not_ok "status's last line" "$(cat "$WORK/status.out")" "want: $want_last" "$(jq -c .lastProgress "$WORK/status.json")"
fi
if grep -qF "result    max_iterations after 12 iterations: $s_figs, min quality" "$WORK/status.out" &&
    grep -qx "name      disk→circle #1" "$WORK/status.out"; then
    ok "status: the job's name and a 'result' line with the summary's figures"
else
    not_ok "status's result line" "$(cat "$WORK/status.out")" "want: $s_figs"
fi
if "$BIN/shapematch" list --server "$BASE" | grep "^$ID " | grep -qF "disk→circle #1"; then
    ok "list shows the job's name"
else
    not_ok "list shows the name" "$("$BIN/shapematch" list --server "$BASE")"
fi

# ------------------------------------------------------- run, locally
"$BIN/shapematch" run --template "$DISK" --target-mesh "$BOX" --target-sol "$BOXSOL" \
    --clamp-ball 0,0,0.1 --max-iter 12 -o "$WORK/run" >/dev/null 2>"$WORK/run.err"
run_line=$(grep '^iter ' "$WORK/run.err" | tail -1)
r_figs="result->target RMS $(f "$WORK/run/summary.json" .distance.result_to_target.rms) (max $(f "$WORK/run/summary.json" .distance.result_to_target.max)), target->result RMS $(f "$WORK/run/summary.json" .distance.target_to_result.rms) (max $(f "$WORK/run/summary.json" .distance.target_to_result.max), p99 $(f "$WORK/run/summary.json" .distance.target_to_result.p99)); L2 of d on the boundary $(f "$WORK/run/summary.json" .boundary_l2)"
if [ "${run_line%%  relative*}" = "${want_line%  }" ] &&
    grep -qE "max_iterations after 12 iterations, (NOT CONVERGED|converged): " "$WORK/run.err" &&
    grep -qF "iterations, $(grep -oE '(NOT CONVERGED|converged)' "$WORK/run.err" | tail -1): $r_figs" "$WORK/run.err"; then
    ok "run: the same progress line as watch, and a closing line with its summary's figures"
else
    not_ok "run's lines" "got  '$run_line'" "want '$want_line'" "$(tail -2 "$WORK/run.err")" "want: $r_figs"
fi

# ---------------------------------------------------------------- names
code=$(hcurl -o "$WORK/bad.json" -w '%{http_code}' -F "template=@$DISK" -F "target_mesh=@$BOX" \
    -F "target_sol=@$BOXSOL" -F "params=$PARAMS" -F "name=$(printf 'a\tb')" "$BASE/v1/jobs")
if [ "$code" = 422 ] && jq -e '.detail | test("^name: holds a control character")' "$WORK/bad.json" >/dev/null; then
    ok "a name with a control character is a 422 naming it"
else
    not_ok "a bad name is refused" "$code $(cat "$WORK/bad.json")"
fi
"$BIN/shapematch" submit --server "$BASE" --template "$DISK" --target-mesh "$BOX" --target-sol "$BOXSOL" \
    --clamp-ball 0,0,0.1 --name "$(head -c 201 /dev/zero | tr '\0' x)" >/dev/null 2>"$WORK/long.err"
rc=$?
if [ $rc = 1 ] && grep -q -- "--name: longer than 200 bytes" "$WORK/long.err"; then
    ok "submit --name refuses a name of 201 bytes before any request (exit 1)"
else
    not_ok "submit --name checks the name" "exit $rc" "$(cat "$WORK/long.err")"
fi

reports_clean && ok "no sanitizer report" || not_ok "no sanitizer report"
stop_daemon
echo "1..$n"
