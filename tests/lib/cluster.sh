# Helpers of the cluster suites (sourced by tests/integration/cluster_*.sh
# after lib.sh; not a suite): a throw-away PostgreSQL (tests/lib/pg.sh),
# stopped on exit even when a test fails, and nodes (shapematchd with
# --database and --role, each with its own spool and log).
source "$(dirname "${BASH_SOURCE[0]}")/pg.sh"

PGDIR=$(mktemp -d /tmp/sm-pg-XXXXXX)
cluster_cleanup() {
    local pid
    for pid in "${DAEMON_PIDS[@]}"; do
        kill -0 "$pid" 2>/dev/null && kill -KILL "$pid" 2>/dev/null
    done
    pg_stop "$PGDIR"
    [ -f "$PGDIR/server.log" ] && [ "$failed" -ne 0 ] && cp "$PGDIR/server.log" "$WORK/postgres.log"
    rm -rf "$PGDIR"
    cleanup
}
trap cluster_cleanup EXIT

# pg_up: starts PostgreSQL, sets DB (the libpq connection string)
pg_up() { DB=$(pg_start "$PGDIR"); }

declare -A NODE_BASE NODE_PID NODE_LOG
# node NAME ROLE [ARGS...]: a node on the database, spool $WORK/NAME-spool
node() {
    local name=$1 role=$2
    shift 2
    SPOOL= start_daemon "$name" --database "$DB" --role "$role" --kill-grace 1 "$@" || return 1
    NODE_BASE[$name]=$BASE
    NODE_PID[$name]=$DPID
    NODE_LOG[$name]=$DLOG
}
# on NAME: later job_state / submit / hcurl calls go to that node
on() { BASE=${NODE_BASE[$1]}; DLOG=${NODE_LOG[$1]}; DPID=${NODE_PID[$1]}; }
# kill9 NAME
kill9() { kill -KILL "${NODE_PID[$1]}" 2>/dev/null; wait "${NODE_PID[$1]}" 2>/dev/null; }
# psql_val SQL: one value from the database
psql_val() { psql -X -A -t -q "$DB" -c "$1" 2>/dev/null; }
# all DESC TEST...: ok when every TEST (a string for `test`, words split
# on "|") holds; the failing ones are printed
all() {
    local desc=$1 t bad=""
    shift
    for t in "$@"; do
        local IFS='|'
        # shellcheck disable=SC2086
        test $t || bad="$bad [$t]"
        unset IFS
    done
    if [ -z "$bad" ]; then ok "$desc"; else not_ok "$desc" "failed:$bad"; fi
}
