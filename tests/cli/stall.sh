#!/usr/bin/env bash
# The default stop rules end a converged run by themselves: on the 2D
# example, a default `shapematch run` stops with reason "stalled" no
# earlier than the first iteration within 10% of the best boundary error
# that 500 iterations reach (stall rule off), and within twice that.  The
# summary reports the scale-free errors and the stall parameters, and the
# default run's boundary_rms is within issue 33's 1e-4.
source "$(dirname "$0")/../lib/cli.sh"
EX=$ROOT/examples/2d
IN=(--template "$EX/template.mesh" --target-mesh "$EX/background.mesh.gz"
    --target-sol "$EX/background.sol.gz" --clamp-ball "$(tr -d ' \n' <"$EX/clamp")")
if ! "$BIN" run "${IN[@]}" --tol-stall 0 --max-iter 500 --quiet -o "$WORK/ref" >"$WORK/ref.err" 2>&1 ||
    ! "$BIN" run "${IN[@]}" --quiet -o "$WORK/def" >"$WORK/def.err" 2>&1; then
    echo "not ok - the 2D example runs"
    sed 's/^/# /' "$WORK/ref.err" "$WORK/def.err"
    exit 0
fi
echo "ok - the 2D example runs (reference and default)"
python3 - "$WORK" <<'PY'
import csv, json, sys
w = sys.argv[1]
def check(ok, what, why=""):
    print("%s - %s%s" % ("ok" if ok else "not ok", what, "" if ok or not why else "\n# " + why))
h = [float(r["boundary_l2"]) for r in csv.DictReader(open(w + "/ref/history.csv"))]
ref = json.load(open(w + "/ref/summary.json"))
s = json.load(open(w + "/def/summary.json"))
best = min(h)
needed = next(i for i, v in enumerate(h) if v <= 1.1 * best)
check(ref["stop_reason"] != "stalled" and len(h) == ref["iterations"] + 1,
      "the reference run ignores the stall rule (%s after %d)" % (ref["stop_reason"], ref["iterations"]))
check(s["stop_reason"] == "stalled", "a default run ends by the stall rule (%s)" % s["stop_reason"])
check(needed <= s["iterations"] <= 2 * needed,
      "stops in [needed, 2 needed]: %d in [%d, %d]" % (s["iterations"], needed, 2 * needed))
check(s["warnings"] == [] and ref["warnings"] == [], "no warning on the clean example", json.dumps(s["warnings"]))
# issue 33's accuracy with the defaults, 2D: boundary_rms (J's own figure,
# at the quadrature points) <= 1e-4; the exact figure is the polygon's
# chord error, 1.6e-4 (tests/cli/coverage.sh, chord_check.py)
check(s["boundary_rms"] <= 1e-4 and s["converged"],
      "2D with the defaults: converged, boundary_rms %.3g <= 1e-4 (exact result->target %.3g)" % (
          s["boundary_rms"], s["distance"]["result_to_target"]["rms"]))
p = s["parameters"]
check(p["tol_stall"] == 0.01 and p["stall_window"] == 15 and p["tol_boundary_rel"] == 0,
      "the summary's parameters carry the stall rule", json.dumps(p))
check(abs(s["boundary_relative"] * 2 ** 0.5 / 2 - s["boundary_rms"]) < 0.05 * s["boundary_rms"]
      and 0.5 < (s["boundary_l2"] / s["boundary_rms"]) ** 2 < 2.0,
      "scale-free errors: rms %.3g (boundary length %.3g), relative %.3g" % (
          s["boundary_rms"], (s["boundary_l2"] / s["boundary_rms"]) ** 2, s["boundary_relative"]))
PY

# issue 33: the stall rule waits for a converging run, and the descent
# reaches an inner corner.  A Gmsh ball onto a bent capsule (an L of two
# arms) with --align affine: the template swings into place while the
# boundary error first rises (the stall rule ended it after 15
# iterations, exit 10, although J was still falling); since the
# two-sided alignment stretches the ball over the whole L, the elements
# behind the L's inner corner degenerate, and the run ended
# quality_blocked after 143 iterations with the corner missed (target
# side p99 0.178 > twice the resolution 0.143).  With the interior
# relaxation (core/sm_relax.h) it converges with the defaults: exit 0,
# covered, no inverted element; --align similarity likewise (it ended
# quality_blocked after 127).
if [ "${SM_VARIANT:-release}" = asan ]; then
    echo "ok - # SKIP ball onto a bent capsule with --align affine and similarity (release build only: 500 iterations)"
elif ! command -v gmsh >/dev/null; then
    echo "not ok - gmsh is installed"
else
    cat >"$WORK/bent.geo" <<'GEO'
SetFactory("OpenCASCADE");
Mesh.MeshSizeFromPoints = 0;
Cylinder(1) = {0, 0, 0, 1.5, 0, 0, 0.4};
Cylinder(2) = {0, 0, 0, 0, 1.5, 0, 0.4};
Sphere(3) = {0, 0, 0, 0.4};
Sphere(4) = {1.5, 0, 0, 0.4};
Sphere(5) = {0, 1.5, 0, 0.4};
BooleanUnion{ Volume{1}; Delete; }{ Volume{2:5}; Delete; }
GEO
    printf 'SetFactory("OpenCASCADE");\nMesh.MeshSizeFromPoints = 0;\nSphere(1) = {0, 0, 0, 1};\n' >"$WORK/ball.geo"
    gmsh "$WORK/bent.geo" -2 -format stl -bin -clmax 0.1 -o "$WORK/bent.stl" -nt 1 >/dev/null 2>&1
    gmsh "$WORK/ball.geo" -3 -format mesh -clmax 0.15 -o "$WORK/ball.mesh" -nt 1 >/dev/null 2>&1
    for align in affine similarity; do
        "$BIN" run --template "$WORK/ball.mesh" --target-surface "$WORK/bent.stl" --clamp-ball 0,0,0,0.2 \
            --align $align --quiet -o "$WORK/bent-$align" >"$WORK/bent-$align.err" 2>&1
        rc=$?
        facts=$(jq -r '"\(.stop_reason) \(.iterations) \(.converged) \(.inverted_elements) \(.distance.target_to_result.p99) \(.resolution)"' \
            "$WORK/bent-$align/summary.json" 2>/dev/null)
        read -r stop its conv inv p99 res <<<"$facts"
        if [ $rc = 0 ] && [ "$conv" = true ] && [ "$inv" = 0 ] && [ "$stop" != quality_blocked ] &&
            awk -v p="$p99" -v r="$res" 'BEGIN { exit !(p <= 2 * r) }'; then
            echo "ok - ball onto a bent capsule, --align $align, defaults: converged ($stop after $its, target side p99 $p99 within twice the resolution $res, 0 inverted)"
        else
            echo "not ok - ball onto a bent capsule, --align $align, defaults: converged (exit $rc: $facts)"
            sed 's/^/# /' "$WORK/bent-$align.err"
        fi
    done
fi
