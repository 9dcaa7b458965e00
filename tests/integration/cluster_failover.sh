#!/usr/bin/env bash
# run.sh: weight 0.25 seconds 60
# Several machines on one PostgreSQL (issue 12), failures and cluster-wide
# operations: an API node killed (-9) while a client follows a job (the
# client resumes on the other with Last-Event-ID: no event lost or
# repeated); cancel on the API node that did not accept the job; an
# Idempotency-Key retry on the other API node returns the same job;
# PostgreSQL restarted with jobs queued and running (/readyz 503 during
# the outage, nodes reconnect, nothing accepted is lost); a worker node
# stopped while it runs a job gives it back at once, and so does one
# stopped while its claim copies a job; retention with two API nodes
# deletes each job once.
source "$(dirname "$0")/lib.sh"
source "$(dirname "$0")/../lib/cluster.sh"

if ! make_case || ! pg_up; then
    not_ok "gmsh builds the test meshes and PostgreSQL starts"
    exit 1
fi
# a lease of 6 s, scaled: renewed every third of it, so a node keeps its
# job unless it stalls for 4 s (with 3 s, a node starved at load 50 lost
# the job it ran, which then ran twice)
LEASE=$((6 * SLOW))
started=1
# The job running across PostgreSQL's restart (max_iter 1002) waits in the
# worker program until the database is back ($WORK/go), then computes:
# computed at once, its 1000 iterations took 0.3 s on an idle machine and
# it ended before the outage.
cat >"$WORK/gate.sh" <<EOF
#!/bin/sh
if grep -q '"max_iter": 1002,' "\$1/job.json"; then
    touch "$WORK/gated"
    while [ ! -e "$WORK/go" ]; do sleep 0.1; done
fi
exec "$BIN/shapematch-worker" "\$@"
EOF
chmod +x "$WORK/gate.sh"
for nr in api1:api api2:api w1:worker; do
    node "${nr%%:*}" "${nr#*:}" --workers 1 --lease "$LEASE" --worker "$WORK/gate.sh" || started=0
done
if [ "$started" != 1 ]; then
    not_ok "the nodes start"
    exit 1
fi
ok "PostgreSQL, 2 API nodes and a worker node start"
LONG="$BALL_PARAMS, \"max_iter\": 1000, \"tol_step\": 1e-15, \"tol_stall\": 0}"

# ------------------------------ kill -9 an API node while a client follows
on api1
fid=$(submit "$FINE" "$BOX" "$BOXSOL" "$LONG")
curl -sS -N --max-time $((60 * SLOW)) -H 'Accept: text/event-stream' \
    "$BASE/v1/jobs/$fid/events" >"$WORK/f1.sse" 2>/dev/null &
CURL=$!
enough() { [ "$(grep -c '^id: ' "$WORK/f1.sse")" -ge 30 ]; }
poll 30 enough
kill9 api1
wait "$CURL" 2>/dev/null
# the client keeps the complete events it got (the last block may be cut)
awk 'BEGIN { RS = "" } /\ndata: / { print }' "$WORK/f1.sse" | sed '$d' |
    awk '/^id: / { print $2 }' >"$WORK/f1.ids"
last=$(tail -n 1 "$WORK/f1.ids")
on api2
curl -sS -N --max-time $((60 * SLOW)) -H 'Accept: text/event-stream' -H "Last-Event-ID: $last" \
    "$BASE/v1/jobs/$fid/events" >"$WORK/f2.sse"
awk '/^id: / { print $2 }' "$WORK/f2.sse" >"$WORK/f2.ids"
cat "$WORK/f1.ids" "$WORK/f2.ids" >"$WORK/all.ids"
total=$(psql_val "SELECT nevents FROM smd_jobs WHERE id = '$fid'")
end=$(awk '/^event: / { e = $2 } END { print e }' "$WORK/f2.sse")
if [ -n "$last" ] && [ "$last" -ge 10 ] && [ "$(cat "$WORK/all.ids" | tr '\n' ' ')" = "$(seq 1 "$total" | tr '\n' ' ')" ] &&
    [ "$end" = status ] && [ "$(job_state "$fid")" = successful ]; then
    ok "API node killed while a client followed (after event $last): resumed on the other with Last-Event-ID, events 1..$total each once"
