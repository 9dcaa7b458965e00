#!/usr/bin/env bash
# State and disk agree when the spool fills up (issue 8): on a small tmpfs
# spool mounted by the test (root), a cancel whose record cannot be
# written is refused (503) and changes nothing (durable first); the daemon
# reports unready (/readyz 503, submissions 503) and starts nothing,
# retries each second; a restart while the disk is still full keeps the
# interrupted job queued in memory and starts nothing; once space is back
# the records say what clients were told: the interrupted job runs again
# as after any restart, a job cancelled with space stays dismissed after a
# restart (it does not run again).
source "$(dirname "$0")/lib.sh"

if [ "$(id -u)" != 0 ]; then
    skip "disk full on a tmpfs spool (needs root to mount)"
    echo "1..$n"
    exit 0
fi
if ! make_case; then
    not_ok "gmsh builds the test meshes" "$(tail -5 "$WORK/case/gmsh.log")"
    exit 1
fi
ok "gmsh builds the test meshes"

MNT=$WORK/tmpfs
mkdir -p "$MNT"
if ! mount -t tmpfs -o size=64m tmpfs "$MNT"; then
    not_ok "a 64 MiB tmpfs is mounted"
    exit 1
fi
trap 'umount "$MNT" 2>/dev/null; cleanup' EXIT
ok "a 64 MiB tmpfs is mounted"
SPOOL=$MNT/spool
start_daemon full --workers 1 --keepalive 1 || { not_ok "the daemon starts"; exit 1; }
ok "the daemon starts on the tmpfs spool"

A=$(submit "$FINE" "$BOX" "$BOXSOL" "$(endless_params)")
if [ -n "$A" ] && wait_state "$A" running 30; then
    ok "a long job runs"
else
    not_ok "a long job runs" "$(cat "$WORK/submit.out")"
fi
Q=$(submit "$DISK" "$BOX" "$BOXSOL" "$(quick_params 5)")
dd if=/dev/zero of="$MNT/fill" bs=64k >/dev/null 2>&1
# durable first: a cancel that cannot be recorded is refused, nothing changes
c=$(hcurl -o "$WORK/del.json" -w '%{http_code}' -X DELETE "$BASE/v1/jobs/$A")
told=$(job_state "$A")
ondisk=$(jq -r .status "$SPOOL/jobs/$A/status.json")
rc=$(curl -sS --max-time 5 -o "$WORK/ready.json" -w '%{http_code}' "$BASE/readyz")
if [ "$c" = 503 ] && jq -e '.detail | test("cannot be written")' "$WORK/del.json" >/dev/null &&
    [ "$told" = running ] && [ "$ondisk" = running ] && [ "$rc" = 503 ] &&
    jq -e '.detail | test("could not be written")' "$WORK/ready.json" >/dev/null; then
    ok "disk full: the cancel is refused (503) and the job stays running, in memory and on disk; unready: $(jq -r .detail "$WORK/ready.json")"
else
    not_ok "disk full: cancel refused, unready" "DELETE $c, told $told, on disk $ondisk, /readyz $rc" \
        "$(cat "$WORK/del.json")" "$(cat "$WORK/ready.json")"
fi
c=$(hcurl -o /dev/null -w '%{http_code}' -X DELETE "$BASE/v1/jobs/$Q")
if [ "$c" = 503 ] && state_is "$Q" accepted && [ "$(jq -r .status "$SPOOL/jobs/$Q/status.json")" = accepted ]; then
    ok "disk full: the cancel of a queued job is refused too (503, still accepted)"
else
    not_ok "disk full: queued cancel refused" "DELETE $c, $(job_state "$Q")"
fi
c=$(curl -sS --max-time 10 -o "$WORK/sub.json" -w '%{http_code}' -F "template=@$DISK" -F "target_mesh=@$BOX" \
    -F "target_sol=@$BOXSOL" -F "params=$(quick_params 5)" "$BASE/v1/jobs")
if [ "$c" = 503 ] || [ "$c" = 507 ]; then
    ok "a submission while the spool is full: $c"
else
    not_ok "a submission while the spool is full" "code $c" "$(cat "$WORK/sub.json")"
fi
sleep 1.5
if [ -z "$Q" ] || state_is "$Q" accepted; then
    ok "a queued job is not started while records cannot be written"
else
    not_ok "a queued job is not started" "$(job_state "$Q")"
fi

