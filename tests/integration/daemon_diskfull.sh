#!/usr/bin/env bash
# State and disk agree when the spool fills up (issue 8): on a small tmpfs
# spool mounted by the test (root), a job cancelled while the disk is full
# cannot have its record written; the daemon then reports unready (/readyz
# 503, submissions 503) and starts nothing, retries the write each
# second, and once space is back the record on disk says what clients were
# told: after a restart the job is in the same state (it does not run
# again).
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
if ! mount -t tmpfs -o size=16m tmpfs "$MNT"; then
    not_ok "a 16 MiB tmpfs is mounted"
    exit 1
fi
trap 'umount "$MNT" 2>/dev/null; cleanup' EXIT
ok "a 16 MiB tmpfs is mounted"
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
hcurl -o /dev/null -X DELETE "$BASE/v1/jobs/$A"
told=$(job_state "$A")
ondisk=$(jq -r .status "$SPOOL/jobs/$A/status.json")
rc=$(curl -sS --max-time 5 -o "$WORK/ready.json" -w '%{http_code}' "$BASE/readyz")
if [ "$told" = dismissed ] && [ "$ondisk" = running ] && [ "$rc" = 503 ] &&
    jq -e '.detail | test("could not be written")' "$WORK/ready.json" >/dev/null; then
    ok "disk full: the cancel is not on disk and the daemon says unready: $(jq -r .detail "$WORK/ready.json")"
else
    not_ok "disk full: unready" "told $told, on disk $ondisk, /readyz $rc" "$(cat "$WORK/ready.json")"
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

rm -f "$MNT/fill"
ready() { [ "$(curl -sS --max-time 5 -o /dev/null -w '%{http_code}' "$BASE/readyz")" = 200 ]; }
if poll 10 ready && [ "$(jq -r .status "$SPOOL/jobs/$A/status.json")" = dismissed ] &&
    grep -q '"event":"spool_writable"' "$DLOG"; then
    ok "space back: the record is written, /readyz 200 again"
else
    not_ok "space back: ready again" "$(jq -r .status "$SPOOL/jobs/$A/status.json")"
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
