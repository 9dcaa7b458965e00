#!/usr/bin/env bash
# run.sh: weight 0.5 seconds 30
# shapematchd under faults and limits: kill -9 of the daemon while one job
# runs and two wait (restart: all three complete, workers died with the
# daemon); kill -9 of a worker (job failed with the signal, the next job
# runs); wall-time and CPU limits; graceful shutdown (running jobs finish
# within the grace, or stay queued and run again at the next start; 503
# for new jobs meanwhile); retention; keepalives on idle event streams.
source "$(dirname "$0")/lib.sh"

if ! make_case; then
    not_ok "gmsh builds the test meshes" "$(tail -5 "$WORK/case/gmsh.log")"
    exit 1
fi
ok "gmsh builds the test meshes"

events_of() { curl -sS --max-time $((30 * SLOW)) "$BASE/v1/jobs/$1/events"; }
message_of() { curl -sS "$BASE/v1/jobs/$1" | jq -r .message; }
pid_gone() { ! kill -0 "$1" 2>/dev/null; }

# ------------------------------------------- kill -9 of the daemon
# Quick jobs may finish before the kill: a worker that waits a second
# before it execs the real one keeps the first job running long enough,
# whatever the speed of the machine.
cat >"$WORK/slow-worker.sh" <<EOF
#!/bin/sh
sleep 1
exec "$BIN/shapematch-worker" "\$@"
EOF
chmod +x "$WORK/slow-worker.sh"
start_daemon crash --workers 1 --worker "$WORK/slow-worker.sh" || { not_ok "daemon starts"; exit 1; }
# A runs its 300 iterations whatever the stall rule says: it must still be
# running when the daemon is killed, however fast this machine is.
A=$(submit "$DISK" "$BOX" "$BOXSOL" "$BALL_PARAMS, \"max_iter\": 300, \"tol_step\": 1e-15, \"tol_stall\": 0}")
B=$(submit "$DISK" "$BOX" "$BOXSOL" "$(quick_params 100)")
C=$(submit "$DISK" "$BOX" "$BOXSOL" "$(quick_params 100)")
poll 20 state_is "$A" running
wpid=$(worker_pid "$A")
if [ "$(job_state "$A")" = running ] && [ "$(job_state "$B")" = accepted ] && [ "$(job_state "$C")" = accepted ]; then
    ok "one job runs, two are queued"
else
    not_ok "one job runs, two are queued" "$(job_state "$A") $(job_state "$B") $(job_state "$C")"
fi
kill9_daemon
if [ -n "$wpid" ] && poll 5 pid_gone "$wpid"; then
    ok "kill -9 of the daemon: its worker dies with it (PR_SET_PDEATHSIG)"
else
    not_ok "the worker dies with the daemon" "pid '$wpid'"
fi
start_daemon crash --workers 1 --worker "$WORK/slow-worker.sh" || { not_ok "daemon restarts"; exit 1; }
timeout $((10 * SLOW)) "$BIN/shapematchd" --listen 127.0.0.1:0 --spool "$SPOOL" 2>"$WORK/second.log"
rc=$?
if [ "$rc" = 1 ] && grep -q "in use by another shapematchd (pid $DPID)" "$WORK/second.log"; then
    ok "a second daemon on the same spool is refused (names the pid holding it)"
else
    not_ok "one daemon per spool" "exit $rc" "$(cat "$WORK/second.log")"
fi
all3() { state_in "$A" successful failed dismissed && state_in "$B" successful failed dismissed &&
    state_in "$C" successful failed dismissed; }
poll 60 all3
if state_is "$A" successful && state_is "$B" successful && state_is "$C" successful; then
    ok "after a restart on the same spool the three jobs complete (successful)"
else
    not_ok "the three jobs complete after a restart" "$(job_state "$A") $(job_state "$B") $(job_state "$C")"
