#!/usr/bin/env bash
# run.sh: weight 0.25 seconds 40
# Several machines on one PostgreSQL (issue 12): 2 API nodes and 3 worker
# nodes (separate processes, separate spools) on a PostgreSQL 15 started
# here.  Jobs submitted round-robin to both API nodes all end successful,
# each run once (attempt 1, claimed by exactly one worker node), visible
# and identical on both API nodes, results byte-identical to `shapematch
# run`; an event stream followed on one API node resumes on the other
# with Last-Event-ID without loss or repeat; the worker node running a job
# is killed (-9): the job completes on another node as attempt 2.  A run
# that finishes without converging (2 iterations) is successful with
# "converged": false and the message "finished, not converged: ..." on
# both API nodes (the one that did not take it learns it from the
# finished event), a converged one says true.
source "$(dirname "$0")/lib.sh"
source "$(dirname "$0")/../lib/cluster.sh"

if ! make_case; then
    not_ok "gmsh builds the test meshes" "$(tail -5 "$WORK/case/gmsh.log")"
    exit 1
fi
if ! pg_up; then
    not_ok "PostgreSQL 15 starts (initdb + pg_ctl in $PGDIR)"
    exit 1
fi
ok "PostgreSQL starts in a temporary folder (unix socket only)"

# a lease of 6 s, scaled: renewed every third of it, so a node keeps its
# jobs unless it stalls for 4 s (with 3 s, a node starved on a loaded
# machine lost the job it ran: the kill below then saw attempt 3)
LEASE=$((6 * SLOW))
started=1
# The job the kill below interrupts (max_iter 1001) is held by the worker
# program while it runs on the first node, so that it is still running
# when that node is killed (1000 iterations of it once took 0.3 s on an
# idle machine: it ended before the kill); its second attempt runs.
cat >"$WORK/held-once.sh" <<EOF
#!/bin/sh
if grep -q '"max_iter": 1001,' "\$1/job.json" && mkdir "$WORK/held" 2>/dev/null; then
    while :; do sleep 1; done
fi
exec "$BIN/shapematch-worker" "\$@"
EOF
chmod +x "$WORK/held-once.sh"
for nr in api1:api api2:api w1:worker w2:worker w3:worker; do
    node "${nr%%:*}" "${nr#*:}" --workers 1 --lease "$LEASE" --worker "$WORK/held-once.sh" ||
        started=0
done
if [ "$started" = 1 ] && [ "$(psql_val 'SELECT max(version) FROM smd_schema')" = 3 ]; then
    ok "2 API and 3 worker nodes start together; the schema is migrated once (version 3: batches' members, jobs' names)"
else
    not_ok "the nodes start" "$(tail -n 3 "$WORK"/*.log)"
    exit 1
fi
on api1
code=$(hcurl -o /dev/null -w '%{http_code}' "$BASE/readyz")
check "/readyz of an API node: 200 while the database answers" [ "$code" = 200 ]

# ------------------------------------------------ jobs round-robin
NJOBS=${SM_CLUSTER_JOBS:-10} # the issue says 30: 10 keep the suite short
P=$(quick_params 40)
ids=()
for ((i = 0; i < NJOBS; i++)); do
    on "api$((i % 2 + 1))"
    id=$(submit "$DISK" "$BOX" "$BOXSOL" "$P")
    [ -n "$id" ] && ids+=("$id")
done
check "$NJOBS jobs submitted round-robin to the two API nodes: 201 each" [ "${#ids[@]}" = "$NJOBS" ]

all_final() {
    local id node
    for node in api1 api2; do
        on "$node"
        for id in "${ids[@]}"; do state_in "$id" successful failed dismissed || return 1; done
    done
}
poll 60 all_final
bad=""
for node in api1 api2; do
    on "$node"
    for id in "${ids[@]}"; do
        s=$(job_state "$id")
        [ "$s" = successful ] || bad="$bad $node:$id:$s"
    done
