#!/usr/bin/env bash
# shapematchd at the integer edges (issue 8): event sequence numbers
# (?after, Last-Event-ID), list offsets and limits and Content-Length at
# and beyond 2^63 are answered at once (400 / 413 problem+json naming the
# parameter) while /healthz keeps answering and SIGTERM still stops the
# daemon; a spool record with "order": INT64_MAX followed by a submission
# and a restart loses no job; a record with an attempt count out of range
# is quarantined as damaged (SPOOL/quarantine/, logged, /metrics, the job
# answers failed "record damaged").
source "$(dirname "$0")/lib.sh"

if ! make_case; then
    not_ok "gmsh builds the test meshes" "$(tail -5 "$WORK/case/gmsh.log")"
    exit 1
fi
ok "gmsh builds the test meshes"

BIG=9223372036854775807     # INT64_MAX: after + 1 overflowed
HUGE=99999999999999999999999 # beyond UINT64_MAX
JSMAX=9007199254740991      # 2^53 - 1: the largest accepted

start_daemon edges --workers 1 || { not_ok "the daemon starts"; exit 1; }
ok "the daemon starts"
A=$(submit "$DISK" "$BOX" "$BOXSOL" "$(quick_params 20)")
if [ -n "$A" ] && wait_final "$A" 60 && state_is "$A" successful; then
    ok "a quick job completes"
else
    not_ok "a quick job completes" "$(cat "$WORK/submit.out")"
fi

# code_of URL [CURL ARGS...]: the HTTP status within a few seconds (000 on
# a timeout); the body goes to $WORK/edge.out
code_of() {
    local url=$1
    shift
    curl -sS --max-time $((5 * SLOW)) -o "$WORK/edge.out" -w '%{http_code}' "$@" "$url" 2>/dev/null
}
healthy() { [ "$(code_of "$BASE/healthz")" = 200 ]; }
# problem CODE PARAM: the last reply was that status, problem+json, and
# its detail names the parameter
problem() {
    jq -e --arg p "$2" --argjson s "$1" '.status == $s and (.detail | startswith($p + ":"))' \
        "$WORK/edge.out" >/dev/null 2>&1
}

for v in "$BIG" "$HUGE" -1 1x; do
    c=$(code_of "$BASE/v1/jobs/$A/events?after=$v")
    if [ "$c" = 400 ] && problem 400 after && healthy; then
        ok "events?after=$v: 400 naming 'after' at once, /healthz answers"
    else
        not_ok "events?after=$v: 400" "code $c" "$(cat "$WORK/edge.out")"
    fi
    c=$(code_of "$BASE/v1/jobs/$A/events" -H "Last-Event-ID: $v")
    if [ "$c" = 400 ] && problem 400 Last-Event-ID && healthy; then
        ok "Last-Event-ID: $v: 400 naming 'Last-Event-ID' at once, /healthz answers"
    else
        not_ok "Last-Event-ID: $v: 400" "code $c" "$(cat "$WORK/edge.out")"
    fi
done
# the largest accepted number replays nothing: the final status only
c=$(code_of "$BASE/v1/jobs/$A/events?after=$JSMAX" -H 'Accept: application/x-ndjson')
if [ "$c" = 200 ] && [ "$(wc -l <"$WORK/edge.out")" = 1 ] &&
    [ "$(jq -r .type "$WORK/edge.out")" = status ]; then
    ok "events?after=2^53-1 of a finished job: only the final status event"
else
    not_ok "events?after=2^53-1" "code $c" "$(cat "$WORK/edge.out")"
fi
c=$(code_of "$BASE/v1/jobs/$A/events" -H "Last-Event-ID: $JSMAX" -H 'Accept: text/event-stream')
if [ "$c" = 200 ] && grep -q '^event: status' "$WORK/edge.out" && ! grep -q '^id:' "$WORK/edge.out"; then
    ok "Last-Event-ID: 2^53-1 of a finished job: only the final status event"
else
    not_ok "Last-Event-ID: 2^53-1" "code $c" "$(cat "$WORK/edge.out")"
fi

for v in "$BIG" "$HUGE" -5; do
    c=$(code_of "$BASE/v1/jobs?offset=$v")
    if [ "$c" = 400 ] && problem 400 offset && healthy; then
        ok "jobs?offset=$v: 400 naming 'offset', /healthz answers"
    else
        not_ok "jobs?offset=$v: 400" "code $c" "$(cat "$WORK/edge.out")"
    fi