fi
ev=$(events_of "$A")
attempts=$(printf '%s\n' "$ev" | jq -r 'select(.type == "started") | .attempt' | tr '\n' ' ')
seqs=$(printf '%s\n' "$ev" | jq -r 'select(.seq) | .seq')
if [ "$attempts" = "1 2 " ] &&
    [ "$(printf '%s\n' "$seqs" | tr '\n' ' ')" = "$(seq 1 "$(printf '%s\n' "$seqs" | wc -l)" | tr '\n' ' ')" ]; then
    ok "the interrupted job ran again (started attempt 1, then 2) and its event log has no gap"
else
    not_ok "the interrupted job's log" "attempts: $attempts"
fi
order=$(jq -r 'select(.event == "job_started") | .job' "$DLOG" | tail -3 | tr '\n' ' ')
if [ "$order" = "$A $B $C " ]; then ok "FIFO order kept across the restart"; else not_ok "FIFO order" "$order"; fi

# ---------------------------------------------- kill -9 of a worker
X=$(submit "$FINE" "$BOX" "$BOXSOL" "$(endless_params)")
Y=$(submit "$DISK" "$BOX" "$BOXSOL" "$(quick_params 50)")
poll 20 state_is "$X" running
xpid=$(worker_pid "$X")
[ -n "$xpid" ] && kill -KILL "$xpid"
wait_final "$X" 20
msg=$(message_of "$X")
if [ "$(job_state "$X")" = failed ] && [[ "$msg" == *"killed by signal 9 (SIGKILL)"* ]]; then
    ok "kill -9 of a worker: the job is failed with \"$msg\""
else
    not_ok "a killed worker fails its job" "$(job_state "$X"): $msg"
fi
last2=$(events_of "$X" | jq -r .type | tail -2 | tr '\n' ' ')
if [ "$last2" = "failed status " ]; then ok "its event log ends with failed, then status"; else not_ok "failed events" "$last2"; fi
if wait_state "$Y" successful 30; then ok "the next job runs and succeeds"; else not_ok "the next job runs" "$(job_state "$Y")"; fi
if curl -sS "$BASE/healthz" | jq -e '.status == "ok"' >/dev/null; then ok "the daemon carries on"; else not_ok "the daemon carries on"; fi
stop_daemon
rc=$?
[ "$rc" = 0 ] && ok "SIGTERM: exit 0" || not_ok "SIGTERM: exit 0" "status $rc"

# ----------------------------------- no spool path in what clients read
# A worker that cannot write its results (files limited to 2 KiB, SIGXFSZ
# ignored: EFBIG) fails naming the file: its message and its events name
# the file's base name, never the spool's path.
cat >"$WORK/lost-input-worker.sh" <<EOF
#!/bin/sh
trap '' XFSZ
ulimit -f 4
exec "$BIN/shapematch-worker" "\$@"
EOF
chmod +x "$WORK/lost-input-worker.sh"
start_daemon grace --workers 1 --worker "$WORK/lost-input-worker.sh" || { not_ok "daemon starts"; exit 1; }
L=$(submit "$DISK" "$BOX" "$BOXSOL" "$(quick_params 5)")
wait_state "$L" failed 20
lmsg=$(message_of "$L")
curl -sS -H 'Accept: application/x-ndjson' "$BASE/v1/jobs/$L/events" >"$WORK/lost.ndjson"
if state_is "$L" failed && [[ "$lmsg" == *results* ]] &&
    [[ "$lmsg" != *"$SPOOL"* ]] && [ -s "$WORK/lost.ndjson" ] && ! grep -qF "$SPOOL" "$WORK/lost.ndjson"; then
    ok "a worker that cannot write its results: the message names the file ($lmsg), no spool path in it or the events"
else
    not_ok "no spool path reaches clients" "message: $lmsg" "$(grep -F "$SPOOL" "$WORK/lost.ndjson" | head -c 400)"
fi
stop_daemon

