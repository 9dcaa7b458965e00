#!/usr/bin/env bash
# A throw-away PostgreSQL for the cluster tests: initdb + pg_ctl from
# Debian's postgresql 15 package into a fresh temporary folder, listening
# on a unix socket in that folder only (no TCP port, nothing shared with
# another suite), trust authentication for the user smtest.  PostgreSQL
# refuses to run as root: as root the server runs as nobody (runuser).
#
#   pg.sh start DIR    initdb (if DIR/data is missing) and start; prints the
#                      libpq connection string on stdout
#   pg.sh stop DIR     fast shutdown (idempotent)
#   pg.sh kill DIR     immediate stop (a crash, for restart tests)
#
# Sourced, it defines pg_start, pg_stop and pg_kill with the same meaning.
PG_BIN=${SM_PG_BIN:-/usr/lib/postgresql/15/bin}

pg__as() { # runs "$@" as the server's user
    if [ "$(id -u)" -eq 0 ]; then
        runuser -u nobody -- "$@"
    else
        "$@"
    fi
}

pg_start() {
    local dir=$1
    mkdir -p "$dir/sock"
    if [ "$(id -u)" -eq 0 ]; then
        chmod 0755 "$dir" && chown nobody "$dir" "$dir/sock" || return 1
    fi
    if [ ! -d "$dir/data" ]; then
        pg__as "$PG_BIN/initdb" -D "$dir/data" -U smtest --auth=trust -E UTF8 --no-sync \
            >"$dir/initdb.log" 2>&1 || { cat "$dir/initdb.log" >&2; return 1; }
    fi
    pg__as "$PG_BIN/pg_ctl" -D "$dir/data" -l "$dir/server.log" -w -t 30 \
        -o "-c listen_addresses='' -c unix_socket_directories='$dir/sock' -c fsync=off -c max_connections=100" \
        start >"$dir/pg_ctl.log" 2>&1 || { cat "$dir/pg_ctl.log" "$dir/server.log" >&2; return 1; }
    echo "host=$dir/sock dbname=postgres user=smtest"
}

pg_stop() {
    [ -f "$1/data/postmaster.pid" ] || return 0
    pg__as "$PG_BIN/pg_ctl" -D "$1/data" -m fast -w -t 30 stop >/dev/null 2>&1
}

pg_kill() {
    [ -f "$1/data/postmaster.pid" ] || return 0
    pg__as "$PG_BIN/pg_ctl" -D "$1/data" -m immediate -w -t 30 stop >/dev/null 2>&1
}

if [ "${BASH_SOURCE[0]}" = "$0" ]; then
    case ${1:-} in
    start) pg_start "$2" ;;
    stop) pg_stop "$2" ;;
    kill) pg_kill "$2" ;;
    *) echo "usage: pg.sh start|stop|kill DIR" >&2; exit 2 ;;
    esac
fi
