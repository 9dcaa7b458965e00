#!/usr/bin/env bash
# Soak of the daemon (issue 8; part of `make bench`, release build,
# loopback): SOAK_SECONDS (default 600) of mixed load —
#   - status reads: wrk on GET /v1/jobs/{id} (1 thread, 8 connections);
#   - event streams: 8 followers of a job that runs throughout, each
#     reconnecting every 10 s, plus one follower per new job;
#   - submissions: a small 2D job every second, every third one cancelled
#     (DELETE) at once;
# while the daemon's RSS, open descriptors and threads are sampled every
# SOAK_EVERY seconds (default 5).  Prints the series, then first, last and
# max of each, and fails when the last sample exceeds the bound against the
# sample taken after the warm-up (the first fifth of the run):
#   RSS <= 1.5 x warm-up + 16 MiB, fds <= warm-up + 64, threads <= warm-up + 8.
# Finished jobs are kept --retention 30s, so the job table itself stays
# bounded (a growing table would be data, not a leak).
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT=$PWD
BIN=$ROOT/build/release
OUT=$ROOT/build/bench-soak
SECONDS_TOTAL=${SOAK_SECONDS:-600}
EVERY=${SOAK_EVERY:-5}
rm -rf "$OUT"
mkdir -p "$OUT"
for tool in wrk curl jq gmsh; do
    command -v "$tool" >/dev/null || { echo "soak: $tool is missing (make deps)" >&2; exit 1; }
done

# ---- the disk case of the integration tests
printf 'SetFactory("OpenCASCADE");\nDisk(1) = {0, 0, 0, 0.5};\nMesh.CharacteristicLengthMax = 0.08;\n' >"$OUT/disk.geo"
printf 'SetFactory("OpenCASCADE");\nDisk(1) = {0, 0, 0, 0.5};\nMesh.CharacteristicLengthMax = 0.03;\n' >"$OUT/fine.geo"
printf 'SetFactory("OpenCASCADE");\nRectangle(1) = {-1.5, -1.5, 0, 3, 3};\nMesh.CharacteristicLengthMax = 0.1;\n' >"$OUT/box.geo"
for m in disk fine box; do gmsh -2 "$OUT/$m.geo" -format mesh -o "$OUT/$m.mesh" -v 0 >/dev/null; done
awk '{ for (i = 1; i <= NF; i++) tok[++n] = $i }
END {
    for (k = 1; k <= n; k++) if (tok[k] == "Vertices") { nv = tok[++k] + 0; start = k; break }
    printf "MeshVersionFormatted 2\n\nDimension 2\n\nSolAtVertices\n%d\n1 1\n", nv
    for (v = 0; v < nv; v++) { b = start + v * 4; printf "%.17g\n", sqrt(tok[b + 1]^2 + tok[b + 2]^2) - 0.8 }
    printf "\nEnd\n"
}' "$OUT/box.mesh" >"$OUT/box.sol"
CLAMP='"clamp": {"kind": "ball", "center": [0, 0], "radius": 0.1}'
QUICK="{$CLAMP, \"max_iter\": 20}"
ENDLESS="{$CLAMP, \"max_iter\": 100000000, \"tol_step\": 1e-15, \"tol_stall\": 0}"

"$BIN/shapematchd" --listen 127.0.0.1:0 --spool "$OUT/spool" --workers 2 --worker-threads 1 \
    --retention 30s --log-level warn 2>"$OUT/daemon.log" &
DPID=$!
PIDS=()
stop_all() {
    local p
    for p in "${PIDS[@]}"; do kill "$p" 2>/dev/null || true; done
    for p in "${PIDS[@]}"; do wait "$p" 2>/dev/null || true; done
    kill -TERM "$DPID" 2>/dev/null || true
    wait "$DPID" 2>/dev/null || true
}
trap stop_all EXIT
PORT=
for _ in $(seq 1 200); do
    PORT=$(ss -ltnpH 2>/dev/null | awk -v p="pid=$DPID," 'index($0, p) { n = split($4, a, ":"); print a[n]; exit }')
    [ -n "$PORT" ] && break
    sleep 0.05
