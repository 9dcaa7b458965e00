#!/usr/bin/env bash
# One JSON writer on the wire: the daemon prints every document with
# proto's sm_json_dumps (shortest exact reals), so a real reads the same
# in every place it appears.  The job's tol_boundary 0.1 (status member
# tolBoundary) is checked in the 201 answer, the status document, the job
# list, the final "status" event (NDJSON and SSE) and the spool's
# status.json: each must print 0.1, never jansson's 0.10000000000000001.
# A problem document (422 with invalid-params) is laid out by the same
# writer: its array stays on the line of its key ("[{"), where jansson's
# pretty printer breaks the line.
source "$(dirname "$0")/lib.sh"

if ! make_case; then
    not_ok "gmsh builds the test meshes" "$(tail -5 "$WORK/case/gmsh.log")"
    exit 1
fi
start_daemon wire --workers 1 || { not_ok "daemon starts"; exit 1; }
ok "the daemon starts"

# has_point_one FILE SEP: FILE holds "tolBoundary"SEP0.1 followed by a
# delimiter, and no longer form of 0.1
has_point_one() {
    grep -Eq "\"tolBoundary\"$2"'0\.1[,}[:space:]]' "$1" && ! grep -q '0\.1000000' "$1"
}

ID=$(submit "$DISK" "$BOX" "$BOXSOL" "$BALL_PARAMS, \"max_iter\": 30, \"tol_boundary\": 0.1}")
if [ -n "$ID" ] && has_point_one "$WORK/submit.out" ': '; then
    ok "the 201 answer prints tolBoundary 0.1"
else
    not_ok "the 201 answer prints tolBoundary 0.1" "$(cat "$WORK/submit.out")"
fi
wait_final "$ID" 60 || not_ok "the job ends" "$(job_state "$ID")"

hcurl -o "$WORK/status.json" "$BASE/v1/jobs/$ID"
if has_point_one "$WORK/status.json" ': '; then
    ok "the status document prints tolBoundary 0.1"
else
    not_ok "the status document prints tolBoundary 0.1" "$(cat "$WORK/status.json")"
fi

hcurl -o "$WORK/list.json" "$BASE/v1/jobs"
if has_point_one "$WORK/list.json" ': '; then
    ok "the job list prints tolBoundary 0.1"
else
    not_ok "the job list prints tolBoundary 0.1" "$(cat "$WORK/list.json")"
fi

hcurl -H 'Accept: application/x-ndjson' -o "$WORK/events.ndjson" "$BASE/v1/jobs/$ID/events"
tail -1 "$WORK/events.ndjson" >"$WORK/last.ndjson"
if [ "$(jq -r .type "$WORK/last.ndjson")" = status ] && has_point_one "$WORK/last.ndjson" ':'; then
    ok "the final status event (NDJSON) prints tolBoundary 0.1"
else
    not_ok "the final status event (NDJSON) prints tolBoundary 0.1" "$(cat "$WORK/last.ndjson")"
fi
hcurl -H 'Accept: text/event-stream' -o "$WORK/events.sse" "$BASE/v1/jobs/$ID/events"
grep -A1 '^event: status$' "$WORK/events.sse" | sed -n 's/^data: //p' >"$WORK/last.sse"
if [ -s "$WORK/last.sse" ] && has_point_one "$WORK/last.sse" ':' &&
    cmp -s <(jq -c 'del(.time)' "$WORK/last.sse") <(jq -c 'del(.time)' "$WORK/last.ndjson"); then
    ok "the final status event (SSE) is the NDJSON one, 0.1 included"
else
    not_ok "the final status event (SSE) prints tolBoundary 0.1" "$(cat "$WORK/events.sse")"
fi

if has_point_one "$SPOOL/jobs/$ID/status.json" ': '; then
    ok "the spool's status.json prints tolBoundary 0.1"
else
    not_ok "the spool's status.json prints tolBoundary 0.1" "$(cat "$SPOOL/jobs/$ID/status.json")"
fi

# a problem document with an array: the same layout as the one writer's
code=$(hcurl -o "$WORK/problem.json" -w '%{http_code}' -F "template=@$DISK" -F "target_mesh=@$BOX" \
    -F "target_sol=@$BOXSOL" -F 'params={"max_iter": 0.5}' "$BASE/v1/jobs")
if [ "$code" = 422 ] && jq -e '."invalid-params"[0].name' "$WORK/problem.json" >/dev/null &&
    grep -q '^  "invalid-params": \[{$' "$WORK/problem.json"; then
    ok "a problem document is printed by the same writer (invalid-params: [{)"
else
    not_ok "a problem document is printed by the same writer" "$code" "$(cat "$WORK/problem.json")"
fi

reports_clean && ok "no sanitizer report" || not_ok "no sanitizer report"
stop_daemon
echo "1..$n"