done
all "every job ends successful, seen so on both API nodes" "-z|$bad" "${#ids[@]}|=|$NJOBS"
[ -n "$bad" ] && echo "# $bad"

claims=$(cat "${NODE_LOG[w1]}" "${NODE_LOG[w2]}" "${NODE_LOG[w3]}" |
    jq -r 'select(.event == "job_claimed") | .job' | sort | uniq -c | awk '$1 != 1' | wc -l)
nclaimed=$(cat "${NODE_LOG[w1]}" "${NODE_LOG[w2]}" "${NODE_LOG[w3]}" |
    jq -r 'select(.event == "job_claimed") | .job' | sort -u | wc -l)
attempts=$(psql_val "SELECT count(*) FROM smd_jobs WHERE attempt = 1 AND state = 'successful'")
all "each job claimed by exactly one worker node, run once (attempt 1)" \
    "$claims|=|0" "$nclaimed|=|$NJOBS" "$attempts|=|$NJOBS"
busy=0
for w in w1 w2 w3; do
    c=$(jq -r 'select(.event == "job_claimed") | .job' "${NODE_LOG[$w]}" | wc -l)
    [ "$c" -gt 0 ] && busy=$((busy + 1))
done
echo "# worker nodes that ran jobs: $busy of 3"

# finished, not converged: the same status on both API nodes
on api1
nc=$(submit "$DISK" "$BOX" "$BOXSOL" "$(quick_params 2)")
nc_final() { local node; for node in api1 api2; do on "$node"; state_in "$nc" successful failed || return 1; done; }
poll 60 nc_final
ncdoc=()
for node in api1 api2; do
    on "$node"
    ncdoc+=("$(hcurl "$BASE/v1/jobs/$nc" | jq -r '"\(.status),\(.converged),\(.message | startswith("finished, not converged: max_iterations after 2 iterations"))"')")
    ncdoc+=("$(hcurl "$BASE/v1/jobs/${ids[0]}" | jq -r '"\(.status),\(.converged)"')")
done
all "a run that did not converge: successful, converged false on both API nodes (a converged one: true)" \
    "${ncdoc[0]}|=|successful,false,true" "${ncdoc[2]}|=|successful,false,true" \
    "${ncdoc[1]}|=|successful,true" "${ncdoc[3]}|=|successful,true"

CLI=$WORK/cli
"$BIN/shapematch" run --template "$DISK" --target-mesh "$BOX" --target-sol "$BOXSOL" \
    --clamp-ball 0,0,0.1 --max-iter 40 -o "$CLI" --quiet >"$WORK/cli.log" 2>&1
same=1
for k in 0 1; do
    on "api$((2 - k))" # the other API node than the one that took it
    hcurl -o "$WORK/r$k.mesh" "$BASE/v1/jobs/${ids[$k]}/results/mesh"
    hcurl -o "$WORK/r$k.sol" "$BASE/v1/jobs/${ids[$k]}/results/displacement"
    cmp -s "$WORK/r$k.mesh" "$CLI/result.mesh" && cmp -s "$WORK/r$k.sol" "$CLI/displacement.sol" || same=0
done
check "results fetched from the API node that did not take the job equal shapematch run's, byte for byte" \
    [ "$same" = 1 ]

