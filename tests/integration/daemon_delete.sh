#!/usr/bin/env bash
# Deletes are durable or refused (issue 8): on a read-only spool (a
# read-only bind mount over it, made by the test as root) DELETE answers
# 503 problem+json and the job stays visible, before and after a restart;
# once the spool is writable again the delete answers 200 and the job does
# not come back after a restart.  An event stream open while its job is
# cancelled and deleted ends with the job's final status event.
source "$(dirname "$0")/lib.sh"

if ! make_case; then
    not_ok "gmsh builds the test meshes" "$(tail -5 "$WORK/case/gmsh.log")"
    exit 1
fi
ok "gmsh builds the test meshes"

start_daemon del --workers 1 || { not_ok "the daemon starts"; exit 1; }
ok "the daemon starts"
A=$(submit "$DISK" "$BOX" "$BOXSOL" "$(quick_params 20)")
if [ -n "$A" ] && wait_final "$A" 60 && state_is "$A" successful; then
    ok "a quick job completes"
else
    not_ok "a quick job completes" "$(cat "$WORK/submit.out")"
fi
code() { curl -sS --max-time $((10 * SLOW)) -o "$WORK/reply.json" -w '%{http_code}' "$@"; }

MOUNTED=
unmount() { [ -n "$MOUNTED" ] && umount "$SPOOL" && MOUNTED=; }
trap 'unmount; cleanup' EXIT
if [ "$(id -u)" = 0 ] && mount --bind "$SPOOL" "$SPOOL" 2>/dev/null &&
    mount -o remount,ro,bind "$SPOOL" 2>/dev/null; then
    MOUNTED=1
    c=$(code -X DELETE "$BASE/v1/jobs/$A")
    if [ "$c" = 503 ] && jq -e '.status == 503 and (.detail | test("kept"))' "$WORK/reply.json" >/dev/null; then
        ok "DELETE on a read-only spool: 503 \"$(jq -r .detail "$WORK/reply.json")\""
    else
        not_ok "DELETE on a read-only spool: 503" "code $c" "$(cat "$WORK/reply.json")"
    fi
    if [ "$(code "$BASE/v1/jobs/$A")" = 200 ] && state_is "$A" successful; then
        ok "the refused job is still visible and unchanged"
    else
        not_ok "the refused job is still visible" "$(cat "$WORK/reply.json")"
    fi
    unmount
    if stop_daemon && start_daemon del --workers 1 && state_is "$A" successful; then
        ok "after a restart the refused job is there, as it was"
    else
        not_ok "after a restart the refused job is there"
    fi
else
    skip "read-only spool (needs root and bind mounts)"
    skip "the refused job is still visible"
    skip "after a restart the refused job is there"
fi
c=$(code -X DELETE "$BASE/v1/jobs/$A")
if [ "$c" = 200 ] && [ "$(code "$BASE/v1/jobs/$A")" = 404 ]; then
    ok "DELETE on a writable spool: 200, then 404"
else
    not_ok "DELETE on a writable spool" "code $c" "$(cat "$WORK/reply.json")"
fi
if stop_daemon && start_daemon del --workers 1 && [ "$(code "$BASE/v1/jobs/$A")" = 404 ] &&
    [ ! -e "$SPOOL/jobs/$A" ]; then
    ok "no resurrection after a restart"
else
    not_ok "no resurrection after a restart" "$(cat "$WORK/reply.json")"
fi

# a follower of a running job that is cancelled and at once deleted
B=$(submit "$FINE" "$BOX" "$BOXSOL" "$(endless_params)")
if [ -n "$B" ] && wait_state "$B" running 30; then
    hcurl -N -H 'Accept: application/x-ndjson' "$BASE/v1/jobs/$B/events" >"$WORK/follow.ndjson" 2>/dev/null &
    FPID=$!
    poll 10 grep -q '"type":"started"' "$WORK/follow.ndjson"
    curl -sS --max-time 10 -o /dev/null -X DELETE "$BASE/v1/jobs/$B" -o /dev/null -X DELETE "$BASE/v1/jobs/$B"
    gone() { [ "$(code "$BASE/v1/jobs/$B")" = 404 ]; }
    poll 10 gone || not_ok "the job is gone after cancel + delete" "$(cat "$WORK/reply.json")"
    for ((i = 0; i < 100 * SLOW; i++)); do kill -0 "$FPID" 2>/dev/null || break; sleep 0.1; done
    if ! kill -0 "$FPID" 2>/dev/null && [ "$(tail -1 "$WORK/follow.ndjson" | jq -r .type)" = status ] &&
        [ "$(tail -1 "$WORK/follow.ndjson" | jq -r .status)" = dismissed ]; then
        ok "the stream of a cancelled and deleted job ends with its final status: $(tail -1 "$WORK/follow.ndjson" | jq -c '{type, status, message}')"
    else
        kill "$FPID" 2>/dev/null
        not_ok "the stream ends with the final status" "$(tail -3 "$WORK/follow.ndjson")"
    fi
else
    not_ok "a long job starts" "$(cat "$WORK/submit.out")"
fi

if stop_daemon && reports_clean; then
    ok "SIGTERM stops the daemon, no sanitizer report"
else
    not_ok "clean stop"
fi
echo "1..$n"