# ----------------------------------------------------------- limits
SPOOL=$WORK/limits-spool
start_daemon limits --workers 1 --job-timeout 1 --kill-grace 1 || { not_ok "daemon starts"; exit 1; }
T=$(submit "$FINE" "$BOX" "$BOXSOL" "$(endless_params)")
wait_final "$T" 20
msg=$(message_of "$T")
if [ "$(job_state "$T")" = failed ] && [[ "$msg" == *"exceeded the wall-time limit of 1 s"* ]]; then
    ok "--job-timeout 1: the job fails with \"$msg\""
else
    not_ok "wall-time limit" "$(job_state "$T"): $msg"
fi
stop_daemon
SPOOL=$WORK/cpu-spool
start_daemon cpu --workers 1 --cpu-limit 1 --kill-grace 1 || { not_ok "daemon starts"; exit 1; }
U=$(submit "$FINE" "$BOX" "$BOXSOL" "$(endless_params)")
wait_final "$U" 30
msg=$(message_of "$U")
if [ "$(job_state "$U")" = failed ] && [[ "$msg" == *"exceeded the CPU limit of 1 s"* ]]; then
    ok "--cpu-limit 1: the job fails with \"$msg\""
else
    not_ok "CPU limit" "$(job_state "$U"): $msg"
fi

# ------------------------------------------------ keepalive, retention
stop_daemon
SPOOL=$WORK/keep-spool
start_daemon keep --workers 1 --keepalive 0.3 --retention 1 || { not_ok "daemon starts"; exit 1; }
K1=$(submit "$FINE" "$BOX" "$BOXSOL" "$(endless_params)")
K2=$(submit "$DISK" "$BOX" "$BOXSOL" "$(quick_params 5)")
poll 20 state_is "$K1" running
curl -sS -N --max-time 2 -H 'Accept: text/event-stream' "$BASE/v1/jobs/$K2/events" >"$WORK/ka.sse" 2>/dev/null
curl -sS -N --max-time 2 "$BASE/v1/jobs/$K2/events" >"$WORK/ka.ndjson" 2>/dev/null
ka=$(grep -c '^: keepalive$' "$WORK/ka.sse")
empty=$(grep -c '^$' "$WORK/ka.ndjson")
if [ "$ka" -ge 2 ] && [ "$empty" -ge 2 ] && grep -q '^event: accepted' "$WORK/ka.sse"; then
    ok "a stream waiting on a queued job gets keepalives (--keepalive 0.3: $ka SSE comments, $empty empty NDJSON lines in 2 s)"
else
    not_ok "keepalives" "sse $ka, ndjson $empty" "$(head -c 300 "$WORK/ka.sse")"
fi
curl -sS -o /dev/null -X DELETE "$BASE/v1/jobs/$K1"
if wait_state "$K2" successful 20; then ok "the queued job runs once the first is cancelled"; else not_ok "queued job runs" "$(job_state "$K2")"; fi
expired() { [ "$(job_state "$K2")" = 404 ] && [ ! -e "$SPOOL/jobs/$K2" ]; }
if poll 10 expired; then
    ok "--retention 1: the finished job and its folder are deleted after a second or so"
else
    not_ok "retention" "$(job_state "$K2")"
fi

# ------------------------------------------------- graceful shutdown
stop_daemon
SPOOL=$WORK/grace-spool
# the slow worker keeps the job running for a second at least: the
# requests below must reach a daemon that is still draining
start_daemon grace --workers 1 --shutdown-grace 60 --worker "$WORK/slow-worker.sh" ||
    { not_ok "daemon starts"; exit 1; }
