#!/usr/bin/env bash
# Large deformations with the defaults, and honest outcomes: a Gmsh unit
# ball (mesh size 0.15) clamped at its centre (radius 0.2) matched onto
# Gmsh-made target surfaces, everything else default.  The boundary RMS
# error is measured independently of shapematch, against the analytic
# surface (tests/cli/robust_cases.py).
#   - ellipsoid 1.3 x 0.9 x 0.8, the same grown x2 and shrunk x0.5, a
#     peanut (non-convex): converged true, exit 0, no inverted element,
#     within 2x the RMS of the best setting (--no-clamp --solver cholmod)
#     and no warning;
#   - a torus (another topology): converged false, exit 10, every output
#     written, the final line says NOT CONVERGED;
#   - the ellipsoid 1000 times larger (millimetres against metres): no
#     background generated (it would be sized in the wrong unit): exit 2
#     at once, the message names the ratio, the likely units and
#     --background-size; with --background-size given, the run goes on
#     with the units warning and a background of that size;
#   - quality_blocked (a floor that blocks every step) apart from a tiny
#     step (step_tolerance) on the 2D example.
set -u
ROOT=${SM_ROOT:-$(cd "$(dirname "$0")/../.." && pwd)}
BIN=${SM_BIN:-$ROOT/build/release}/shapematch
CASES=$ROOT/tests/cli/robust_cases.py
WORK=$(mktemp -d)
trap 'rm -rf "$WORK"' EXIT
if ! command -v gmsh >/dev/null; then echo "not ok - gmsh is installed"; exit 0; fi
cd "$WORK" || exit 0

gmsh_run() { gmsh "$@" -nt 1 >/dev/null 2>&1; }
ok=1
for c in ball ellipsoid grown shrunk peanut torus; do python3 "$CASES" geo "$c" "$c.geo" || ok=0; done
gmsh_run ball.geo -3 -format mesh -clmax 0.15 -o ball.mesh || ok=0
# facets of ~0.1 (0.04 on the shrunk ellipsoid, whose faceting would
# otherwise be the error of both settings)
for c in ellipsoid grown shrunk peanut torus; do
    h=0.1
    [ "$c" = shrunk ] && h=0.04
    gmsh_run "$c.geo" -2 -format stl -bin -clmax $h -o "$c.stl" || ok=0
done
printf 'SetFactory("OpenCASCADE");\nMesh.MeshSizeFromPoints = 0;\nSphere(1) = {0, 0, 0, 1};\nDilate {{0, 0, 0}, {1300, 900, 800}} { Volume{1}; }\n' >mm.geo
gmsh_run mm.geo -2 -format stl -bin -clmax 100 -o mm.stl || ok=0
if [ $ok = 1 ]; then
    echo "ok - Gmsh made the template and the target surfaces"
else
    echo "not ok - Gmsh made the template and the target surfaces"; exit 0
fi

# match NAME CASE ARGS...: runs, records the exit code and the measured RMS
match() {
    local name=$1 c=$2; shift 2
    "$BIN" run --template ball.mesh --target-surface "$c.stl" --quiet -o "$name" "$@" \
        >"$name.out" 2>"$name.err"
    echo $? >"$name.rc"
    python3 "$CASES" rms "$c" "$name/result.mesh" 2>/dev/null | cut -d' ' -f1 >"$name.rms"
}
# The sanitizer build checks the same code paths for memory errors on one
# case (the shrunk ellipsoid, which re-assembles the most); the accuracy
# of every case is the release build's to check (a quarter of the time).
cases="ellipsoid grown shrunk peanut"
[ "${SM_VARIANT:-release}" = asan ] && cases=shrunk
for c in $cases; do
    match "def-$c" "$c" --clamp-ball 0,0,0,0.2 --max-iter 150
    match "best-$c" "$c" --no-clamp --solver cholmod --max-iter 150
    read -r rc <"def-$c.rc"
    rms=$(cat "def-$c.rms")
    best=$(cat "best-$c.rms")
    facts=$(jq -r '"\(.converged) \(.inverted_elements) \(.warnings | length) \(.stop_reason) \(.iterations)"' \
        "def-$c/summary.json" 2>/dev/null)
    read -r conv inv nwarn stop its <<<"$facts"
    if [ "$rc" = 0 ] && [ "$conv" = true ] && [ "$inv" = 0 ] && [ "$nwarn" = 0 ] && [ -n "$rms" ] &&
        [ -n "$best" ] && awk -v r="$rms" -v b="$best" 'BEGIN { exit !(r <= 2 * b) }'; then
        echo "ok - ball onto $c with the defaults: RMS $rms (best setting $best), $stop after $its, converged"
    else
        echo "not ok - ball onto $c with the defaults: exit $rc, RMS $rms against $best, $facts"
        sed 's/^/# /' "def-$c.err"
    fi
