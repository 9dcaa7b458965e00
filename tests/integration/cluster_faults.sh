#!/usr/bin/env bash
# run.sh: weight 0.25 seconds 60
# Database faults of a cluster (issue 28), one PostgreSQL and two nodes
# (an API node, a worker node) shared by both parts:
#
# 1. A session frozen inside a transaction that holds a job's row lock: a
#    psql session takes the row lock of a running job, then is stopped
#    with SIGSTOP, as a worker node frozen mid-transaction would leave it
#    (its socket open, its transaction never ending).  The API node must
#    keep answering: a DELETE of that job fails within
#    --database-lock-timeout (503, the job kept) and never holds the
#    daemon's lock while it waits, so status, /healthz and /readyz answer
#    meanwhile; the node reports unready after the timeout; the lease
#    expiry names the lease it cannot take; once the session is gone the
#    DELETE works.
# 2. The database refuses a finished run's events and results for a
#    reason other than a lost connection: a trigger raises SQLSTATE 53100
#    (disk_full, what PostgreSQL answers when its data directory is full)
#    on every event but "accepted" and on every result blob while a switch
#    row exists.  The worker node must hold what it could not store and
#    retry it in order: unready meanwhile, its lease kept (the job is not
#    run again), and once the database takes writes again the job ends
#    successful after one attempt with every event, in order, without a
#    gap in iterations or sequence numbers.  Meanwhile the worker node is
#    killed (-9) and started again on the same spool: what it held is on
#    disk (SPOOL/outbox/), replayed in order at the start, its lease
#    renewed again, so the job still ends once.
#
# Windows wait for states, not for time: each fault is switched on once
# the job is in the state it needs (running, its run ended, its outbox on
# disk), and the windows that remain (the lock timeout, the leases) scale
# with the variant's slowdown SLOW (lib.sh), so that an ASan build on a
# loaded machine meets the same verdicts as a release build on an idle
# one.
#
# SM_TEST_OLD_DAEMON=1 SM_BIN=<older build> runs it on a daemon without
# the timeout flags, to see the failures the fixes remove.
source "$(dirname "$0")/lib.sh"
source "$(dirname "$0")/../lib/cluster.sh"

if ! make_case || ! pg_up; then
    not_ok "gmsh builds the test meshes and PostgreSQL starts"
    exit 1
fi
# The lock timeout: the probes of part 1 are made while a DELETE waits
# this long (1 s once; on a loaded machine a probe alone took 2 s).  A row
# lock is waited for in two steps, each up to the lock timeout: twice it
# stays under the sessions' statement timeout (30 s), which 4 x 4 s did
# not under ASan.  The
# short lease (parts 1 and 3) expires while its node is frozen, and the
# frozen session of part 1 outlasts it; it is renewed every third of it,
# so a running node keeps it unless it stalls for 3 s (2 s once, which a
# node starved on a loaded machine lost).
LOCK_TIMEOUT=$((4 + SLOW))
LEASE=$((5 * SLOW))
# part 2's lease outlives a kill -9 and a restart of its node (10 s: an
# ASan node's restart took more than the 6 s once used)
LEASE_LONG=$((10 * SLOW))
LOCKT=(--database-lock-timeout "$LOCK_TIMEOUT")
[ -n "${SM_TEST_OLD_DAEMON:-}" ] && LOCKT=() # a daemon without the flag: the failure before the fix
if ! node api1 api --workers 1 --lease "$LEASE" "${LOCKT[@]}" ||
    ! node w1 worker --workers 1 --lease "$LEASE" "${LOCKT[@]}"; then
    not_ok "the nodes start"
    exit 1
fi
ok "PostgreSQL, an API node and a worker node start (--database-lock-timeout $LOCK_TIMEOUT, --lease $LEASE)"

on api1
id=$(submit "$FINE" "$BOX" "$BOXSOL" "$(endless_params)")
poll 30 state_is "$id" running || not_ok "the job runs" "$(job_state "$id")"
# its run paused (the worker process stopped): the job stays running in
# the database, its node keeps its lease, and no event comes while its row
# is locked below.  (An endless run sent ~750 events a second: held by
# the lock, the node wrote them to its outbox, one durable file each, and
# took a minute to be done with them.)
on w1
has_worker() { [ -n "$(worker_pid "$id")" ]; }
poll 30 has_worker
WPID=$(worker_pid "$id")
kill -STOP "$WPID" 2>/dev/null || not_ok "the run is paused" "worker pid '${WPID}'"
on api1

