#!/usr/bin/env bash
# The end of a run while the spool is full (issue 8, "state and disk
# agree"; sibling of daemon_diskfull.sh, same tmpfs set-up as root): a job
# whose worker finishes while its final record cannot be written is not
# shown final — it stays "running" (message "ending: ..."), its stream
# gets no "finished" and no final status, its results stay, the daemon is
# unready (/readyz 503) and refuses submissions (503 + Retry-After,
# problem+json); when space is back the record is written and only then
# the job is successful, its stream ends with "finished" then the final
# status.  A restart while the record is still unwritten ends the job from
# its complete results (no second run) once the record can be written.
#
# To make the run end while the disk is full (and not fail on its own
# results), the daemon runs a gate worker: the real worker runs and
# publishes its results, then the gate waits for the test (which fills
# the spool meanwhile) before it exits, and the daemon records a run's end
# when its worker has exited.
source "$(dirname "$0")/lib.sh"

if [ "$(id -u)" != 0 ]; then
    skip "the end of a run on a full tmpfs spool (needs root to mount)"
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
FOLLOWERS=()
stop_followers() {
    local pid
    for pid in "${FOLLOWERS[@]}"; do kill "$pid" 2>/dev/null; done
    for pid in "${FOLLOWERS[@]}"; do wait "$pid" 2>/dev/null; done
    FOLLOWERS=()
}
trap 'stop_followers; umount "$MNT" 2>/dev/null; cleanup' EXIT
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
SPOOL=$MNT/spool
start_daemon end --workers 1 --keepalive 1 --worker "$WORK/gate-worker.sh" ||
    { not_ok "the daemon starts"; exit 1; }
ok "the daemon starts on a 16 MiB tmpfs spool"

PARAMS=$(quick_params 20)
ready_code() { curl -sS --max-time 5 -o "$WORK/ready.json" -w '%{http_code}' "$BASE/readyz"; }
ondisk() { jq -r ".$2" "$SPOOL/jobs/$1/status.json"; }
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
    [ "$(ondisk "$J" status)" = running ] && [ -f "$SPOOL/jobs/$J/results/summary.json" ] &&
    [ "$code" = 503 ] && jq -e '.detail | test("could not be written")' "$WORK/ready.json" >/dev/null &&
    grep -q '^HTTP/1.1 503' "$WORK/sub.h" && grep -qi '^Retry-After: ' "$WORK/sub.h" &&
    grep -qi '^Content-Type: application/problem+json' "$WORK/sub.h"; then
    ok "held: still running ($(hcurl "$BASE/v1/jobs/$J" | jq -r .message | cut -c1-40)...), running on disk, results kept, /readyz 503, submissions 503 + Retry-After"
else
    not_ok "held: not final, unready" "state $(job_state "$J"), on disk $(ondisk "$J" status), /readyz $code" \
        "$(cat "$WORK/ready.json")" "$(head -1 "$WORK/sub.h") $(cat "$WORK/sub.json")"
fi
sleep 1.2 # one retry of the supervisor passes: the spool still refuses
types=$(event_types "$WORK/f1.ndjson")
if state_is "$J" running && [[ $types != *finished* ]] && [[ $types != *status* ]] &&
    hcurl "$BASE/metrics" | grep -q '^shapematch_jobs_finished_total{state="successful"} 0$'; then
    ok "after a retry on the full spool: still running, the follower got no final event ($types), nothing counted"
else
    not_ok "nothing published while held" "state $(job_state "$J"), follower: $types"
fi
rm -f "$MNT/fill"
if poll 10 state_is "$J" successful && [ "$(ondisk "$J" status)" = successful ] &&
    poll 5 test "$(ready_code)" = 200; then
    ok "space back: the record is written, then the job is successful; /readyz 200"
else
    not_ok "space back: published" "state $(job_state "$J"), on disk $(ondisk "$J" status)"
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
    not_ok "second held end and stop" "job $K: $(ondisk "$K" status)"
fi
if [ "$(ondisk "$K" status)" = running ] &&
    start_daemon end --workers 1 --keepalive 1 --worker "$WORK/gate-worker.sh" &&
    [ "$(helds "$K")" = 2 ] && state_is "$K" running && [ "$(ready_code)" = 503 ] &&
    [ "$(starts "$K")" = 1 ] && [ -f "$SPOOL/jobs/$K/results/summary.json" ] && state_is "$J" successful; then
    ok "restarted on the full spool: the run's complete results end it, held until recorded (running, /readyz 503, not run again)"
else
    not_ok "restart with the end unwritten" "state $(job_state "$K"), on disk $(ondisk "$K" status), starts $(starts "$K")" \
        "$(grep -E 'job_|store_error' "$DLOG" | tail -5)"
fi
follow "$K" "$WORK/f2.ndjson"
sleep 0.3
rm -f "$MNT/fill"
if poll 10 state_is "$K" successful && [ "$(ondisk "$K" status)" = successful ] &&
    poll 5 test "$(jq -r .type "$WORK/f2.ndjson" 2>/dev/null | tail -1)" = status &&
    [[ $(event_types "$WORK/f2.ndjson") == *" finished status " ]]; then
    ok "space back: successful from the results, the stream ends with finished then status: $(hcurl "$BASE/v1/jobs/$K" | jq -r .message)"
else
    not_ok "recovered end published" "state $(job_state "$K"), events $(event_types "$WORK/f2.ndjson")"
fi
if stop_daemon && start_daemon end --workers 1 && state_is "$J" successful && state_is "$K" successful &&
    [ "$(starts "$J")" = 1 ] && [ "$(starts "$K")" = 1 ] && [ "$(ondisk "$J" attempt)" = 1 ] &&
    [ "$(ondisk "$K" attempt)" = 1 ]; then
    ok "after a restart both stay successful, each ran once (attempt 1)"
else
    not_ok "durable and run once" "J $(job_state "$J") starts $(starts "$J"), K $(job_state "$K") starts $(starts "$K")"
fi
stop_followers
if stop_daemon && reports_clean && ! grep -lE 'Sanitizer|runtime error' "$SPOOL"/jobs/*/worker.log 2>/dev/null | grep -q .; then
    ok "SIGTERM stops the daemon, no sanitizer report"
else
    not_ok "clean stop"
fi
echo "1..$n"
