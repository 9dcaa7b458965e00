#!/usr/bin/env bash
# run.sh: weight 0.5 seconds 25
# State and disk agree when the spool fills up (issue 8): on a small tmpfs
# spool mounted by the test (root), a cancel whose record cannot be
# written is refused (503) and changes nothing (durable first); the daemon
# reports unready (/readyz 503, submissions 503) and starts nothing,
# retries each second; a restart while the disk is still full keeps the
# interrupted job queued in memory and starts nothing; once space is back
# the records say what clients were told: the interrupted job runs again
# as after any restart, a job cancelled with space stays dismissed after a
# restart (it does not run again); a run that ends while the spool is
# full is held, not shown final, until its record is written (below).
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
FOLLOWERS=() # background event streams (curl), stopped at the end
stop_followers() {
    local pid
    for pid in "${FOLLOWERS[@]}"; do kill "$pid" 2>/dev/null; done
    for pid in "${FOLLOWERS[@]}"; do wait "$pid" 2>/dev/null; done
    FOLLOWERS=()
}
trap 'stop_followers; umount "$MNT" 2>/dev/null; cleanup' EXIT
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
# --- the end of a run while the spool is full ------------------------------
# A run that ends while its final record cannot be written is not shown
# final: it stays "running" (message "ending: ..."), its stream gets no
# "finished" and no final status, its results stay, the daemon is unready
# and refuses submissions (503 + Retry-After, problem+json); when space is
# back the record is written and only then the job is successful and its
# stream ends with "finished" then the final status.  A restart while the
# record is still unwritten ends the job from its complete results (no
# second run) once the record can be written.  To make the run end while
# the disk is full (and not fail on its own results), the daemon runs a
# gate worker: the real worker runs and publishes its results, then the
# gate waits for the test (which fills the spool meanwhile) before it
# exits; the daemon records a run's end when its worker has exited.
stop_daemon
GATE=$WORK/gate
mkdir -p "$GATE"
cat >"$WORK/gate-worker.sh" <<EOF
#!/bin/sh
"$BIN/shapematch-worker" "\$@"
rc=\$?
id=\$(basename "\$1")
touch "$GATE/ended-\$id"
i=0
while [ ! -e "$GATE/go-\$id" ] && [ \$i -lt 600 ]; do sleep 0.05; i=\$((i + 1)); done
exit \$rc
EOF
chmod +x "$WORK/gate-worker.sh"
SPOOL=$MNT/end-spool
start_daemon end --workers 1 --keepalive 1 --worker "$WORK/gate-worker.sh" ||
    { not_ok "a daemon with a gate worker starts"; exit 1; }
ok "a daemon with a gate worker starts on a fresh spool on the tmpfs"

PARAMS=$(quick_params 20)
ready_code() { curl -sS --max-time 5 -o "$WORK/ready.json" -w '%{http_code}' "$BASE/readyz"; }
on_disk() { jq -r ".$2" "$SPOOL/jobs/$1/status.json"; }
# runs of job ID started by the daemon (all starts of this suite's log)
starts() { grep -c "\"event\":\"job_started\".*\"job\":\"$1\"" "$DLOG"; }
# ends of job ID held so far (job_ending_held lines), and whether more than N
helds() { grep -c "\"event\":\"job_ending_held\".*\"job\":\"$1\"" "$DLOG"; }
held_more() { [ "$(helds "$1")" -gt "$2" ]; }
follow() { # ID FILE: an NDJSON follower of the job's events, in the background
    curl -sS -N --max-time $((60 * SLOW)) -H 'Accept: application/x-ndjson' \
        "$BASE/v1/jobs/$1/events" >"$2" 2>/dev/null &
    FOLLOWERS+=($!)
}
# the types of the events in FILE, repeats counted: "accepted started progress*70 finished status "
event_types() { jq -r .type "$1" 2>/dev/null | uniq -c | awk '{ printf "%s%s ", $2, ($1 > 1 ? "*" $1 : "") }'; }
fill() { dd if=/dev/zero of="$MNT/fill" bs=64k >/dev/null 2>&1; }

# finish_while_full ID: the job's run is over (results published, its
# gate worker waiting), the spool is filled, the worker exits; 0 when the
# daemon then held the end
finish_while_full() {
    local before
    before=$(helds "$1")
    poll 30 test -e "$GATE/ended-$1" || return 1
    fill
    touch "$GATE/go-$1"
    poll 10 held_more "$1" "$before"
}

# --- the end is held while the record cannot be written -----------------
J=$(submit "$DISK" "$BOX" "$BOXSOL" "$PARAMS")
follow "$J" "$WORK/f1.ndjson"
if [ -n "$J" ] && finish_while_full "$J"; then
    ok "a run ends while the spool is full: its end is held (job_ending_held)"
else
    not_ok "the end is held" "job $J: $(job_state "$J")" "$(grep -E 'job_|store_error' "$DLOG" | tail -5)"
fi
code=$(ready_code)
hcurl -D "$WORK/sub.h" -o "$WORK/sub.json" -F "template=@$DISK" -F "target_mesh=@$BOX" \
    -F "target_sol=@$BOXSOL" -F "params=$(quick_params 5)" "$BASE/v1/jobs" >/dev/null