# events: the same log on both API nodes, seq 1..n, one started (attempt 1)
on api1
hcurl -H 'Accept: application/x-ndjson' "$BASE/v1/jobs/${ids[1]}/events" >"$WORK/e1.ndjson"
on api2
hcurl -H 'Accept: application/x-ndjson' "$BASE/v1/jobs/${ids[1]}/events" >"$WORK/e2.ndjson"
# (the closing status line is made by each node when it is sent: not compared)
grep '"seq"' "$WORK/e1.ndjson" >"$WORK/e1.seq"
grep '"seq"' "$WORK/e2.ndjson" >"$WORK/e2.seq"
seqs=$(jq -r 'select(.seq) | .seq' "$WORK/e1.ndjson" | tr '\n' ' ')
nseq=$(jq -r 'select(.seq) | .seq' "$WORK/e1.ndjson" | wc -l)
started=$(jq -r 'select(.type == "started") | .attempt' "$WORK/e1.ndjson" | tr '\n' ' ')
if cmp -s "$WORK/e1.seq" "$WORK/e2.seq" && [ "$seqs" = "$(seq 1 "$nseq" | tr '\n' ' ')" ] &&
    [ "$started" = "1 " ] && [ "$(jq -r 'select(.seq) | .type' "$WORK/e1.ndjson" | tail -1)" = finished ]; then
    ok "the event log is the same on both API nodes: seq 1..$nseq, one started (attempt 1), finished last"
else
    not_ok "event logs of the two API nodes" "seqs $seqs" "started $started" "$(diff "$WORK/e1.seq" "$WORK/e2.seq" | head)"
fi

# ------------------------------------------- kill -9 a worker node mid-job
SLOWP=$(echo "$BALL_PARAMS, \"max_iter\": 1001, \"tol_step\": 1e-15, \"tol_stall\": 0}")
on api1
kid=$(submit "$FINE" "$BOX" "$BOXSOL" "$SLOWP")
runner=""
find_runner() {
    local w
    for w in w1 w2 w3; do
        if grep -q "\"event\":\"job_started\",\"job\":\"$kid\"" "${NODE_LOG[$w]}"; then
            runner=$w
            return 0
        fi
    done
    return 1
}
poll 20 find_runner
if [ -z "$runner" ]; then
    not_ok "a worker node starts the long job"
    exit 1
fi
on api2
poll 10 state_is "$kid" running
kill9 "$runner"
pkill -KILL -P "${NODE_PID[$runner]}" 2>/dev/null # (its worker process, if still there)
t0=$SECONDS
poll 60 state_in "$kid" successful failed
s=$(job_state "$kid")
att=$(psql_val "SELECT attempt FROM smd_jobs WHERE id = '$kid'")
other=$(for w in w1 w2 w3; do [ "$w" != "$runner" ] && jq -r --arg id "$kid" \
    'select(.event == "job_claimed" and .job == $id) | .attempt' "${NODE_LOG[$w]}"; done | tr '\n' ' ')
if [ "$s" = successful ] && [ "$att" = 2 ] && [ "$other" = "2 " ]; then
    ok "kill -9 of the worker node running a job ($runner): it completes on another node as attempt 2 ($((SECONDS - t0)) s)"
else
    not_ok "a job whose worker node was killed" "state $s attempt $att other-node claims '$other' runner $runner"
fi
hcurl -H 'Accept: application/x-ndjson' "$BASE/v1/jobs/$kid/events" >"$WORK/k.ndjson"
kseq=$(jq -r 'select(.seq) | .seq' "$WORK/k.ndjson" | tr '\n' ' ')
kn=$(jq -r 'select(.seq) | .seq' "$WORK/k.ndjson" | wc -l)
kst=$(jq -r 'select(.type == "started") | .attempt' "$WORK/k.ndjson" | tr '\n' ' ')
all "its events: seq 1..$kn without gap or repeat, started twice (attempts 1 and 2)" \
    "$kseq|=|$(seq 1 "$kn" | tr '\n' ' ')" "$kst|=|1 2 " "$kn|-gt|10"

for nd in api1 api2 w1 w2 w3; do
    [ "$nd" = "$runner" ] && continue
    kill -TERM "${NODE_PID[$nd]}" 2>/dev/null
done
for nd in api1 api2 w1 w2 w3; do
    [ "$nd" = "$runner" ] && continue
    wait "${NODE_PID[$nd]}" 2>/dev/null
done
check "no sanitizer report in any node's log" reports_clean
echo "1..$n"