done
[ -n "$PORT" ] || { echo "soak: the daemon did not start" >&2; cat "$OUT/daemon.log" >&2; exit 1; }
BASE=http://127.0.0.1:$PORT
submit() { # PARAMS [MESH]: the job id
    curl -sS --max-time 30 -F "template=@${2:-$OUT/disk.mesh}" -F "target_mesh=@$OUT/box.mesh" \
        -F "target_sol=@$OUT/box.sol" -F "params=$1" "$BASE/v1/jobs" | jq -r '.jobID // empty'
}
sample() { # "rss_kib fds threads"
    local rss thr
    rss=$(awk '/^VmRSS:/ { print $2 }' "/proc/$DPID/status")
    thr=$(awk '/^Threads:/ { print $2 }' "/proc/$DPID/status")
    echo "$rss $(ls "/proc/$DPID/fd" | wc -l) $thr"
}

LONG=$(submit "$ENDLESS" "$OUT/fine.mesh")
[ -n "$LONG" ] || { echo "soak: cannot submit" >&2; exit 1; }
T_END=$(($(date +%s) + SECONDS_TOTAL))
echo "soak: $SECONDS_TOTAL s against $BASE (daemon pid $DPID), sampling every $EVERY s"

wrk -t1 -c8 -d"${SECONDS_TOTAL}s" "$BASE/v1/jobs/$LONG" >"$OUT/wrk.txt" 2>&1 &
PIDS+=($!)
for i in $(seq 1 8); do
    (while [ "$(date +%s)" -lt "$T_END" ]; do
        curl -sS -N --max-time 10 "$BASE/v1/jobs/$LONG/events" >/dev/null 2>&1 || true
    done) &
    PIDS+=($!)
done
(n=0
while [ "$(date +%s)" -lt "$T_END" ]; do
    id=$(submit "$QUICK") || id=
    n=$((n + 1))
    if [ -n "$id" ]; then
        echo "$id" >>"$OUT/submitted"
        if [ $((n % 3)) = 0 ]; then
            curl -sS --max-time 10 -X DELETE -o /dev/null "$BASE/v1/jobs/$id" && echo "$id" >>"$OUT/cancelled"
        else
            curl -sS -N --max-time 20 "$BASE/v1/jobs/$id/events" >/dev/null 2>&1 &
        fi
    fi
    sleep 1
done
wait) &
PIDS+=($!)

echo "   t_s   rss_kib  fds threads" | tee "$OUT/series.txt"
t0=$(date +%s)
while [ "$(date +%s)" -lt "$T_END" ]; do
    printf '%6d %9s %4s %7s\n' $(($(date +%s) - t0)) $(sample) | tee -a "$OUT/series.txt"
    sleep "$EVERY"
done
for p in "${PIDS[@]}"; do wait "$p" 2>/dev/null || true; done
PIDS=()
sleep 2
printf '%6d %9s %4s %7s\n' $(($(date +%s) - t0)) $(sample) | tee -a "$OUT/series.txt"
curl -sS --max-time 10 -X DELETE -o /dev/null "$BASE/v1/jobs/$LONG" || true

echo
grep -E 'Requests/sec|Latency|requests in' "$OUT/wrk.txt" | sed 's/^/wrk: /'
echo "submissions: $(wc -l <"$OUT/submitted" 2>/dev/null || echo 0), cancelled: $(wc -l <"$OUT/cancelled" 2>/dev/null || echo 0)"
awk -v warm_frac=0.2 'NR > 1 { t[++n] = $1; r[n] = $2; f[n] = $3; h[n] = $4 }
END {
    if (n < 3) { print "soak: too few samples"; exit 1 }
    w = 1; while (w < n && t[w] < t[n] * warm_frac) w++
    split("rss_kib fds threads", name, " ")
    for (k = 1; k <= 3; k++) {
        first = k == 1 ? r[1] : k == 2 ? f[1] : h[1]
        warm = k == 1 ? r[w] : k == 2 ? f[w] : h[w]
        last = k == 1 ? r[n] : k == 2 ? f[n] : h[n]
        max = 0
        for (i = 1; i <= n; i++) { v = k == 1 ? r[i] : k == 2 ? f[i] : h[i]; if (v > max) max = v }
        bound = k == 1 ? 1.5 * warm + 16384 : k == 2 ? warm + 64 : warm + 8
        printf "%-8s first %8d  after warm-up (t=%ds) %8d  last %8d  max %8d  bound %8d  %s\n",
               name[k], first, t[w], warm, last, max, bound, last <= bound ? "ok" : "GREW"
        if (last > bound) bad = 1
    }
    exit bad
}' "$OUT/series.txt"