# ------------------------------------------- 1. a frozen session
# BEGIN, lock the job's row, then SIGSTOP
mkfifo "$WORK/psql.in"
psql -X -q "$DB" <"$WORK/psql.in" >"$WORK/psql.out" 2>&1 &
PSQL=$!
exec 7>"$WORK/psql.in"
echo "BEGIN; SELECT 'locked' FROM smd_jobs WHERE id = '$id' FOR UPDATE;" >&7
poll 10 grep -q locked "$WORK/psql.out" || not_ok "the psql session locks the row" "$(cat "$WORK/psql.out")"
kill -STOP "$PSQL"
held=$(psql_val "SELECT count(*) FROM pg_stat_activity WHERE state = 'idle in transaction'")

# a DELETE on the API node waits for the row; meanwhile the node answers
t0=$(date +%s.%N)
hcurl --max-time $((2 * LOCK_TIMEOUT + 10 * SLOW)) -o "$WORK/del1.json" -w '%{http_code}' -X DELETE "$BASE/v1/jobs/$id" \
    >"$WORK/del1.code" 2>/dev/null &
DEL=$!
sleep 0.2
probe() { # NAME URL: the HTTP status before the lock timeout ("000": no answer) in $WORK/probe-NAME
    curl -sS -o /dev/null -w '%{http_code}' --max-time $((LOCK_TIMEOUT - 1)) "$2" >"$WORK/probe-$1" 2>/dev/null
}
# side by side, so that all four are made while the DELETE waits
probes=()
probe health "$BASE/healthz" &
probes+=($!)
probe status "$BASE/v1/jobs/$id" &
probes+=($!)
probe list "$BASE/v1/jobs" &
probes+=($!)
probe ready "$BASE/readyz" &
probes+=($!)
wait "${probes[@]}"
waiting=no
kill -0 "$DEL" 2>/dev/null && waiting=yes # the probes are over, the DELETE still waits
p_health=$(cat "$WORK/probe-health")
p_status=$(cat "$WORK/probe-status")
p_list=$(cat "$WORK/probe-list")
p_ready=$(cat "$WORK/probe-ready")
wait "$DEL"
t1=$(date +%s.%N)
del1=$(cat "$WORK/del1.code")
secs=$(awk -v a="$t0" -v b="$t1" 'BEGIN { printf "%.1f", b - a }')
if [ "$held" -ge 1 ] && [ "$waiting" = yes ] && [ "$p_health" = 200 ] && [ "$p_status" = 200 ] &&
    [ "$p_list" = 200 ] && [ "$p_ready" = 200 ]; then
    ok "row lock held by a frozen session: /healthz, status, list and /readyz answer while a DELETE waits"
else
    not_ok "the API node answers while a DELETE waits on a row lock" \
        "sessions idle in transaction $held; the DELETE still waiting after the probes: $waiting" \
        "healthz $p_health status $p_status list $p_list readyz $p_ready"
fi
# bounded: twice the lock timeout and 5 s (scaled) for the rest
if [ "$del1" = 503 ] && awk -v s="$secs" -v b=$((2 * LOCK_TIMEOUT + 5 * SLOW)) 'BEGIN { exit !(s < b) }' &&
    grep -q 'lock timeout' "$WORK/del1.json" && [ "$(job_state "$id")" = running ]; then
    ok "the DELETE answers 503 after the lock timeout (${secs} s), the job is kept"
else
    not_ok "DELETE bounded by --database-lock-timeout" "code $del1 after $secs s: $(head -c 300 "$WORK/del1.json")"
fi
r=$(curl -sS -o "$WORK/ready.json" -w '%{http_code}' --max-time 2 "$BASE/readyz")
if [ "$r" = 503 ] && grep -q 'lock timeout' "$WORK/ready.json"; then
    ok "the node whose database call timed out reports unready (/readyz 503 naming the timeout)"
else
    not_ok "unready after a timeout" "readyz $r: $(head -c 300 "$WORK/ready.json")"
fi

# the lease expired while the row is locked: the sweep says so
expired_held() { grep -q '"event":"leases_expired_held"' "${NODE_LOG[api1]}" "${NODE_LOG[w1]}"; }
if poll 30 expired_held; then
    ok "the lease expiry names the expired lease whose row is locked"
else
    not_ok "leases_expired_held logged"
fi

