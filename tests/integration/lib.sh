# Helpers of the shapematchd integration suites (sourced, not run).
#
# Each suite gets a fresh folder build/test-integration/<variant>-<suite>-<pid>/
# (spools, daemon logs, test meshes), real daemons on free loopback ports
# (--listen 127.0.0.1:0, the port is read back from the "listening" log
# line), real curl, and prints TAP lines.  Daemons started here are killed
# on exit (by their pid).  Waiting is always polling with a deadline, never
# a bare sleep.
# Shared by the daemon, client, demo and deploy suites: keep its functions'
# meaning stable.
# Env: SM_BIN (binaries of the variant), SM_ROOT (repo root), SM_VARIANT;
# SM_TEST_KEEP=1 keeps the folder of a passing run, SM_TEST_TIMING=1 prints
# the elapsed time after each ok line.
set -u
ROOT=${SM_ROOT:-$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)}
BIN=${SM_BIN:-$ROOT/build/release}
VARIANT=${SM_VARIANT:-release}
SUITE=$(basename "$0" .sh)
WORK=$ROOT/build/test-integration/$VARIANT-$SUITE-$$
rm -rf "$WORK"
mkdir -p "$WORK"
# sanitizer builds run slower: deadlines scale
SLOW=1
[ "$VARIANT" = asan ] && SLOW=4

source "$(dirname "${BASH_SOURCE[0]}")/../lib/tap.sh"

DAEMON_PIDS=()
cleanup() {
    local pid
    for pid in "${DAEMON_PIDS[@]}"; do
        kill -0 "$pid" 2>/dev/null && kill -KILL "$pid" 2>/dev/null
    done
    for pid in "${DAEMON_PIDS[@]}"; do wait "$pid" 2>/dev/null; done
    if [ "$failed" -eq 0 ] && [ -z "${SM_TEST_KEEP:-}" ]; then
        rm -rf "$WORK"
    else
        echo "# kept $WORK for inspection"
    fi
}
trap cleanup EXIT

# poll SECONDS COMMAND...: runs COMMAND every 0.1 s until it succeeds or
# the deadline (scaled for sanitizer builds) passes.
poll() {
    local limit
    limit=$(awk -v s="$1" -v k="$SLOW" 'BEGIN { printf "%d", s * k * 10 }')
    shift
    local i
    for ((i = 0; i < limit; i++)); do
        "$@" && return 0
        sleep 0.1
    done
    "$@"
}

# ---------------------------------------------------------------- daemons

DPID=
BASE=
DLOG=
SPOOL=
# start_daemon NAME [ARGS...]: a daemon with spool $WORK/NAME-spool (or
# $SPOOL if set by the caller), log $WORK/NAME.log; sets DPID, BASE, DLOG.
start_daemon() {
    local name=$1
    shift
    SPOOL=${SPOOL:-$WORK/$name-spool}
    DLOG=$WORK/$name.log
    # a restart appends to the same log: wait for one more "listening" line
    local before=0
    [ -f "$DLOG" ] && before=$(grep -c '"event":"listening"' "$DLOG")
    # one numerical thread per worker: small jobs gain nothing from more,
    # and on a loaded machine spinning BLAS threads make run times erratic
    "$BIN/shapematchd" --listen 127.0.0.1:0 --spool "$SPOOL" --worker-threads 1 "$@" 2>>"$DLOG" &
    DPID=$!
    DAEMON_PIDS+=("$DPID")
    local port=
    local i
    for ((i = 0; i < 400 * SLOW; i++)); do
        if [ -f "$DLOG" ] && [ "$(grep -c '"event":"listening"' "$DLOG")" -gt "$before" ]; then
            port=$(jq -r 'select(.event == "listening") | .port' "$DLOG" 2>/dev/null | tail -1)
            break
        fi
        kill -0 "$DPID" 2>/dev/null || break
        sleep 0.05
    done
    if [ -z "$port" ]; then
        echo "# daemon $name did not start:" >&2
        sed 's/^/#   /' "$DLOG" >&2
        return 1
    fi
    BASE=http://127.0.0.1:$port
    return 0
}

# stop_daemon: SIGTERM and wait for a clean exit; returns its status.
stop_daemon() {
    [ -n "$DPID" ] || return 0
    kill -TERM "$DPID" 2>/dev/null
    local i
    for ((i = 0; i < 600 * SLOW; i++)); do
        kill -0 "$DPID" 2>/dev/null || break
        sleep 0.05
    done
    if kill -0 "$DPID" 2>/dev/null; then
        kill -KILL "$DPID" 2>/dev/null
        wait "$DPID" 2>/dev/null
        DPID=
        return 124
    fi
    wait "$DPID"
    local rc=$?
    DPID=
    return $rc
}