G=$(submit "$DISK" "$BOX" "$BOXSOL" "$(quick_params 400)")
poll 20 state_is "$G" running
kill -TERM "$DPID"
# the signal is handled a moment later (it once answered /readyz 200
# first): wait until the daemon says it drains, then ask the rest
poll 5 readyz_is 503
ready=$(curl -sS -o "$WORK/ready.json" -w '%{http_code}' "$BASE/readyz")
post=$(curl -sS -o "$WORK/post.json" -D "$WORK/post.hdr" -w '%{http_code}' -F "template=@$DISK" \
    -F "target_mesh=@$BOX" -F "target_sol=@$BOXSOL" -F "params=$(quick_params 5)" "$BASE/v1/jobs")
getc=$(curl -sS -o /dev/null -w '%{http_code}' "$BASE/v1/jobs/$G")
if [ "$ready" = 503 ] && [ "$post" = 503 ] && [ "$getc" = 200 ] && grep -qi '^retry-after:' "$WORK/post.hdr"; then
    ok "while draining: /readyz 503, new jobs 503 with Retry-After, status still served"
else
    not_ok "draining" "readyz $ready, POST $post, GET $getc"
fi
wait_daemon_exit 60
rc=$?
if [ "$rc" = 0 ] && [ "$(jq -r .status "$SPOOL/jobs/$G/status.json")" = successful ]; then
    ok "SIGTERM with a running job: it finishes within the grace, then the daemon exits 0"
else
    not_ok "running job finishes within the grace" "exit $rc, $(jq -r .status "$SPOOL/jobs/$G/status.json")"
fi
start_daemon grace --workers 1 --shutdown-grace 0.5 --kill-grace 1 || { not_ok "daemon starts"; exit 1; }
H=$(submit "$FINE" "$BOX" "$BOXSOL" "$(endless_params)")
I=$(submit "$DISK" "$BOX" "$BOXSOL" "$(quick_params 5)")
poll 20 state_is "$H" running
curl -sS -N --max-time 60 -H 'Accept: text/event-stream' "$BASE/v1/jobs/$H/events" >"$WORK/h.sse" 2>/dev/null &
follower=$!
poll 10 grep -q '^event: progress' "$WORK/h.sse"
stop_daemon
rc=$?
follower_gone() { ! kill -0 "$follower" 2>/dev/null; }
if poll 5 follower_gone; then
    ok "an open event stream is closed by the shutdown (the client can reconnect later)"
else
    kill "$follower" 2>/dev/null
    not_ok "event stream closed at shutdown"
fi
wait "$follower" 2>/dev/null
hs=$(jq -r .status "$SPOOL/jobs/$H/status.json")
hm=$(jq -r .message "$SPOOL/jobs/$H/status.json")
is=$(jq -r .status "$SPOOL/jobs/$I/status.json")
if [ "$rc" = 0 ] && [ "$hs" = accepted ] && [[ "$hm" == *shutdown* ]] && [ "$is" = accepted ]; then
    ok "past the grace the running job is stopped and kept queued (\"$hm\"), the queued one too"
else
    not_ok "stopped jobs stay queued" "exit $rc, $hs ($hm), $is"
fi
start_daemon grace --workers 1 --kill-grace 1 || { not_ok "daemon restarts"; exit 1; }
if poll 20 state_is "$H" running; then ok "at the next start the stopped job runs again"; else not_ok "the stopped job runs again" "$(job_state "$H")"; fi
curl -sS -o /dev/null -X DELETE "$BASE/v1/jobs/$H"
if wait_state "$I" successful 30; then ok "and the queued one after it"; else not_ok "the queued job runs" "$(job_state "$I")"; fi
stop_daemon
rc=$?
[ "$rc" = 0 ] && ok "SIGTERM: exit 0" || not_ok "SIGTERM: exit 0" "status $rc"

if reports_clean; then ok "no sanitizer report in the daemon or worker logs"; else not_ok "sanitizer reports" "$(grep -lE 'Sanitizer|runtime error' "$WORK"/*.log "$WORK"/*-spool/jobs/*/worker.log 2>/dev/null)"; fi
echo "1..$n"
