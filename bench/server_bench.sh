#!/usr/bin/env bash
# Daemon benchmark (part of `make bench`; figures, not pass/fail), on the
# release build, loopback only, bounded to about a minute:
#   - GET /v1/jobs/{id} under wrk, 64 connections: requests/s and p99
#   - submit-to-first-event latency: from the start of POST /v1/jobs to the
#     first progress event read from /events (worker start, input reading
#     and setup included), median and worst of 10, pool idle
#   - throughput of small 2D jobs with the pool full (jobs per minute)
#   - daemon RSS idle, under wrk and while the pool is full
# Env: BENCH_SECONDS (wrk duration, default 5), BENCH_JOBS (default 40).
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT=$PWD
BIN=$ROOT/build/release
OUT=$ROOT/build/bench-server
WRK_SECONDS=${BENCH_SECONDS:-5}
NJOBS=${BENCH_JOBS:-40}
WORKERS=$(nproc)
rm -rf "$OUT"
mkdir -p "$OUT"
for tool in wrk curl jq gmsh; do
    command -v "$tool" >/dev/null || { echo "server_bench: $tool is missing (make deps)" >&2; exit 1; }
done

# ---- a small 2D case (the disk of the integration tests)
cat >"$OUT/disk.geo" <<'EOF'
SetFactory("OpenCASCADE");
Disk(1) = {0, 0, 0, 0.5};
Mesh.CharacteristicLengthMax = 0.08;
EOF
cat >"$OUT/box.geo" <<'EOF'
SetFactory("OpenCASCADE");
Rectangle(1) = {-1.5, -1.5, 0, 3, 3};
Mesh.CharacteristicLengthMax = 0.1;
EOF
gmsh -2 "$OUT/disk.geo" -format mesh -o "$OUT/disk.mesh" -v 0 >/dev/null
gmsh -2 "$OUT/box.geo" -format mesh -o "$OUT/box.mesh" -v 0 >/dev/null
awk '{ for (i = 1; i <= NF; i++) tok[++n] = $i }
END {
    for (k = 1; k <= n; k++) if (tok[k] == "Vertices") { nv = tok[++k] + 0; start = k; break }
    printf "MeshVersionFormatted 2\n\nDimension 2\n\nSolAtVertices\n%d\n1 1\n", nv
    for (v = 0; v < nv; v++) {
        b = start + v * 4
        printf "%.17g\n", sqrt(tok[b + 1]^2 + tok[b + 2]^2) - 0.8
    }
    printf "\nEnd\n"
}' "$OUT/box.mesh" >"$OUT/box.sol"
PARAMS='{"clamp": {"kind": "ball", "center": [0, 0], "radius": 0.1}, "max_iter": 50}'

# ---- the daemon, configured as by default (one JSON log line per request)
"$BIN/shapematchd" --listen 127.0.0.1:0 --spool "$OUT/spool" --workers "$WORKERS" \
    --retention 0 2>"$OUT/daemon.log" &
DPID=$!
trap 'kill -TERM $DPID 2>/dev/null; wait $DPID 2>/dev/null' EXIT
PORT=
for _ in $(seq 1 200); do
    PORT=$(jq -r 'select(.event == "listening") | .port' "$OUT/daemon.log" 2>/dev/null | head -1)
    [ -n "$PORT" ] && break
    sleep 0.05
done
[ -n "$PORT" ] || { echo "server_bench: the daemon did not start" >&2; cat "$OUT/daemon.log" >&2; exit 1; }
BASE=http://127.0.0.1:$PORT
rss_kb() { awk '/^VmRSS:/ { print $2 }' "/proc/$DPID/status"; }
submit() {
    curl -sS -F "template=@$OUT/disk.mesh" -F "target_mesh=@$OUT/box.mesh" -F "target_sol=@$OUT/box.sol" \
        -F "params=$PARAMS" "$BASE/v1/jobs" | jq -r .jobID
}
state() { curl -sS "$BASE/v1/jobs/$1" | jq -r .status; }

sleep 0.5
RSS_IDLE=$(rss_kb)