if state_is "$J" running && hcurl "$BASE/v1/jobs/$J" | jq -e '.message | test("^ending")' >/dev/null &&
    [ "$(on_disk "$J" status)" = running ] && [ -f "$SPOOL/jobs/$J/results/summary.json" ] &&
    [ "$code" = 503 ] && jq -e '.detail | test("could not be written")' "$WORK/ready.json" >/dev/null &&
    grep -q '^HTTP/1.1 503' "$WORK/sub.h" && grep -qi '^Retry-After: ' "$WORK/sub.h" &&
    grep -qi '^Content-Type: application/problem+json' "$WORK/sub.h"; then
    ok "held: still running ($(hcurl "$BASE/v1/jobs/$J" | jq -r .message | cut -c1-40)...), running on disk, results kept, /readyz 503, submissions 503 + Retry-After"
else
    not_ok "held: not final, unready" "state $(job_state "$J"), on disk $(on_disk "$J" status), /readyz $code" \
        "$(cat "$WORK/ready.json")" "$(head -1 "$WORK/sub.h") $(cat "$WORK/sub.json")"
fi
sleep 1.2 # one retry of the supervisor passes: the spool still refuses
types=$(event_types "$WORK/f1.ndjson")
c=$(hcurl -o "$WORK/del.json" -w '%{http_code}' -X DELETE "$BASE/v1/jobs/$J")
if state_is "$J" running && [[ $types != *finished* ]] && [[ $types != *status* ]] &&
    hcurl "$BASE/metrics" | grep -q '^shapematch_jobs_finished_total{state="successful"} 0$' &&
    [ "$c" = 503 ] && state_is "$J" running; then
    ok "after a retry on the full spool: still running, the follower got no final event ($types), nothing counted; DELETE 503"
else
    not_ok "nothing published while held" "state $(job_state "$J"), follower: $types, DELETE $c" "$(cat "$WORK/del.json")"
fi
rm -f "$MNT/fill"
if poll 10 state_is "$J" successful && [ "$(on_disk "$J" status)" = successful ] &&
    poll 5 test "$(ready_code)" = 200; then
    ok "space back: the record is written, then the job is successful; /readyz 200"
else
    not_ok "space back: published" "state $(job_state "$J"), on disk $(on_disk "$J" status)"
fi
types=$(event_types "$WORK/f1.ndjson")
if poll 5 test "$(jq -r .type "$WORK/f1.ndjson" 2>/dev/null | tail -1)" = status &&
    [[ $(event_types "$WORK/f1.ndjson") == *" finished status " ]] &&
    [ "$(jq -r 'select(.type == "status") | .status' "$WORK/f1.ndjson")" = successful ] &&
    hcurl "$BASE/metrics" | grep -q '^shapematch_jobs_finished_total{state="successful"} 1$'; then
    ok "the stream ends with finished then status successful, after the record: $(event_types "$WORK/f1.ndjson")"
else
    not_ok "the stream ends after the record" "$(event_types "$WORK/f1.ndjson")"
fi

# --- a restart while the end is held: ended from the results, no rerun --
K=$(submit "$DISK" "$BOX" "$BOXSOL" "$PARAMS")
if [ -n "$K" ] && finish_while_full "$K" && stop_daemon; then
    ok "a second run ends on the full spool (held), the daemon stops"
else
    not_ok "second held end and stop" "job $K: $(on_disk "$K" status)"
fi
if [ "$(on_disk "$K" status)" = running ] &&
    start_daemon end --workers 1 --keepalive 1 --worker "$WORK/gate-worker.sh" &&
    [ "$(helds "$K")" = 2 ] && state_is "$K" running && [ "$(ready_code)" = 503 ] &&
    [ "$(starts "$K")" = 1 ] && [ -f "$SPOOL/jobs/$K/results/summary.json" ] && state_is "$J" successful; then
    ok "restarted on the full spool: the run's complete results end it, held until recorded (running, /readyz 503, not run again)"
else
    not_ok "restart with the end unwritten" "state $(job_state "$K"), on disk $(on_disk "$K" status), starts $(starts "$K")" \
        "$(grep -E 'job_|store_error' "$DLOG" | tail -5)"
fi
follow "$K" "$WORK/f2.ndjson"
sleep 0.3
rm -f "$MNT/fill"
if poll 10 state_is "$K" successful && [ "$(on_disk "$K" status)" = successful ] &&
    poll 5 test "$(jq -r .type "$WORK/f2.ndjson" 2>/dev/null | tail -1)" = status &&
    [[ $(event_types "$WORK/f2.ndjson") == *" finished status " ]]; then
    ok "space back: successful from the results, the stream ends with finished then status: $(hcurl "$BASE/v1/jobs/$K" | jq -r .message)"
else
    not_ok "recovered end published" "state $(job_state "$K"), events $(event_types "$WORK/f2.ndjson")"
fi
if stop_daemon && start_daemon end --workers 1 && state_is "$J" successful && state_is "$K" successful &&
    [ "$(starts "$J")" = 1 ] && [ "$(starts "$K")" = 1 ] && [ "$(on_disk "$J" attempt)" = 1 ] &&
    [ "$(on_disk "$K" attempt)" = 1 ]; then
    ok "after a restart both stay successful, each ran once (attempt 1)"
else
    not_ok "durable and run once" "J $(job_state "$J") starts $(starts "$J"), K $(job_state "$K") starts $(starts "$K")"
fi
stop_followers
if stop_daemon && reports_clean; then
    ok "SIGTERM stops the daemon, no sanitizer report"
else
    not_ok "clean stop"
fi
echo "1..$n"