done
c=$(code_of "$BASE/v1/jobs?offset=$JSMAX&limit=1000")
if [ "$c" = 200 ] && jq -e '.numberReturned == 0 and .numberMatched == 1 and
        ([.links[] | select(.rel == "next")] | length) == 0 and
        ([.links[] | select(.rel == "prev") | .href] == ["/v1/jobs?limit=1000&offset=9007199254740991" | sub("9007199254740991"; "9007199254739991")])' \
    "$WORK/edge.out" >/dev/null; then
    ok "jobs?offset=2^53-1: an empty page, no next link, prev link without overflow"
else
    not_ok "jobs?offset=2^53-1" "code $c" "$(cat "$WORK/edge.out")"
fi
for v in "$BIG" "$HUGE" 0 1001; do
    c=$(code_of "$BASE/v1/jobs?limit=$v")
    if [ "$c" = 400 ] && problem 400 limit; then
        ok "jobs?limit=$v: 400 naming 'limit'"
    else
        not_ok "jobs?limit=$v: 400" "code $c" "$(cat "$WORK/edge.out")"
    fi
done
c=$(code_of "$BASE/v1/jobs" -X POST -H "Content-Length: $HUGE" -H 'Content-Type: multipart/form-data; boundary=x')
if [ "$c" = 413 ] && healthy; then
    ok "Content-Length beyond 2^64: 413 at once, /healthz answers"
else
    not_ok "Content-Length beyond 2^64: 413" "code $c" "$(cat "$WORK/edge.out")"
fi
if healthy && [ "$(code_of "$BASE/v1/jobs/$A")" = 200 ] && [ "$(code_of "$BASE/readyz")" = 200 ]; then
    ok "after all of it status, /readyz and /healthz answer"
else
    not_ok "the daemon still answers"
fi
if stop_daemon; then
    ok "SIGTERM stops the daemon (exit 0)"
else
    not_ok "SIGTERM stops the daemon"
fi

# ------------------------------------------------- spool numbers at the edge
REC=$SPOOL/jobs/$A/status.json
# (sed, not jq: jq writes integers beyond 2^53 as floats)
sed -E "s/\"order\": *[0-9]+/\"order\": $BIG/" "$REC" >"$REC.new" && mv "$REC.new" "$REC"
start_daemon edges --workers 1 || { not_ok "the daemon restarts"; exit 1; }
B=$(submit "$DISK" "$BOX" "$BOXSOL" "$(quick_params 20)")
if [ -n "$B" ] && wait_final "$B" 60 && state_is "$B" successful && state_is "$A" successful; then
    ok "a record with order INT64_MAX loads; the next job is accepted and runs"
else
    not_ok "order INT64_MAX, then a submission" "$(cat "$WORK/submit.out")"
fi
border=$(sed -nE 's/.*"order": *([0-9]+).*/\1/p' "$SPOOL/jobs/$B/status.json")
if [ "$border" = "$BIG" ]; then
    ok "the next job's order saturates at INT64_MAX (no overflow)"
else
    not_ok "the next order saturates" "order $border"
fi
stop_daemon
start_daemon edges --workers 1 || { not_ok "the daemon restarts again"; exit 1; }
ids=$(curl -sS "$BASE/v1/jobs" | jq -r '[.jobs[].jobID] | join(" ")')
if [ "$ids" = "$A $B" ] && state_is "$A" successful && state_is "$B" successful; then
    ok "after the restart both jobs are there, in submission order"
else
    not_ok "no job lost at the restart" "jobs: $ids"
fi
stop_daemon

# an attempt count out of range: the record is damaged, quarantined and
# logged; the job answers failed "record damaged"
sed -E 's/"attempt": *[0-9]+/"attempt": 99999999999/' "$SPOOL/jobs/$B/status.json" >"$WORK/rec" &&
    mv "$WORK/rec" "$SPOOL/jobs/$B/status.json"
start_daemon edges --workers 1 || { not_ok "the daemon starts with a damaged record"; exit 1; }
if state_is "$B" failed && hcurl "$BASE/v1/jobs/$B" | jq -e '.message | test("record damaged")' >/dev/null &&
    state_is "$A" successful && grep -q "\"event\":\"job_quarantined\".*$B.*bad attempt" "$DLOG" &&
    ls "$SPOOL/quarantine/" | grep -q "^$B-" &&
    hcurl "$BASE/metrics" | grep -q '^shapematch_records_quarantined 1$'; then
    ok "a record with attempt out of range is quarantined (logged, /metrics), answers failed, the others load"
else
    not_ok "attempt out of range" "$(job_state "$B")" "$(grep job_quarantined "$DLOG")"
fi
if stop_daemon; then
    ok "SIGTERM stops the daemon (exit 0)"
else
    not_ok "SIGTERM stops the daemon at the end"
fi
if reports_clean; then
    ok "no sanitizer report in the daemon or worker logs"
else
    not_ok "no sanitizer report" "$(grep -lE 'Sanitizer|runtime error' "$WORK"/*.log)"
fi
echo "1..$n"