# ---- GET /v1/jobs/{id} under wrk
ID=$(submit)
for _ in $(seq 1 100); do [ "$(state "$ID")" = successful ] && break; sleep 0.1; done
wrk -t2 -c64 -d"${WRK_SECONDS}s" --latency "$BASE/v1/jobs/$ID" >"$OUT/wrk.txt" 2>&1 &
WPID=$!
RSS_WRK=0
while kill -0 $WPID 2>/dev/null; do
    r=$(rss_kb)
    [ "$r" -gt "$RSS_WRK" ] && RSS_WRK=$r
    sleep 0.2
done
wait $WPID
RPS=$(awk '/^Requests\/sec:/ { print $2 }' "$OUT/wrk.txt")
P50=$(awk '$1 == "50%" { print $2 }' "$OUT/wrk.txt")
P99=$(awk '$1 == "99%" { print $2 }' "$OUT/wrk.txt")
ERRS=$(awk '/Non-2xx|Socket errors/' "$OUT/wrk.txt" | tr '\n' ' ')

# ---- submit-to-first-event latency (pool idle)
lat=()
for _ in $(seq 1 10); do
    t0=$(date +%s.%N)
    id=$(submit)
    curl -sS -N --max-time 30 "$BASE/v1/jobs/$id/events" 2>/dev/null | grep -m1 -q '"type":"progress"' || true
    t1=$(date +%s.%N)
    lat+=("$(awk -v a="$t0" -v b="$t1" 'BEGIN { printf "%.1f", (b - a) * 1000 }')")
    for _ in $(seq 1 100); do [ "$(state "$id")" = successful ] && break; sleep 0.05; done
done
LAT_MED=$(printf '%s\n' "${lat[@]}" | sort -n | awk '{ v[NR] = $1 } END { print v[int((NR + 1) / 2)] }')
LAT_MAX=$(printf '%s\n' "${lat[@]}" | sort -n | tail -1)

# ---- throughput with the pool full
t0=$(date +%s.%N)
pids=()
for i in $(seq 1 "$NJOBS"); do
    submit >"$OUT/tp$i.id" &
    pids+=($!)
done
wait "${pids[@]}"
RSS_LOAD=0
while :; do
    r=$(rss_kb)
    [ "$r" -gt "$RSS_LOAD" ] && RSS_LOAD=$r
    n=$(curl -sS "$BASE/v1/jobs?status=accepted,running&limit=1" | jq .numberMatched)
    [ "$n" = 0 ] && break
    sleep 0.1
done
t1=$(date +%s.%N)
DONE=$(curl -sS "$BASE/v1/jobs?status=successful&limit=1" | jq .numberMatched)
JPM=$(awk -v a="$t0" -v b="$t1" -v n="$NJOBS" 'BEGIN { printf "%.0f", n * 60 / (b - a) }')
SECS=$(awk -v a="$t0" -v b="$t1" 'BEGIN { printf "%.2f", b - a }')

kill -TERM $DPID
wait $DPID || true
trap - EXIT

echo "shapematchd on 127.0.0.1, $WORKERS workers, $(nproc) cores (release build)"
printf '  GET /v1/jobs/{id}, wrk 64 connections %ss (request log on): %s requests/s, p50 %s, p99 %s %s\n' \
    "$WRK_SECONDS" "$RPS" "$P50" "$P99" "$ERRS"
printf '  submit -> first progress event: median %s ms, worst %s ms (10 jobs, pool idle)\n' "$LAT_MED" "$LAT_MAX"
printf '  throughput, pool full: %s small 2D jobs (180 vertices, 50 iterations) in %s s = %s jobs/min (%s successful)\n' \
    "$NJOBS" "$SECS" "$JPM" "$((DONE - 11))"
printf '  daemon RSS: idle %s KiB, under wrk %s KiB, pool full %s KiB\n' "$RSS_IDLE" "$RSS_WRK" "$RSS_LOAD"
cat >"$OUT/figures.txt" <<EOF
requests_per_s=$RPS p99=$P99 first_event_ms_median=$LAT_MED first_event_ms_max=$LAT_MAX
jobs_per_min=$JPM rss_idle_kb=$RSS_IDLE rss_wrk_kb=$RSS_WRK rss_load_kb=$RSS_LOAD
EOF