# the session goes: the job can be deleted (dismissed) again
{ kill -KILL "$PSQL" && wait "$PSQL"; } 2>/dev/null
exec 7>&-
dismissed() {
    local c
    c=$(hcurl -o /dev/null -w '%{http_code}' -X DELETE "$BASE/v1/jobs/$id")
    [ "$c" = 200 ] && state_in "$id" dismissed
}
if poll 20 dismissed && poll 10 curl -sf -o /dev/null "$BASE/readyz"; then
    ok "the frozen session gone: DELETE 200, the job dismissed, the node ready again"
else
    not_ok "DELETE after the lock is freed" "state $(job_state "$id")"
fi
# ------------------------------------------- 2. the database refuses writes
# w1 again with a lease that outlives its own kill -9 and restart below,
# once nothing of part 1 is left on it: its run of that job ended, its
# outbox empty on disk, ready.  (On a slow node that run ends late, and
# what of it was still on disk at the kill was replayed at the restart,
# into the fault below: held, the node claimed nothing, the part failed.)
spooled() { find "$WORK/w1-spool/outbox" -regex '.*/[0-9a-f]*\.json' | wc -l; }
part1_left() {
    grep -q "\"event\":\"job_cancelled\",\"job\":\"$id\"" "${NODE_LOG[w1]}" &&
        [ "$(spooled)" = 0 ] && curl -sf -o /dev/null "${NODE_BASE[w1]}/readyz"
}
poll 20 part1_left || not_ok "w1 done with part 1" "$(spooled) outbox files" \
    "$(grep -c "\"event\":\"job_cancelled\",\"job\":\"$id\"" "${NODE_LOG[w1]}") job_cancelled lines"
kill9 w1
node w1 worker --workers 1 --lease "$LEASE_LONG" "${LOCKT[@]}" || not_ok "the worker node starts again"
psql -X -q "$DB" >"$WORK/fault.log" 2>&1 <<'SQL' || not_ok "the fault trigger is installed" "$(cat "$WORK/fault.log")"
CREATE TABLE fault_full (x int);
CREATE FUNCTION fault_full_fn() RETURNS trigger LANGUAGE plpgsql AS $$
BEGIN
  IF NOT EXISTS (SELECT 1 FROM fault_full) THEN
    RETURN NEW;
  END IF;
  IF TG_TABLE_NAME = 'smd_events' THEN
    IF NEW.payload->>'type' = 'accepted' THEN
      RETURN NEW;
    END IF;
  END IF;
  RAISE EXCEPTION 'could not extend file: No space left on device' USING ERRCODE = '53100';
END $$;
CREATE TRIGGER fault_full BEFORE INSERT ON smd_events FOR EACH ROW EXECUTE FUNCTION fault_full_fn();
CREATE TRIGGER fault_full BEFORE INSERT ON smd_blobs FOR EACH ROW
  WHEN (starts_with(NEW.name, 'results/')) EXECUTE FUNCTION fault_full_fn();
INSERT INTO fault_full VALUES (1);
SQL
ok "a switchable disk-full fault: events (but accepted) and result blobs refused with SQLSTATE 53100"