else
    not_ok "resume on the other API node" "last '$last' total '$total' end '$end'" \
        "$(tr '\n' ' ' <"$WORK/all.ids" | head -c 600)"
fi
SPOOL= start_daemon api1b --database "$DB" --role api --workers 1 --lease "$LEASE" || not_ok "api1 comes back"
NODE_BASE[api1]=$BASE NODE_PID[api1]=$DPID NODE_LOG[api1]=$DLOG

# ------------------------------------- cancel on the other API node
on api1
cid=$(submit "$FINE" "$BOX" "$BOXSOL" "$(endless_params)") # runs until stopped
on api2
poll 20 state_is "$cid" running
t0=$SECONDS
code=$(hcurl -o "$WORK/del.json" -w '%{http_code}' -X DELETE "$BASE/v1/jobs/$cid")
on api1
poll 15 state_is "$cid" dismissed
s1=$(job_state "$cid")
on api2
s2=$(job_state "$cid")
hcurl -H 'Accept: application/x-ndjson' "$BASE/v1/jobs/$cid/events" >"$WORK/c.ndjson"
lasttype=$(jq -r 'select(.seq) | .type' "$WORK/c.ndjson" | tail -n 1)
stopped=$(grep -c "\"event\":\"job_cancelled\",\"job\":\"$cid\"" "${NODE_LOG[w1]}")
dbs=$(psql_val "SELECT state FROM smd_jobs WHERE id = '$cid'")
if [ "$code" = 200 ] && [ "$s1" = dismissed ] && [ "$s2" = dismissed ] && [ "$lasttype" = cancelled ] &&
    [ "$stopped" = 1 ] && [ "$dbs" = dismissed ]; then
    ok "DELETE on the API node that did not accept a running job: the worker node stops it ($((SECONDS - t0)) s), dismissed everywhere"
else
    not_ok "cancel across nodes" "code $code states $s1/$s2 db $dbs last event $lasttype worker stopped $stopped" \
        "$(cat "$WORK/del.json")"
fi

# ---------------------------------- idempotent retry on the other node
on api2
k1=$(submit "$DISK" "$BOX" "$BOXSOL" "$(quick_params 5)" -H 'Idempotency-Key: cluster-retry')
c1=$(cat "$WORK/submit.code")
on api1
k2=$(submit "$DISK" "$BOX" "$BOXSOL" "$(quick_params 5)" -H 'Idempotency-Key: cluster-retry')
c2=$(cat "$WORK/submit.code")
nkey=$(psql_val "SELECT count(*) FROM smd_jobs WHERE idempotency_key = 'cluster-retry'")
if [ -n "$k1" ] && [ "$k1" = "$k2" ] && [ "$c1" = 201 ] && [ "$c2" = 200 ] && [ "$nkey" = 1 ]; then
    ok "Idempotency-Key retried on the other API node: the same job (201 then 200), one row"
else
    not_ok "Idempotency-Key across API nodes" "$k1 ($c1) vs $k2 ($c2), rows $nkey"
fi

# ------------------------------------------------ PostgreSQL restart
on api1
rid=$(submit "$FINE" "$BOX" "$BOXSOL" "$BALL_PARAMS, \"max_iter\": 1002, \"tol_step\": 1e-15, \"tol_stall\": 0}")
poll 20 state_is "$rid" running
poll 20 [ -e "$WORK/gated" ] # its worker program started
qids=()
for i in 1 2 3; do qids+=("$(submit "$DISK" "$BOX" "$BOXSOL" "$(quick_params 20)")"); done
rsome=$(psql_val "SELECT state || ' ' || attempt FROM smd_jobs WHERE id = '$rid'")
pg_kill "$PGDIR"
ready_is() { [ "$(hcurl -o /dev/null -w '%{http_code}' "$BASE/readyz")" = "$1" ]; }
poll 10 ready_is 503
down=$(hcurl "$BASE/readyz" | jq -r .detail)
check "/readyz answers 503 while the database is down ($down)" ready_is 503
lost=$(submit "$DISK" "$BOX" "$BOXSOL" "$(quick_params 20)" -D "$WORK/outage.headers")
retry=$(grep -ci '^retry-after:' "$WORK/outage.headers")
check "an upload during the outage gets 503 with Retry-After (retry later), not 507 ($(cat "$WORK/submit.code"), retry-after $retry)" \
    [ "$(cat "$WORK/submit.code"):$retry:$lost" = "503:1:" ]