done

match def-torus torus --clamp-ball 0,0,0,0.2 --max-iter 150
read -r rc <def-torus.rc
conv=$(jq -r .converged def-torus/summary.json 2>/dev/null)
if [ "$rc" = 10 ] && [ "$conv" = false ] && [ -s def-torus/result.mesh ] && [ -s def-torus/result.vtu ] &&
    [ -s def-torus/displacement.sol ] && grep -q "NOT CONVERGED" def-torus.err &&
    [ "$(jq -r .exit_code def-torus/summary.json)" = 10 ]; then
    echo "ok - ball onto a torus: converged false, exit 10, outputs written (RMS $(cat def-torus.rms), $(jq -r .stop_reason def-torus/summary.json))"
else
    echo "not ok - ball onto a torus: exit $rc, converged $conv"; sed 's/^/# /' def-torus.err
fi

t0=$EPOCHREALTIME
"$BIN" run --template ball.mesh --target-surface mm.stl --clamp-ball 0,0,0,0.2 --max-iter 1 --quiet \
    -o mm >mm.out 2>mm.err
rc=$?
secs=$(awk -v a="${t0/,/.}" -v b="${EPOCHREALTIME/,/.}" 'BEGIN { printf "%.1f", b - a }')
if [ $rc = 2 ] && [ ! -e mm/summary.json ] &&
    grep -q "error: target_surface 'mm.stl': the target is 10[0-9][0-9] times larger than the template .*about 1000 times: are they in different units .*give --background-size" mm.err; then
    echo "ok - a target in millimetres, template in metres: no background generated, exit 2 in $secs s, the ratio and --background-size named"
else
    echo "not ok - units mismatch refused before a background is generated (exit $rc)"; sed 's/^/# /' mm.err
fi
"$BIN" run --template ball.mesh --target-surface mm.stl --clamp-ball 0,0,0,0.2 --max-iter 1 --quiet \
    --background-size 100 -o mm >mm.out 2>mm.err
f=$(jq -r '[.warnings[] | select(.code == "units") | .figure] | first // empty' mm/summary.json 2>/dev/null)
nbg=$(jq -r .target_surface.background_vertices mm/summary.json 2>/dev/null)
if [ -n "$f" ] && awk -v f="$f" 'BEGIN { exit !(f > 900 && f < 1500) }' && [ "${nbg:-0}" -gt 0 ] &&
    [ "$nbg" -lt 300000 ] && grep -q "warning: units: .*about 1000 times" mm.err; then
    echo "ok - the same with --background-size 100: it runs, units warning ($f), background of $nbg vertices"
else
    echo "not ok - units warning with an explicit background size ($f, $nbg vertices)"; sed 's/^/# /' mm.err
fi

# quality_blocked is not a tiny step: on the 2D example a quality floor
# at the template's own worst quality (0.806) blocks every step within 3
# iterations (not converged, exit 10), while a large step tolerance ends
# a run whose mesh is far above the floor as step_tolerance (converged:
# 3.4e-4 is a quarter of the background's 1.5e-3)
EX=$ROOT/examples/2d
IN2=(--template "$EX/template.mesh" --target-mesh "$EX/background.mesh.gz"
     --target-sol "$EX/background.sol.gz" --clamp-ball "$(tr -d ' \n' <"$EX/clamp")" --quiet)
"$BIN" run "${IN2[@]}" --min-quality 0.78 -o qb >qb.out 2>qb.err
rc_qb=$?
# (the paper's J alone: with the target-side term the early iterations
# pull toward the star's arms, and a step tolerance this large then ends
# the run before it arrives, 8.8e-4 after 14 iterations, not converged)
"$BIN" run "${IN2[@]}" --tol-step 2e-3 --tol-stall 0 --coverage-weight 0 -o ts >ts.out 2>ts.err
rc_ts=$?
qb=$(jq -r '"\(.stop_reason) \(.converged)"' qb/summary.json 2>/dev/null)
ts=$(jq -r '"\(.stop_reason) \(.converged) \(.min_quality > 0.4)"' ts/summary.json 2>/dev/null)
if [ "$rc_qb" = 10 ] && [ "$qb" = "quality_blocked false" ] && [ "$rc_ts" = 0 ] &&
    [ "$ts" = "step_tolerance true true" ]; then
    echo "ok - a quality floor that blocks every step: quality_blocked, exit 10; a tiny step: step_tolerance, exit 0"
else
    echo "not ok - quality_blocked ($rc_qb: $qb) against step_tolerance ($rc_ts: $ts)"
    sed 's/^/# /' qb.err ts.err
fi