on api1
id=$(submit "$FINE" "$BOX" "$BOXSOL" "$BALL_PARAMS, \"max_iter\": 60, \"tol_step\": 1e-15, \"tol_stall\": 0}")
# the run ends on the worker node (its local record), nothing of it stored
on w1
ran() { grep -q "\"event\":\"job_finished\",\"job\":\"$id\"" "${NODE_LOG[w1]}"; }
poll 60 ran || not_ok "the run ends on the worker node" "$(job_state "$id")"
# the node tried to store the run and holds it: unready, and its end (the
# final item, with the results) written to the outbox on disk
held_on_disk() {
    grep -qs '"kind":"final"' "$WORK"/w1-spool/outbox/*.json &&
        curl -sS --max-time 5 "${NODE_BASE[w1]}/readyz" | grep -q "wait to be stored"
}
poll 20 held_on_disk
r_w1=$(curl -sS -o "$WORK/ready.json" -w '%{http_code}' --max-time 5 "${NODE_BASE[w1]}/readyz")
db_state=$(psql_val "SELECT state || ' ' || attempt FROM smd_jobs WHERE id = '$id'")
db_events=$(psql_val "SELECT count(*) FROM smd_events WHERE job = '$id'")
if [ "$r_w1" = 503 ] && grep -q "wait to be stored" "$WORK/ready.json" &&
    [ "$db_state" = "running 1" ] && [ "$db_events" = 1 ]; then
    ok "the database refuses the run's events and results: the worker node holds them, unready, the lease kept (running, attempt 1)"
else
    not_ok "held while the database refuses writes" \
        "w1 readyz $r_w1: $(head -c 300 "$WORK/ready.json")" "db: '$db_state', $db_events events"
fi

# kill -9 while the results wait, then the same node again on its spool
nspool=$(spooled)
token=$(psql_val "SELECT lease_token FROM smd_jobs WHERE id = '$id'")
nreplay=$(grep -c '"event":"outbox_replay"' "${NODE_LOG[w1]}")
kill9 w1
# the database's clock at the kill: no renewal of the killed node can end
# the lease later than this plus --lease
t_kill=$(psql_val "SELECT extract(epoch FROM clock_timestamp())")
node w1 worker --workers 1 --lease "$LEASE_LONG" "${LOCKT[@]}" || not_ok "the worker node starts again"
replayed() { [ "$(grep -c '"event":"outbox_replay"' "${NODE_LOG[w1]}")" -gt "$nreplay" ]; }
poll 10 replayed
# the restarted node renews the same lease: it now ends past the kill +
# --lease (a state, where a sleep of --lease + 1 s since the kill once
# stood, which a slow restart could outlast)
renewed() {
    [ "$(psql_val "SELECT lease_token = ${token:-0} AND lease_expires > to_timestamp(${t_kill:-0})
        + $LEASE_LONG * interval '1 second' FROM smd_jobs WHERE id = '$id'")" = t ]
}
poll "$LEASE_LONG" renewed
r_w1=$(curl -sS -o "$WORK/ready.json" -w '%{http_code}' --max-time 5 "${NODE_BASE[w1]}/readyz")
db_state=$(psql_val "SELECT state || ' ' || attempt || ' ' || (lease_token = ${token:-0}) || ' ' ||
    (lease_expires > to_timestamp(${t_kill:-0}) + $LEASE_LONG * interval '1 second') FROM smd_jobs WHERE id = '$id'")
all "killed -9 while $nspool events and the results wait on disk: the restarted node replays them, unready, renews the same lease (past the kill + --lease $LEASE_LONG)" \
    "$nspool|-ge|10" "$(grep -c '"event":"outbox_replay"' "${NODE_LOG[w1]}")|=|$((nreplay + 1))" "$r_w1|=|503" \
    "$(grep -c 'wait to be stored' "$WORK/ready.json")|=|1" "${db_state// /_}|=|running_1_true_true"

psql_val "DELETE FROM fault_full" >/dev/null
on api1
poll 30 state_is "$id" successful
final=$(psql_val "SELECT state || ' ' || attempt FROM smd_jobs WHERE id = '$id'")
psql -X -A -t -q "$DB" -c "SELECT seq || ' ' || (payload->>'type') || ' ' || coalesce(payload->>'iteration', '-') FROM smd_events WHERE job = '$id' ORDER BY seq" >"$WORK/events.txt"
nev=$(wc -l <"$WORK/events.txt")
seqs_ok=$(awk '$1 != NR { bad = 1 } END { print bad ? "no" : "yes" }' "$WORK/events.txt")
iters=$(awk '$2 == "progress" { print $3 }' "$WORK/events.txt" | tr '\n' ' ')
iters_ok=$(awk '$2 == "progress" { if (prev != "" && $3 != prev + 1) bad = 1; prev = $3; n++ }
    END { print (bad || n < 10) ? "no" : "yes" }' "$WORK/events.txt")
types=$(awk '$2 != "progress" { printf "%s ", $2 }' "$WORK/events.txt")
if [ "$final" = "successful 1" ] && [ "$seqs_ok" = yes ] && [ "$iters_ok" = yes ] &&
    [ "$types" = "accepted started finished " ]; then
    ok "writes taken again: successful after 1 attempt, $nev events, seq 1..$nev, every iteration in order"
else
    not_ok "every held event and the result stored once the database takes writes" \
        "db: '$final', events: $types; seqs $seqs_ok; iterations $iters_ok: $iters"
fi
if poll 10 curl -sf -o /dev/null "${NODE_BASE[w1]}/readyz" &&
    [ "$(grep -c "\"event\":\"job_claimed\",\"job\":\"$id\"" "${NODE_LOG[w1]}")" = 1 ]; then
    ok "the worker node is ready again; the job was claimed once"
else
    not_ok "ready again, one claim" "claims: $(grep -c '"event":"job_claimed"' "${NODE_LOG[w1]}")"
fi
outbox_empty() { [ "$(spooled)" = 0 ]; }
poll 5 outbox_empty
check "the outbox on disk is empty once stored ($(spooled) files left)" test "$(spooled)" = 0
kill9 w1
node w1 worker --workers 1 --lease "$LEASE" "${LOCKT[@]}" || not_ok "the worker node starts again"
# ------------------------------------------- 3. a claim that fails, a lost lease
# The worker node is frozen (SIGSTOP, shorter than the lease) while a job
# is queued and a file takes the place of that job's folder in the node's
# spool: its claims fail.  A claim that fails gives its attempt back
# (nothing ran), and its message names no folder of the node.
on api1
kill -STOP "${NODE_PID[w1]}"
u=$(submit "$DISK" "$BOX" "$BOXSOL" "$(quick_params 5)")
: >"$WORK/w1-spool/jobs/$u"
kill -CONT "${NODE_PID[w1]}"
# two failed claims at least: before the fix the attempt is then 2 or more
tries() { # the failed claims the job's message counts
    local m
    m=$(psql_val "SELECT substring(message from '\((\d+) failed claims\)') FROM smd_jobs WHERE id = '$u'")
    echo "${m:-0}"
}
claims_failed() { [ "$(tries)" -ge 2 ]; }
poll 10 claims_failed
# backoff: over the next 3 s a claim every 0.2 s would fail 15 times;
# doubling from 0.2 s (jitter: each wait in its upper half) at most 5
t_a=$(tries)
sleep 3
t_b=$(tries)
ua=$(psql_val "SELECT state || ' ' || attempt FROM smd_jobs WHERE id = '$u'")
umsg=$(psql_val "SELECT message FROM smd_jobs WHERE id = '$u'")
nlog=$(grep -c "\"event\":\"claim_failed\".*job $u" "${NODE_LOG[w1]}")
rm -f "$WORK/w1-spool/jobs/$u"
hcurl -o /dev/null -X DELETE "$BASE/v1/jobs/$u"
all "a claim that fails (the node cannot make the job's folder) uses no attempt ($t_b failed claims, then: $ua), its message names no folder of the node ($umsg)" \
    "$t_a|-ge|2" "${ua#* }|-le|1" "$(grep -cF "$WORK" <<<"$umsg")|=|0"
all "failed claims back off (from $t_a to $t_b failed claims in 3 s) and are logged once ($nlog lines)" \
    "$((t_b - t_a))|-le|6" "$((t_b - t_a))|-ge|1" "$nlog|=|1"
# A running job's node frozen beyond its lease: the lease expires, and
# the node, woken, stops the run saying so, not as if a client cancelled.
v=$(submit "$FINE" "$BOX" "$BOXSOL" "$(endless_params)")
poll 30 state_is "$v" running
# frozen once its run started on the node (the database says running from
# the claim on: a node frozen between its claim and the run's start, seen
# at load 50, starts the run after it has lost the lease and never ends it)
run_started() { grep -q "\"event\":\"job_started\",\"job\":\"$v\"" "${NODE_LOG[w1]}"; }
poll 30 run_started
kill -STOP "${NODE_PID[w1]}"
expired() { [ "$(psql_val "SELECT attempt || ' ' || (lease_token IS NULL) FROM smd_jobs WHERE id = '$v'")" != "1 false" ]; }
poll 30 expired # deadlines: a frozen node catches up slowly on a loaded machine
kill -CONT "${NODE_PID[w1]}"
lost_line() { grep "\"event\":\"job_cancelled\",\"job\":\"$v\"" "${NODE_LOG[w1]}" | head -n 1; }
has_lost_line() { [ -n "$(lost_line)" ]; }
poll 30 has_lost_line
line=$(lost_line)
if [[ "$line" == *"lease was lost"* && "$line" != *DELETE* ]]; then
    ok "a node that lost its lease stops the run saying so (not \"cancelled by request\")"
else
    not_ok "the lost lease's wording" "${line:-no job_cancelled line on w1}"
fi
poll 30 state_is "$v" running
hcurl -o /dev/null -X DELETE "$BASE/v1/jobs/$v"
poll 30 state_is "$v" dismissed
for nd in api1 w1; do kill -TERM "${NODE_PID[$nd]}" 2>/dev/null; done
for nd in api1 w1; do wait "${NODE_PID[$nd]}" 2>/dev/null; done
check "no sanitizer report in any node's log" reports_clean
echo "1..$n"