sleep 1
pg_start "$PGDIR" >/dev/null
# each node reconnects on its own (backoff 0.1 s doubling to 5 s): api2's
# copy of the jobs once lagged a second behind api1's
both_ready() {
    local nd
    for nd in api1 api2; do
        on "$nd"
        ready_is 200 || return 1
    done
}
poll 20 both_ready
check "the nodes reconnect: /readyz 200 again on both API nodes" both_ready
touch "$WORK/go" # the job that ran across the outage computes now
on api2 # its upload connection was idle during the outage
qids+=("$(submit "$DISK" "$BOX" "$BOXSOL" "$(quick_params 20)")")
check "the first upload after the restart is accepted (201)" [ "$(cat "$WORK/submit.code")" = 201 ]
alldone() { # on both API nodes: each follows the database on its own
    local id nd
    for nd in api1 api2; do
        on "$nd"
        for id in "$rid" "${qids[@]}"; do state_is "$id" successful || return 1; done
    done
}
poll 60 alldone
bad=""
for id in "$rid" "${qids[@]}"; do
    for nd in api1 api2; do
        on "$nd"
        s=$(job_state "$id")
        [ "$s" = successful ] || bad="$bad $nd:$id:$s"
    done
done
all "the jobs queued and running across the restart all end successful on both API nodes" "-z|$bad" \
    "${rid:-none}|!=|none" "${#qids[@]}|=|4" "$rsome|=|running 1"
[ -n "$bad" ] && echo "# $bad"
on api1
depth0() { # the gauges follow the database's queue (refreshed every lease / 3)
    hcurl "$BASE/metrics" >"$WORK/metrics.txt" &&
        grep -q '^shapematch_cluster_queue_depth 0$' "$WORK/metrics.txt" &&
        grep -q '^shapematch_cluster_leases 0$' "$WORK/metrics.txt" &&
        grep -q '^shapematch_database_up 1$' "$WORK/metrics.txt"
}
poll 10 depth0
check "/metrics has the queue depth and leases from the database" depth0

# ------------------------- a worker node stopped (SIGTERM) while it runs
# The job's first run is held by the worker program (running until the
# daemon's SIGTERM ends it): computed, its 1000 iterations took 0.3 s on
# an idle machine and ended before the stop, so w3 never ran it.
cat >"$WORK/held-once.sh" <<EOF
#!/bin/sh
if grep -q '"max_iter": 1001,' "\$1/job.json" && mkdir "$WORK/held" 2>/dev/null; then
    while :; do sleep 1; done
fi
exec "$BIN/shapematch-worker" "\$@"
EOF
chmod +x "$WORK/held-once.sh"
kill -TERM "${NODE_PID[w1]}"
wait "${NODE_PID[w1]}" 2>/dev/null
node w2 worker --workers 1 --lease "$LEASE" --shutdown-grace 0 --worker "$WORK/held-once.sh" ||
    not_ok "node w2 starts"
on api1
sid=$(submit "$FINE" "$BOX" "$BOXSOL" "$BALL_PARAMS, \"max_iter\": 1001, \"tol_step\": 1e-15, \"tol_stall\": 0}")
poll 20 state_is "$sid" running
# running in the database means claimed: the worker program may not have
# started yet (that case, a stop while the claim copies the job, is below)
poll 20 [ -d "$WORK/held" ]
held=$([ -d "$WORK/held" ] && echo held)
t0=$SECONDS
kill -TERM "${NODE_PID[w2]}"
wait "${NODE_PID[w2]}" 2>/dev/null
back=$(psql_val "SELECT state || ' ' || attempt || ' ' || (lease_token IS NULL) FROM smd_jobs WHERE id = '$sid'")
node w3 worker --workers 1 --lease "$LEASE" || not_ok "node w3 starts"
on api1 # node() pointed BASE at w3, which serves only the jobs it ran
poll 30 state_is "$sid" successful
all "a worker node stopped while it runs a job gives it back at once ($((SECONDS - t0)) s to the end), another runs it as attempt 2" \
    "$held|=|held" "$back|=|accepted 1 true" "$(job_state "$sid")|=|successful" \
    "$(psql_val "SELECT attempt FROM smd_jobs WHERE id = '$sid'")|=|2"

