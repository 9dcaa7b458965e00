#!/usr/bin/env bash
# Several machines on one PostgreSQL (part of `make bench`; figures, not
# pass/fail), release build, one machine, loopback and a unix socket:
#   - small 2D jobs per minute: the embedded daemon with W workers against
#     one API node + W worker nodes of one worker each (W = 1, 2, 3)
#   - submit -> first progress event through the database (median of 10)
#   - GET /v1/jobs/{id} under wrk (64 connections) on an API node backed by
#     PostgreSQL against the embedded daemon
# All nodes share this machine's cores: the figures show the cost of the
# database path, not the gain of more machines.
# Env: BENCH_JOBS (default 30), BENCH_SECONDS (wrk, default 5).
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT=$PWD
BIN=$ROOT/build/release
OUT=$ROOT/build/bench-cluster
NJOBS=${BENCH_JOBS:-30}
WRK_SECONDS=${BENCH_SECONDS:-5}
rm -rf "$OUT"
mkdir -p "$OUT"
source "$ROOT/tests/lib/pg.sh"
PGDIR=$(mktemp -d /tmp/sm-pg-bench-XXXXXX)
PIDS=()
stop_all() {
    local p
    for p in "${PIDS[@]}"; do kill -TERM "$p" 2>/dev/null || true; done
    for p in "${PIDS[@]}"; do wait "$p" 2>/dev/null || true; done
    PIDS=()
}
trap 'stop_all; pg_stop "$PGDIR"; rm -rf "$PGDIR"' EXIT

printf 'SetFactory("OpenCASCADE");\nDisk(1) = {0, 0, 0, 0.5};\nMesh.CharacteristicLengthMax = 0.08;\n' >"$OUT/disk.geo"
printf 'SetFactory("OpenCASCADE");\nRectangle(1) = {-1.5, -1.5, 0, 3, 3};\nMesh.CharacteristicLengthMax = 0.1;\n' >"$OUT/box.geo"
gmsh -2 "$OUT/disk.geo" -format mesh -o "$OUT/disk.mesh" -v 0 >/dev/null
gmsh -2 "$OUT/box.geo" -format mesh -o "$OUT/box.mesh" -v 0 >/dev/null
awk '{ for (i = 1; i <= NF; i++) tok[++n] = $i }
END {
    for (k = 1; k <= n; k++) if (tok[k] == "Vertices") { nv = tok[++k] + 0; start = k; break }
    printf "MeshVersionFormatted 2\n\nDimension 2\n\nSolAtVertices\n%d\n1 1\n", nv
    for (v = 0; v < nv; v++) { b = start + v * 4; printf "%.17g\n", sqrt(tok[b + 1]^2 + tok[b + 2]^2) - 0.8 }
    printf "\nEnd\n"
}' "$OUT/box.mesh" >"$OUT/box.sol"
PARAMS='{"clamp": {"kind": "ball", "center": [0, 0], "radius": 0.1}, "max_iter": 50}'