# wait_daemon_exit SECONDS: the daemon (already signalled) exits by itself;
# returns its status (124 when it does not: it is then killed).
wait_daemon_exit() {
    local i
    for ((i = 0; i < $1 * 20 * SLOW; i++)); do
        kill -0 "$DPID" 2>/dev/null || break
        sleep 0.05
    done
    if kill -0 "$DPID" 2>/dev/null; then
        kill9_daemon
        return 124
    fi
    wait "$DPID"
    local rc=$?
    DPID=
    return $rc
}

# kill9_daemon: SIGKILL, no chance to clean up.
kill9_daemon() {
    kill -KILL "$DPID" 2>/dev/null
    wait "$DPID" 2>/dev/null
    DPID=
}

# sanitizer or runtime-error reports in the daemon log or any worker log
reports_clean() {
    ! grep -lE 'Sanitizer|runtime error|LeakSanitizer' "$WORK"/*.log \
        "$WORK"/*-spool/jobs/*/worker.log 2>/dev/null | grep -q .
}

# ------------------------------------------------------------------- jobs

# curl with the common options; the body on stdout
hcurl() { curl -sS --max-time $((30 * SLOW)) "$@"; }

# job_state ID: the job's status, or the HTTP code when it is not 200
job_state() {
    local body code
    body=$(curl -sS --max-time 10 -w '\n%{http_code}' "${AUTH[@]}" "$BASE/v1/jobs/$1")
    code=${body##*$'\n'}
    # no jq here: this runs in polling loops on a busy machine
    if [ "$code" = 200 ] && [[ $body =~ \"status\":\ \"([a-z]+)\" ]]; then
        echo "${BASH_REMATCH[1]}"
    else
        echo "$code"
    fi
}
AUTH=()
state_is() { [ "$(job_state "$1")" = "$2" ]; }
# readyz_is CODE: the daemon's /readyz answers CODE (a drain after SIGTERM
# is seen a moment after the signal: poll it)
readyz_is() { [ "$(curl -sS -o /dev/null -w '%{http_code}' "$BASE/readyz")" = "$1" ]; }
# worker_copy JOB-DIR NAME SED-SCRIPT: the worker program run again, one
# thread, on a copy of a job's folder ($WORK/again-NAME: its inputs/, and
# its job.json through the sed script, not jq: the check's key covers the
# params as written); its log in $WORK/again-NAME/worker.log
worker_copy() {
    local dir=$WORK/again-$2
    rm -rf "$dir"
    mkdir -p "$dir"
    cp -r "$1/inputs" "$dir/"
    sed "$3" "$1/job.json" >"$dir/job.json"
    OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 "$BIN/shapematch-worker" "$dir" 3>/dev/null \
        2>"$dir/worker.log"
}
# worker_again JOB-DIR FILE...: the worker run again on three copies of a
# job whose upload check kept what it built (again-kept: as it is;
# again-none: without job.json's "checked"; again-stale: a key that is not
# the job's); 0 when each results/FILE of all three is the job's, byte for
# byte
worker_again() {
    local job=$1 f v
    shift
    worker_copy "$job" kept ''
    worker_copy "$job" none 's/"checked"/"unchecked"/'
    worker_copy "$job" stale 's/"key": "[0-9a-f]*"/"key": "0000000000000000"/'
    for f; do
        for v in kept none stale; do
            cmp -s "$job/results/$f" "$WORK/again-$v/results/$f" || return 1
        done
    done
}
state_in() { # ID STATE... : the state is one of these
    local s
    s=$(job_state "$1")
    shift
    local want
    for want in "$@"; do [ "$s" = "$want" ] && return 0; done
    return 1
}
# wait_state ID STATE SECONDS: gives up early when the job ends in another
# final state (or is gone)
state_reached() {
    local s
    s=$(job_state "$1")
    [ "$s" = "$2" ] && return 0
    case $s in successful | failed | dismissed | 404) [ "$2" = running ] || [ "$2" = accepted ] || return 2 ;; esac
    return 1
}
wait_state() {
    local limit i rc
    limit=$(awk -v s="$3" -v k="$SLOW" 'BEGIN { printf "%d", s * k * 10 }')
    for ((i = 0; i <= limit; i++)); do
        state_reached "$1" "$2"
        rc=$?
        [ "$rc" = 0 ] && return 0
        [ "$rc" = 2 ] && return 1
        sleep 0.1
    done
    return 1
}
# wait_final ID SECONDS: successful, failed or dismissed
wait_final() { poll "$2" state_in "$1" successful failed dismissed; }

# submit TEMPLATE TARGET_MESH TARGET_SOL PARAMS_JSON [CURL ARGS...]: prints
# the new job's id (empty on failure; the response is in $WORK/submit.out)
submit() {
    local t=$1 m=$2 s=$3 p=$4
    shift 4
    hcurl "${AUTH[@]}" -o "$WORK/submit.out" -w '%{http_code}' -F "template=@$t" \
        -F "target_mesh=@$m" -F "target_sol=@$s" -F "params=$p" "$@" "$BASE/v1/jobs" \
        >"$WORK/submit.code" 2>"$WORK/submit.err"
    jq -r '.jobID // empty' "$WORK/submit.out" 2>/dev/null
}

# worker_pid ID: pid of the job's worker from the daemon log (last start)
worker_pid() {
    jq -r --arg id "$1" 'select(.event == "job_started" and .job == $id) | .pid' "$DLOG" | tail -1
}

# ------------------------------------------------------------ test meshes

# A small case made with gmsh: a disk of radius 0.5 (template), a fine disk
# (slow jobs), a box background with the signed distance to the circle of
# radius 0.8, and a 3D cube (for dimension mismatches).  Sets DISK, FINE,
# BOX, BOXSOL, CUBE, CUBESOL, BALL_PARAMS.
# The meshes are made once for every suite of a build (in
# build/test-fixtures/, named by a checksum of their sources; a lock lets
# one suite make them while the others wait) and each suite works on its
# own copy.
make_case() {
    local d=$WORK/case src=$ROOT/tests/lib/case
    mkdir -p "$d" "$ROOT/build/test-fixtures"
    local sum
    sum=$(cat "$src"/{disk,fine,box,cube}.geo "$src/sphere_sdf.awk" | md5sum | cut -c1-16)
    local shared=$ROOT/build/test-fixtures/case-$sum
    if [ ! -f "$shared/done" ]; then
        (
            flock 9
            [ -f "$shared/done" ] && exit 0
            local tmp=$shared.tmp.$$
            rm -rf "$tmp" && mkdir -p "$tmp" || exit 1
            # the geometries and the analytic distance: tests/lib/case/
            cp "$src"/{disk,fine,box,cube}.geo "$tmp/"
            cp "$src/sphere_sdf.awk" "$tmp/sdf.awk"
            (cd "$tmp" && gmsh -2 disk.geo -format mesh -o disk.mesh -v 0 &&
                gmsh -2 fine.geo -format mesh -o fine.mesh -v 0 &&
                gmsh -2 box.geo -format mesh -o box.mesh -v 0 &&
                gmsh -3 cube.geo -format mesh -o cube.mesh -v 0 &&
                awk -v R=0.8 -f sdf.awk box.mesh >box.sol &&
                awk -v R=0.8 -f sdf.awk cube.mesh >cube.sol) >"$tmp/gmsh.log" 2>&1 || exit 1
            touch "$tmp/done" && rm -rf "$shared" && mv "$tmp" "$shared"
        ) 9>"$ROOT/build/test-fixtures/case.lock" || { cp "$shared.tmp."*/gmsh.log "$d/" 2>/dev/null; return 1; }
    fi
    cp "$shared"/* "$d/" || return 1
    rm -f "$d/done"
    DISK=$d/disk.mesh
    FINE=$d/fine.mesh
    BOX=$d/box.mesh
    BOXSOL=$d/box.sol
    CUBE=$d/cube.mesh
    CUBESOL=$d/cube.sol
    BALL_PARAMS='{"clamp": {"kind": "ball", "center": [0, 0], "radius": 0.1}'
    return 0
}
# params for the disk case: a quick job (~0.1 s) and one that runs until
# it is stopped (fine mesh, huge iteration cap)
quick_params() { echo "$BALL_PARAMS, \"max_iter\": ${1:-50}}"; }
endless_params() { echo "$BALL_PARAMS, \"max_iter\": 100000000, \"tol_step\": 1e-15, \"tol_stall\": 0}"; }

# browser_only WHY: a browser suite runs in the release variant only (the
# page is the same in both; WHY names what covers the daemon under the
# sanitizers) and needs Chromium and playwright-core (make deps).
browser_only() {
    if [ "$VARIANT" != release ]; then
        skip "browser tests run in the release variant only ($1)"
        echo "1..$n"
        exit 0
    fi
    if [ ! -x /usr/bin/chromium ] || [ ! -d "$ROOT/node_modules/playwright-core" ]; then
        not_ok "chromium and playwright-core are installed (make deps)" "$(ls -l /usr/bin/chromium 2>&1)"
        echo "1..$n"
        exit 1
    fi
}

# node_checks DESC SCRIPT ARGS...: runs a node driver that prints one JSON
# line {"ok", "desc", "detail"} per check and turns them into TAP lines;
# a driver that exits non-zero is the failed check DESC.
node_checks() {
    local desc=$1 line rc
    shift
    command node "$@" >"$WORK/node.out" 2>"$WORK/node.err"
    rc=$?
    while IFS= read -r line; do
        jq -e 'has("desc")' <<<"$line" >/dev/null 2>&1 || continue
        if [ "$(jq -r .ok <<<"$line")" = true ]; then
            ok "$(jq -r .desc <<<"$line")"
        else
            not_ok "$(jq -r .desc <<<"$line")" "$(jq -r .detail <<<"$line")"
        fi
    done <"$WORK/node.out"
    [ "$rc" = 0 ] || not_ok "$desc" "exit $rc" "$(tail -20 "$WORK/node.err")"
}