# --------------- a worker node stopped while its claim copies the job
# The claim is caught between its UPDATE and the copy of the job's inputs:
# a session holds smd_blobs locked until the node is shutting down.  The
# node must give the job back at its stop, not keep the lease until it
# expires (it kept it: no node could run the job for --lease seconds).
kill -TERM "${NODE_PID[w3]}"
wait "${NODE_PID[w3]}" 2>/dev/null
on api1
uid=$(submit "$DISK" "$BOX" "$BOXSOL" "$(quick_params 5)")
on api2
poll 20 state_is "$uid" accepted # api2 copied it before the lock
mkfifo "$WORK/lock.sql"
psql -X -A -t -q "$DB" <"$WORK/lock.sql" >"$WORK/lock.out" 2>&1 &
LOCKER=$!
exec 7>"$WORK/lock.sql"
echo "BEGIN; LOCK TABLE smd_blobs IN ACCESS EXCLUSIVE MODE; SELECT 'locked';" >&7
poll 20 grep -q '^locked$' "$WORK/lock.out"
node w4 worker --workers 1 --lease "$LEASE" --database-lock-timeout $((60 * SLOW)) ||
    not_ok "node w4 starts"
claimed() { [ "$(psql_val "SELECT state || ' ' || attempt FROM smd_jobs WHERE id = '$uid'")" = "running 1" ]; }
poll 20 claimed
kill -TERM "${NODE_PID[w4]}"
poll 20 grep -q '"event":"shutting_down"' "${NODE_LOG[w4]}"
echo "COMMIT;" >&7
exec 7>&-
wait "$LOCKER"
t0=$SECONDS
wait "${NODE_PID[w4]}" 2>/dev/null
ubk=$(psql_val "SELECT state || ' ' || attempt || ' ' || (lease_token IS NULL) FROM smd_jobs WHERE id = '$uid'")
released=$(grep -c "\"event\":\"job_released\",\"msg\":\"job $uid:" "${NODE_LOG[w4]}")
node w5 worker --workers 1 --lease "$LEASE" || not_ok "node w5 starts"
on api1
poll 30 state_is "$uid" successful
all "a worker node stopped while its claim copied the job gives it back at its stop, no attempt used ($((SECONDS - t0)) s to the end)" \
    "$ubk|=|accepted 0 true" "$released|=|1" "$(job_state "$uid")|=|successful" \
    "$(psql_val "SELECT attempt FROM smd_jobs WHERE id = '$uid'")|=|1"

# ---------------------------------------------------- retention, once
for nd in api1 api2 w5; do kill -TERM "${NODE_PID[$nd]}" 2>/dev/null; done
for nd in api1 api2 w5; do wait "${NODE_PID[$nd]}" 2>/dev/null; done
for nr in r1:api r2:api rw:worker; do
    node "${nr%%:*}" "${nr#*:}" --workers 1 --lease "$LEASE" --retention 2 || not_ok "node ${nr%%:*} starts"
done
on r1
e1=$(submit "$DISK" "$BOX" "$BOXSOL" "$(quick_params 5)")
on r2
e2=$(submit "$DISK" "$BOX" "$BOXSOL" "$(quick_params 5)")
gone() {
    local nd id
    for nd in r1 r2; do
        on "$nd"
        for id in "$e1" "$e2"; do [ "$(job_state "$id")" = 404 ] || return 1; done
    done
}
poll 30 gone
once=1
for id in "$e1" "$e2"; do
    c=$(cat "${NODE_LOG[r1]}" "${NODE_LOG[r2]}" "${NODE_LOG[rw]}" | grep -c "\"event\":\"job_expired\",\"msg\":\"job $id ")
    [ "$c" = 1 ] || once=0
done
rows=$(psql_val "SELECT count(*) FROM smd_jobs WHERE id IN ('$e1', '$e2')")
all "retention with two API nodes: each job deleted once (one job_expired line), gone from the database and both nodes" \
    "$once|=|1" "$rows|=|0" "${e1:-none}|!=|none" "${e2:-none}|!=|none"
for nd in r1 r2 rw; do kill -TERM "${NODE_PID[$nd]}" 2>/dev/null; done
for nd in r1 r2 rw; do wait "${NODE_PID[$nd]}" 2>/dev/null; done
check "no sanitizer report in any node's log" reports_clean
echo "1..$n"