# daemon NAME ARGS...: started in the background, sets PORT
daemon() {
    local name=$1
    shift
    "$BIN/shapematchd" --listen 127.0.0.1:0 --spool "$OUT/$name-spool" --worker-threads 1 \
        --retention 0 "$@" 2>"$OUT/$name.log" &
    PIDS+=($!)
    PORT=
    for _ in $(seq 1 200); do
        PORT=$(grep -o '"event":"listening".*"port":[0-9]*' "$OUT/$name.log" 2>/dev/null | grep -o '[0-9]*$' | head -1 || true)
        [ -n "$PORT" ] && return 0
        sleep 0.05
    done
    echo "cluster_bench: $name did not start" >&2
    cat "$OUT/$name.log" >&2
    exit 1
}
submit() {
    curl -sS -F "template=@$OUT/disk.mesh" -F "target_mesh=@$OUT/box.mesh" -F "target_sol=@$OUT/box.sol" \
        -F "params=$PARAMS" "$1/v1/jobs" | jq -r .jobID
}
queued_or_running() { curl -sS "$1/v1/jobs?status=accepted,running&limit=1" | jq .numberMatched; }
# throughput BASE: jobs/minute for NJOBS submitted at once
throughput() {
    local base=$1 t0 t1 i
    t0=$(date +%s.%N)
    for i in $(seq 1 "$NJOBS"); do submit "$base" >/dev/null & done
    wait $(jobs -p | grep -v -F -x -f <(printf '%s\n' "${PIDS[@]}")) 2>/dev/null || true
    sleep 0.3
    while [ "$(queued_or_running "$base")" != 0 ]; do sleep 0.1; done
    t1=$(date +%s.%N)
    awk -v a="$t0" -v b="$t1" -v n="$NJOBS" 'BEGIN { printf "%.0f", n * 60 / (b - a) }'
}
latency() { # BASE: median ms from POST to the first progress event, 10 jobs
    local base=$1 lat=() t0 t1 id
    for _ in $(seq 1 10); do
        t0=$(date +%s.%N)
        id=$(submit "$base")
        curl -sS -N --max-time 30 -H 'Accept: application/x-ndjson' "$base/v1/jobs/$id/events" 2>/dev/null |
            grep -m1 -q '"type":"progress"' || true
        t1=$(date +%s.%N)
        lat+=("$(awk -v a="$t0" -v b="$t1" 'BEGIN { printf "%.1f", (b - a) * 1000 }')")
        while [ "$(queued_or_running "$base")" != 0 ]; do sleep 0.05; done
    done
    printf '%s\n' "${lat[@]}" | sort -n | awk '{ v[NR] = $1 } END { print v[int((NR + 1) / 2)] }'
}
rps() { # BASE ID
    wrk -t2 -c64 -d"${WRK_SECONDS}s" "$1/v1/jobs/$2" 2>&1 | awk '/^Requests\/sec:/ { printf "%.0f", $2 }'
}

declare -A EMB CL
for w in 1 2 3; do
    daemon "emb$w" --workers "$w"
    base=http://127.0.0.1:$PORT
    EMB[$w]=$(throughput "$base")
    if [ "$w" = 1 ]; then
        EMB_LAT=$(latency "$base")
        id=$(submit "$base")
        while [ "$(queued_or_running "$base")" != 0 ]; do sleep 0.05; done
        EMB_RPS=$(rps "$base" "$id")
    fi
    stop_all
done

DB=$(pg_start "$PGDIR")
for w in 1 2 3; do
    psql -X -q "$DB" -c 'DROP TABLE IF EXISTS smd_blobs, smd_events, smd_jobs, smd_schema CASCADE; DROP SEQUENCE IF EXISTS smd_lease_tokens' >/dev/null 2>&1
    daemon "api-$w" --database "$DB" --role api --workers 1
    base=http://127.0.0.1:$PORT
    for k in $(seq 1 "$w"); do daemon "w$k-$w" --database "$DB" --role worker --workers 1; done
    CL[$w]=$(throughput "$base")
    if [ "$w" = 1 ]; then
        CL_LAT=$(latency "$base")
        id=$(submit "$base")
        while [ "$(queued_or_running "$base")" != 0 ]; do sleep 0.05; done
        CL_RPS=$(rps "$base" "$id")
    fi
    stop_all
done

echo "small 2D jobs (180 vertices, 50 iterations), $NJOBS submitted at once, $(nproc) cores shared by every node"
for w in 1 2 3; do
    printf '  %d worker(s): embedded %s jobs/min; PostgreSQL, 1 API node + %d worker node(s): %s jobs/min (%.2fx)\n' \
        "$w" "${EMB[$w]}" "$w" "${CL[$w]}" "$(awk -v a="${CL[$w]}" -v b="${EMB[$w]}" 'BEGIN { print a / b }')"
done
printf '  submit -> first progress event: embedded %s ms, through PostgreSQL %s ms (median of 10)\n' "$EMB_LAT" "$CL_LAT"
printf '  GET /v1/jobs/{id}, wrk 64 connections %ss: embedded %s requests/s, API node on PostgreSQL %s requests/s\n' \
    "$WRK_SECONDS" "$EMB_RPS" "$CL_RPS"