# a restart while the disk is still full: the interrupted job is queued
# again in memory (its record cannot be written), the daemon is unready
# and starts nothing; no job is lost or run against what clients saw
stop_daemon
if start_daemon full --workers 1 --keepalive 1; then
    ok "the daemon starts again on the full spool"
else
    not_ok "the daemon starts on the full spool"
    exit 1
fi
rc=$(curl -sS --max-time 5 -o "$WORK/ready2.json" -w '%{http_code}' "$BASE/readyz")
sleep 1.5
if [ "$rc" = 503 ] && state_is "$A" accepted && state_is "$Q" accepted &&
    [ "$(jq -r .status "$SPOOL/jobs/$A/status.json")" = running ] &&
    ! grep -q '"event":"job_started"' <(sed -n "$(grep -n '"event":"listening"' "$DLOG" | tail -1 | cut -d: -f1),\$p" "$DLOG"); then
    ok "restarted on a full spool: unready (503), both jobs queued in memory, none started"
else
    not_ok "restart on a full spool" "/readyz $rc, A $(job_state "$A"), Q $(job_state "$Q")" \
        "$(grep -E 'job_started|recovery|requeued' "$DLOG" | tail -5)"
fi

rm -f "$MNT/fill"
ready() { [ "$(curl -sS --max-time 5 -o /dev/null -w '%{http_code}' "$BASE/readyz")" = 200 ]; }
if poll 10 ready && grep -q '"event":"spool_writable"' "$DLOG"; then
    ok "space back: the records are written, /readyz 200 again"
else
    not_ok "space back: ready again" "$(jq -r .status "$SPOOL/jobs/$A/status.json")"
fi
if wait_state "$A" running 30 && [ "$(jq .attempt "$SPOOL/jobs/$A/status.json")" = 2 ]; then
    ok "the interrupted job runs again (attempt 2), as a restart does"
else
    not_ok "the interrupted job runs again" "$(job_state "$A")"
fi
c=$(hcurl -o /dev/null -w '%{http_code}' -X DELETE "$BASE/v1/jobs/$A")
if [ "$c" = 200 ] && poll 10 test "$(jq -r .status "$SPOOL/jobs/$A/status.json")" = dismissed; then
    ok "with space, the cancel is recorded (dismissed on disk)"
else
    not_ok "cancel with space" "DELETE $c, on disk $(jq -r .status "$SPOOL/jobs/$A/status.json")"
fi
if [ -n "$Q" ] && wait_final "$Q" 60 && state_is "$Q" successful; then
    ok "the queued job runs once the spool takes writes"
else
    not_ok "the queued job runs afterwards" "$(job_state "$Q")"
fi
if stop_daemon && start_daemon full --workers 1 && state_is "$A" dismissed; then
    ok "after a restart the job is as clients were told (dismissed), not run again"
else
    not_ok "no flip after a restart" "$(job_state "$A")"
fi
# a torn status.json (external damage): quarantined and reported, not lost
stop_daemon
if [ -n "$Q" ]; then
    head -c 40 "$SPOOL/jobs/$Q/status.json" >"$WORK/torn" && cp "$WORK/torn" "$SPOOL/jobs/$Q/status.json"
fi
if start_daemon full --workers 1 && state_is "$Q" failed &&
    hcurl "$BASE/v1/jobs/$Q" | jq -e '.message | test("^record damaged")' >/dev/null &&
    ls "$SPOOL/quarantine" | grep -q "^$Q-" && grep -q "\"event\":\"job_quarantined\".*$Q" "$DLOG" &&
    hcurl "$BASE/metrics" | grep -q '^shapematch_records_quarantined 1$' && state_is "$A" dismissed; then
    ok "a torn status.json: quarantined, logged, in /metrics, the job answers failed: $(hcurl "$BASE/v1/jobs/$Q" | jq -r .message)"
else
    not_ok "a torn status.json is quarantined" "$(job_state "$Q")" "$(grep quarantin "$DLOG")"
fi
if hcurl -o /dev/null -X DELETE "$BASE/v1/jobs/$Q" && [ "$(job_state "$Q")" = 404 ]; then
    ok "the damaged job can be deleted"
else
    not_ok "the damaged job can be deleted" "$(job_state "$Q")"
fi
if stop_daemon && reports_clean; then
    ok "SIGTERM stops the daemon, no sanitizer report"
else
    not_ok "clean stop"
fi
echo "1..$n"
