#!/usr/bin/env bash
# `shapematch warp --points` from the command line against the Python
# package's shapematch.warp on the same points, in the same run (issue 35
# item 6: the CLI >= 1.5M points/s inside the mesh), and the cost of
# points outside the template (--outside, the nearest boundary facet).
#
#   bench/warp_cli.sh [RESULT_DIR] [NPOINTS]
#
# RESULT_DIR: a result folder (default build/bench-run, what bench/run.sh
# leaves: the 3D example's).  NPOINTS random points inside the template's
# ball (radius 0.28 about (0.5, 0.5, 0.5), the template's radius being 0.3),
# written as CSV (%.17g) and as .npy.  Each figure is the whole command
# (process start, reading the map, the points in and out), best of 3, in
# points per second of wall clock; the machine's load is printed with it.
set -euo pipefail
cd "$(dirname "$0")/.."
BIN=${SM_BIN:-build/release}
RES=${1:-build/bench-run}
N=${2:-1000000}
PY=/usr/bin/python3 # Debian's, with python3-numpy
[ -s "$RES/result.mesh" ] || { echo "warp_cli: no result in $RES (run bench/run.sh first)" >&2; exit 1; }
"$PY" -c 'import numpy' 2>/dev/null || { echo "warp_cli: python3-numpy is needed" >&2; exit 1; }
W=$(mktemp -d "${TMPDIR:-/tmp}/sm-warp-bench.XXXXXX")
trap 'rm -rf "$W"' EXIT
"$PY" - "$W" "$N" <<'PY'
import sys
import numpy as np
w, n = sys.argv[1], int(sys.argv[2])
rng = np.random.default_rng(1)
p = rng.normal(size=(n, 3))
p *= (0.28 * rng.random(n) ** (1 / 3) / np.linalg.norm(p, axis=1))[:, None]
p += 0.5
np.save(w + "/in.npy", p)
np.savetxt(w + "/in.csv", p, delimiter=",", fmt="%.17g", header="x,y,z", comments="")
# 7,279 points (a mesh's vertices, as in issue 35) all well outside
np.save(w + "/far.npy", p[:7279] + 5.0)
PY
best() { # CMD...: the best wall seconds of 3 runs
    local b=""
    for _ in 1 2 3; do
        local t0 t1
        t0=$(date +%s.%N)
        "$@" >/dev/null 2>&1
        t1=$(date +%s.%N)
        b=$(awk -v a="$t0" -v z="$t1" -v b="$b" 'BEGIN { t = z - a; print (b == "" || t < b) ? t : b }')
    done
    echo "$b"
}
csv=$(best "$BIN/shapematch" warp -q --result "$RES" --points "$W/in.csv" -o "$W/out.csv")
npy=$(best "$BIN/shapematch" warp -q --result "$RES" --points "$W/in.npy" -o "$W/out.npy")
far=$(best "$BIN/shapematch" warp -q --result "$RES" --points "$W/far.npy" -o "$W/far-out.npy")
py=$("$PY" - "$RES" "$W/in.npy" <<PY
import os, sys, time
sys.path.insert(0, "python")
os.environ.setdefault("SHAPEMATCH_LIBDIR", "$BIN")
import numpy as np
import shapematch
p = np.load(sys.argv[2])
best = None
for _ in range(3):
    t = time.perf_counter()
    shapematch.warp(sys.argv[1], points=p)   # the map read too, as the CLI does
    t = time.perf_counter() - t
    best = t if best is None or t < best else best
print(best)
PY
)
awk -v n="$N" -v csv="$csv" -v npy="$npy" -v py="$py" -v far="$far" -v load="$(cut -d' ' -f1-3 /proc/loadavg)" 'BEGIN {
  printf("%d points inside the template, whole command, best of 3 (load %s):\n", n, load)
  printf("  shapematch warp, CSV in and out:   %.2f s, %.2fM points/s (goal >= 1.5M/s)\n", csv, n / csv / 1e6)
  printf("  shapematch warp, .npy in and out:  %.2f s, %.2fM points/s\n", npy, n / npy / 1e6)
  printf("  Python shapematch.warp (arrays):   %.2f s, %.2fM points/s\n", py, n / py / 1e6)
  printf("  ratio CLI/Python: CSV %.2f, .npy %.2f\n", (n / csv) / (n / py), (n / npy) / (n / py))
  printf("  7,279 points all outside (the nearest boundary facet each): %.2f s whole command\n", far)
}'
