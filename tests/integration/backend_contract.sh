#!/usr/bin/env bash
# run.sh: weight 0.25 seconds 70
# The backend contract (server/jobs/smd_backend.h): the same cases, the
# same expectations, against both backends through the daemon's API:
#   spool        one daemon on its own spool
#   postgresql   one node (--role all) on a PostgreSQL 15 started here in
#                a temporary folder (tests/lib/pg.sh, unix socket only)
# Cases: submit and run (claimed by this node's pool, attempt 1);
# Idempotency-Key (the retry gets the same job, 200; another key a new
# one); cancel of a queued job and of a running one; delete of a final
# job; a daemon stop while a job runs (it runs again after the restart,
# attempt 2); the node killed (-9) while a job runs: it runs again when
# the node is back (the spool: recovery at start; PostgreSQL: the lease
# expires); retention (the final job deleted after --retention); a job's
# name kept across a restart (the spool's record, PostgreSQL's column); a run
# that finishes without converging (2 iterations of the disk: its boundary
# error 2.6 times the background's resolution) is successful with
# "converged": false in its status, finished event and summary, the 20-
# iteration run "converged": true (the status document is the engine's,
# stored by each backend's record); a batch whose model job waits while a
# member runs, and is built, then survives a restart.
# PostgreSQL's lease fencing across several nodes is cluster_failover.sh's.
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

# The endless runs (the cases of a running job: cancel, stop, kill) are
# held by the worker program below: running, their started event sent by
# the daemon, and no other.  (Computing, one sent ~750 progress events a
# second: on a loaded machine the PostgreSQL node's outbox fell thousands
# behind, a stop took 48 s, and a DELETE's dismissal was still in the
# outbox at the next kill.)  The daemon's SIGTERM, or its death (the
# worker's parent-death signal), ends a held run.
cat >"$WORK/worker.sh" <<EOF
#!/bin/sh
if grep -q '"max_iter": 100000000,' "\$1/job.json"; then
    while :; do sleep 1; done
fi
exec "$BIN/shapematch-worker" "\$@"
EOF
chmod +x "$WORK/worker.sh"

# start BACKEND NAME: the daemon of that backend (WORKERS workers, one by
# default), same spool and database on a restart
start() {
    local backend=$1 name=$2
    shift 2
    case $backend in
    spool) SPOOL=$WORK/$name-spool start_daemon "$name" --workers "${WORKERS:-1}" --kill-grace 1 \
        --shutdown-grace 1 --worker "$WORK/worker.sh" "$@" ;;
    postgresql) SPOOL=$WORK/$name-spool start_daemon "$name" --database "$DB" --role all \
        --workers "${WORKERS:-1}" --kill-grace 1 --shutdown-grace 1 --lease 10 --worker "$WORK/worker.sh" "$@" ;;
    esac
}

# started_attempts ID: the attempts of its "started" events in the log
# (the stream of a live job stays open: read for 2 s)
started_attempts() {
    hcurl --max-time 2 -H 'Accept: application/x-ndjson' "$BASE/v1/jobs/$1/events" 2>/dev/null |
        jq -r 'select(.type == "started") | .attempt' 2>/dev/null | tr '\n' ' '
}
# wait_attempts ID WANT SECONDS: until its started attempts are WANT; the
# last ones read are in $seen_attempts (the verdicts use what the wait saw:
# a read after it may be cut short on a loaded machine)
seen_attempts=
wait_attempts() {
    local end=$((SECONDS + $3 * SLOW))
    while [ $SECONDS -lt $end ]; do
        seen_attempts=$(started_attempts "$1")
        [ "$seen_attempts" = "$2" ] && return 0
        sleep 0.5
    done
    return 1
}

# settled BACKEND ID: nothing but job ID is live in the shared store (the
# spool: always).  A final state this node reached (a cancel) goes to the
# database through an outbox under the lease: a kill -9 before it is out
# leaves the database saying "running", and the job runs again elsewhere
# (the outbox is in memory: a known gap, not this case).  The kill case
# below tests a crash while one job runs, not that window.
settled() {
    [ "$1" = spool ] && return 0
    [ "$(psql_val "SELECT count(*) FROM smd_jobs WHERE state IN ('accepted', 'running')
        AND id <> '$2'")" = 0 ]
}

delete_code() { hcurl -o /dev/null -w '%{http_code}' -X DELETE "$BASE/v1/jobs/$1"; }
get_code() { hcurl -o /dev/null -w '%{http_code}' "$BASE/v1/jobs/$1"; }

