#!/usr/bin/env bash
# Robustness table (part of `make bench`, or alone: bench/robust.sh): a
# Gmsh unit ball (mesh size 0.15, and 0.08: 38k tetrahedra, the AMG
# solver by default) clamped at its centre (radius 0.2) onto Gmsh-made
# target surfaces, with the defaults and with the best other setting
# (--no-clamp --solver cholmod).  Per run: boundary RMS measured against
# the analytic surface (tests/cli/robust_cases.py, not shapematch's own
# figure), iterations, stop reason, converged, min quality, wall time.
# ROBUST_FINE=0 skips the finer ball (its runs take minutes).
# ROBUST_FINEST=1 adds issue 20's fine ball (mesh size 0.045: 210k
# tetrahedra) onto the ellipsoid, defaults against the best setting
# (measured 2026-12-03 on 2 shared cores, STL of size 0.05: RMS 3.63e-4
# both, converged, stalled after 112 and 169 iterations, 152 s and 220 s;
# the issue had 1.3e-2 with the defaults before the adaptive re-assembly).
set -u
cd "$(dirname "$0")/.."
BIN=${BIN:-build/release}/shapematch
CASES=tests/cli/robust_cases.py
W=build/bench-robust
mkdir -p "$W"
for c in ball ellipsoid grown shrunk peanut torus; do python3 "$CASES" geo "$c" "$W/$c.geo"; done
gmsh "$W/ball.geo" -3 -format mesh -clmax 0.15 -nt 1 -v 1 -o "$W/ball15.mesh" >/dev/null
[ "${ROBUST_FINE:-1}" = 0 ] ||
    gmsh "$W/ball.geo" -3 -format mesh -clmax 0.08 -nt 1 -v 1 -o "$W/ball08.mesh" >/dev/null
[ "${ROBUST_FINEST:-0}" = 0 ] ||
    gmsh "$W/ball.geo" -3 -format mesh -clmax 0.045 -nt 1 -v 1 -o "$W/ball045.mesh" >/dev/null
for c in ellipsoid grown shrunk peanut torus; do
    gmsh "$W/$c.geo" -2 -format stl -bin -clmax 0.05 -nt 1 -v 1 -o "$W/$c.stl" >/dev/null
done

row() { # row TEMPLATE CASE LABEL ARGS...
    local t=$1 c=$2 label=$3 out=$W/out rms start end rc
    shift 3
    start=$(date +%s.%N)
    "$BIN" run --template "$W/$t.mesh" --target-surface "$W/$c.stl" --quiet -o "$out" "$@" \
        >/dev/null 2>&1
    rc=$?
    end=$(date +%s.%N)
    rms=$(python3 "$CASES" rms "$c" "$out/result.mesh" | cut -d' ' -f1)
    python3 -c '
import json, sys
s = json.load(open(sys.argv[1] + "/summary.json"))
print("| %s | %s | %s | %.3g | %d | %s | %s | %d | %.3f | %.1f |" % (sys.argv[2], sys.argv[3], sys.argv[4],
      float(sys.argv[5]), s["iterations"], s["stop_reason"], str(s.get("converged")).lower(),
      int(sys.argv[7]), s["min_quality"], float(sys.argv[6])))' \
        "$out" "$t" "$c" "$label" "$rms" "$(awk -v a="$start" -v b="$end" 'BEGIN { print b - a }')" "$rc"
}

echo "== robustness: Gmsh unit ball onto Gmsh target surfaces (RMS against the analytic surface) =="
echo "| template | target | setting | RMS | iterations | stop | converged | exit | min quality | wall s |"
echo "|---|---|---|---|---|---|---|---|---|---|"
templates=ball15
[ "${ROBUST_FINE:-1}" = 0 ] || templates="ball15 ball08"
for t in $templates; do
    for c in ellipsoid grown shrunk peanut torus; do
        row "$t" "$c" defaults --clamp-ball 0,0,0,0.2
        row "$t" "$c" "--no-clamp --solver cholmod" --no-clamp --solver cholmod
    done
done
if [ "${ROBUST_FINEST:-0}" != 0 ]; then
    row ball045 ellipsoid defaults --clamp-ball 0,0,0,0.2
    row ball045 ellipsoid "--no-clamp --solver cholmod" --no-clamp --solver cholmod
fi