contract() {
    local b=$1 name=$1
    if ! start "$b" "$name"; then
        not_ok "$b: the daemon starts"
        return
    fi

    # ---- submit, claim, run
    local id
    id=$(submit "$DISK" "$BOX" "$BOXSOL" "$(quick_params 20)")
    local code
    code=$(cat "$WORK/submit.code")
    wait_final "$id" 60
    wait_attempts "$id" "1 " 10
    all "$b: a submitted job is accepted (201), run here once (attempt 1) and successful" \
        "$code|=|201" "$(job_state "$id")|=|successful" "$seen_attempts|=|1 "

    # ---- finished, not converged: successful with converged false
    local nc
    nc=$(submit "$DISK" "$BOX" "$BOXSOL" "$(quick_params 2)")
    wait_final "$nc" 60
    local ncs ncf ncr ys
    ncs=$(hcurl "$BASE/v1/jobs/$nc" | jq -r '"\(.status),\(.converged),\(.message | startswith("finished, not converged: max_iterations after 2"))"')
    ncf=$(hcurl "$BASE/v1/jobs/$nc/events" | jq -r 'select(.type == "finished") | "\(.converged),\(.result.converged)"')
    ncr=$(hcurl "$BASE/v1/jobs/$nc/results" | jq -r .converged)
    ys=$(hcurl "$BASE/v1/jobs/$id" | jq -r '"\(.status),\(.converged)"')
    all "$b: a run that did not converge: successful, converged false (status, event, summary)" \
        "$ncs|=|successful,false,true" "$ncf|=|false,false" "$ncr|=|false" "$ys|=|successful,true"

    # ---- Idempotency-Key
    local k1 k1c k2 k2c k3
    k1=$(submit "$DISK" "$BOX" "$BOXSOL" "$(quick_params 5)" -H "Idempotency-Key: $b-1")
    k1c=$(cat "$WORK/submit.code")
    k2=$(submit "$DISK" "$BOX" "$BOXSOL" "$(quick_params 5)" -H "Idempotency-Key: $b-1")
    k2c=$(cat "$WORK/submit.code")
    k3=$(submit "$DISK" "$BOX" "$BOXSOL" "$(quick_params 5)" -H "Idempotency-Key: $b-2")
    all "$b: Idempotency-Key: the retry gets the same job (200), another key a new one (201)" \
        "$k1c|=|201" "$k2c|=|200" "-n|$k1" "$k1|=|$k2" "-n|$k3" "$k3|!=|$k1"
    wait_final "$k1" 60
    wait_final "$k3" 60

    # ---- cancel: running, and queued behind it
    local run queued
    run=$(submit "$FINE" "$BOX" "$BOXSOL" "$(endless_params)")
    poll 30 state_is "$run" running
    queued=$(submit "$DISK" "$BOX" "$BOXSOL" "$(quick_params 5)")
    local qs
    qs=$(job_state "$queued")
    local qc rc
    qc=$(delete_code "$queued")
    rc=$(delete_code "$run")
    poll 30 state_is "$run" dismissed
    poll 30 state_is "$queued" dismissed
    all "$b: DELETE of a queued job and of a running one: both dismissed" \
        "$qs|=|accepted" "$qc|=|200" "$rc|=|200" "$(job_state "$queued")|=|dismissed" \
        "$(job_state "$run")|=|dismissed"

    # ---- delete a final job
    local dc gc
    dc=$(delete_code "$id")
    gc=$(get_code "$id")
    all "$b: DELETE of a final job: gone (404 after)" "$dc|=|200" "$gc|=|404"

    # ---- a stop while a job runs: it runs again after the restart; a
    # job's name is kept by the backend across it
    local named
    named=$(submit "$DISK" "$BOX" "$BOXSOL" "$(quick_params 2)" -F "name=$b: «disk» #2")
    wait_final "$named" 60
    run=$(submit "$FINE" "$BOX" "$BOXSOL" "$(endless_params)")
    poll 30 state_is "$run" running
    # the first attempt's started event stored before the stop (as below
    # for the kill: one still in the node's outbox when the restart comes
    # after the lease is fenced out, a known gap, not this case)
    wait_attempts "$run" "1 " 30
    stop_daemon
    local after="" kept="" listed=""
    if start "$b" "$name"; then
        wait_attempts "$run" "1 2 " 30
        after=$seen_attempts
        kept=$(hcurl "$BASE/v1/jobs/$named" | jq -r .name)
        listed=$(hcurl "$BASE/v1/jobs?limit=1000" | jq -r --arg id "$named" '.jobs[] | select(.jobID == $id) | .name')
    fi
    all "$b: a job running at a daemon stop runs again after the restart (attempt 2)" \
        "$after|=|1 2 "
    all "$b: a job's name (part name) is in its status and the list after a restart" \
        "$kept|=|$b: «disk» #2" "$listed|=|$b: «disk» #2"
    delete_code "$run" >/dev/null
    poll 30 state_is "$run" dismissed

    # ---- the node killed while a job runs: it runs again when it is back
    run=$(submit "$FINE" "$BOX" "$BOXSOL" "$(endless_params)")
    poll 30 state_is "$run" running
    poll 30 settled "$b" "$run"
    # the first attempt's started event stored before the kill: an event
    # still in the node's outbox dies with it (a known gap, not what this
    # case checks), and a loaded machine widens that window
    wait_attempts "$run" "1 " 30
    local wpid
    wpid=$(worker_pid "$run")
    kill -KILL "$DPID" 2>/dev/null
    wait "$DPID" 2>/dev/null
    [ -n "$wpid" ] && kill -KILL "$wpid" 2>/dev/null
    after=""
    if start "$b" "$name"; then
        wait_attempts "$run" "1 2 " 60
        after=$seen_attempts
    fi
    all "$b: the node killed (-9) while a job runs: the job runs again when it is back (attempt 2)" \
        "$after|=|1 2 "
    delete_code "$run" >/dev/null
    poll 30 state_is "$run" dismissed

    # ---- a batch: the model job waits for its members (two workers: one
    # runs a member that never ends, the other must not take the model),
    # then is built from the two that succeeded; it survives a restart
    # (its record valid, its members and model files kept)
    stop_daemon
    if ! WORKERS=2 start "$b" "$name"; then
        not_ok "$b: the daemon starts again with two workers"
        return
    fi
    # nothing of the cases above still live in the shared store: a run
    # left behind would keep its node's outbox busy with progress events
    # ahead of these members' ends
    delete_code "$run" >/dev/null
    poll 60 settled "$b" none
    local m1 m2 live bid bcode waiting
    m1=$(submit "$DISK" "$BOX" "$BOXSOL" "$(quick_params 5)")
    m2=$(submit "$DISK" "$BOX" "$BOXSOL" "$(quick_params 8)")
    wait_final "$m1" 60
    wait_final "$m2" 60
    live=$(submit "$FINE" "$BOX" "$BOXSOL" "$(endless_params)")
    poll 30 state_is "$live" running
    bcode=$(hcurl -o "$WORK/batch.out" -w '%{http_code}' -H 'Content-Type: application/json' \
        --data-binary "{\"targets\": [{\"job\": \"$m1\", \"name\": \"a\"}, {\"job\": \"$m2\",
        \"name\": \"b\"}, {\"job\": \"$live\", \"name\": \"c\"}], \"model_align\": \"rigid\"}" \
        "$BASE/v1/batches")
    bid=$(jq -r '.batchID // empty' "$WORK/batch.out")
    sleep $((3 * SLOW))
    waiting="$(job_state "$bid"),$(hcurl "$BASE/v1/batches/$bid" | jq -r .status)"
    delete_code "$live" >/dev/null
    wait_final "$bid" 120
    local bmsg before_mean
    bmsg=$(hcurl "$BASE/v1/jobs/$bid" | jq -r .message)
    before_mean=$(hcurl "$BASE/v1/batches/$bid/model/mean.mesh" | sha256sum)
    all "$b: a batch's model job waits while a member runs, then is built from the members that succeeded" \
        "$bcode|=|201" "$waiting|=|accepted,running" "$(job_state "$bid")|=|successful" \
        "$bmsg|=|finished: model of 2 of 3 targets (left out, without a result: c)"
    stop_daemon
    local after_doc after_mean after_codes
    if WORKERS=2 start "$b" "$name"; then
        # PostgreSQL: the node's replica catches up with the database
        batch_back() { [ "$(hcurl "$BASE/v1/batches/$bid" | jq -r .status)" = successful ]; }
        poll 30 batch_back
        after_doc=$(hcurl "$BASE/v1/batches/$bid" | jq -r '"\(.status),\(.counts.successful),\(.counts.dismissed),\(.model.status)"')
        after_mean=$(hcurl "$BASE/v1/batches/$bid/model/mean.mesh" | sha256sum)
        after_codes="$(get_code "$m1") $(get_code "$m2") $(get_code "$live") $(hcurl -o /dev/null -w '%{http_code}' "$BASE/v1/batches/$bid/model")"
    fi
    all "$b: a batch survives a restart: its document, its model job (successful), its members and model files" \
        "$after_doc|=|successful,2,1,successful" "$after_codes|=|200 200 200 200" \
        "$after_mean|=|$before_mean" "$(grep -c job_quarantined "$DLOG")|=|0"

    # ---- retention: final jobs are deleted after --retention (3 s, scaled)
    # The final state is the one the wait saw: asked again afterwards, a
    # loaded machine could already be past the retention (2 s once).
    local keep=$((3 * SLOW))
    stop_daemon
    if ! start "$b" "$name" --retention "$keep"; then
        not_ok "$b: the daemon starts again with --retention $keep"
        return
    fi
    id=$(submit "$DISK" "$BOX" "$BOXSOL" "$(quick_params 5)")
    local fs=
    final_seen() {
        fs=$(job_state "$id")
        case $fs in successful | failed | dismissed) return 0 ;; esac
        return 1
    }
    poll 60 final_seen
    expired() { [ "$(get_code "$id")" = 404 ]; }
    poll $((20 + keep)) expired
    all "$b: a final job is deleted after --retention" "$fs|=|successful" "$(get_code "$id")|=|404"

    stop_daemon
    check "$b: the daemon stops cleanly" [ $? = 0 ]
}

contract spool
contract postgresql
echo "1..$n"
