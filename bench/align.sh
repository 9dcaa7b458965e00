#!/usr/bin/env bash
# `make bench`, the alignment: examples/3d's template moved by a known
# rigid motion (40 degrees about (1, 2, 3), then a translation of about 10
# diameters), matched with --align rigid and --align similarity, against
# the example's own (hand-aligned) run: the alignment's time against the
# match it precedes (goal: <= 10%), where it puts the template's centre
# (the ball's rotation is free: only the centre is determined), and the
# final boundary RMS of both; then mixed units (below).  Figures, not
# verdicts.
set -euo pipefail
cd "$(dirname "$0")/.."
BIN=build/release/shapematch
W=build/bench-align
rm -rf "$W" && mkdir -p "$W"
python3 - "$W" <<'PY'
import math, sys
w = sys.argv[1]
ax = [1 / math.sqrt(14), 2 / math.sqrt(14), 3 / math.sqrt(14)]
a = math.radians(40)
c, s, t = math.cos(a), math.sin(a), 1 - math.cos(a)
x, y, z = ax
R = [[t*x*x + c, t*x*y - s*z, t*x*z + s*y], [t*x*y + s*z, t*y*y + c, t*y*z - s*x],
     [t*x*z - s*y, t*y*z + s*x, t*z*z + c]]
B = [3.0, -2.0, 5.0]
move = lambda p: [sum(R[i][j] * p[j] for j in range(3)) + B[i] for i in range(3)]
lines = open("examples/3d/template.mesh").readlines()
out, i = [], 0
while i < len(lines):
    out.append(lines[i])
    if lines[i].strip() == "Vertices":
        n = int(lines[i + 1]); out.append(lines[i + 1])
        for k in range(n):
            f = lines[i + 2 + k].split()
            q = move([float(v) for v in f[:3]])
            out.append(" %.17g %.17g %.17g %s\n" % (q[0], q[1], q[2], f[3]))
        i += 2 + n; continue
    i += 1
open(w + "/moved.mesh", "w").writelines(out)
print("%.17g,%.17g,%.17g" % tuple(move([0.5, 0.5, 0.5])), file=open(w + "/centre", "w"))
PY
MC=$(cat "$W/centre")
TARGET=(--target-mesh examples/3d/background.mesh.gz --target-sol examples/3d/background.sol.gz)
$BIN run --template examples/3d/template.mesh "${TARGET[@]}" --clamp-ball "$(cat examples/3d/clamp)" \
    --quiet -o "$W/hand" 2>/dev/null || true
for mode in rigid similarity; do
    /usr/bin/time -f "%e" -o "$W/$mode.wall" $BIN run --template "$W/moved.mesh" "${TARGET[@]}" \
        --clamp-ball "$MC,0.05" --align $mode --quiet -o "$W/$mode" 2>/dev/null || true
    jq -r --arg mode "$mode" --argjson hand "$(jq .boundary_rms "$W/hand/summary.json")" \
        --argjson wall "$(cat "$W/$mode.wall")" --arg c "$MC" '
        ($c | split(",") | map(tonumber)) as $x | .alignment.matrix as $m |
        ([range(3)] | map(($m[4*.+0]*$x[0] + $m[4*.+1]*$x[1] + $m[4*.+2]*$x[2] + $m[4*.+3] - 0.5) | fabs) | max) as $e |
        "align \($mode): \(.alignment.seconds * 1000 | floor) ms, the match \(.timings.total * 1000 | floor) ms " +
        "(\(.alignment.seconds / .timings.total * 100 | floor)% of it, goal <= 10%; whole command \($wall) s), " +
        "\(.alignment.iterations) iterations, centre within \($e), scale \(.alignment.scale), " +
        "RMS \(.alignment.rms_before) -> \(.alignment.rms_after), final \(.boundary_rms) " +
        "(hand-aligned \($hand): \(.boundary_rms / $hand * 100 | floor / 100)x)"' "$W/$mode/summary.json"
done

# Units: the 3D template (metres) onto an ellipsoid STL in metres and the
# same STL in millimetres, --align similarity, no --background-size: the
# alignment runs on the exact surface before any background is built (the
# background then goes around the moved template), so mixed units cost
# what one unit costs.  Figures: the whole command's wall time of each,
# their ratio, and the alignment's share of the whole command.
cat >"$W/ell.geo" <<'GEO'
SetFactory("OpenCASCADE");
Sphere(1) = {0.5, 0.5, 0.5, 0.3};
Dilate {{0.5, 0.5, 0.5}, {1.15, 0.9, 0.8}} { Volume{1}; }
Mesh.MeshSizeFromPoints = 0;
GEO
gmsh "$W/ell.geo" -2 -format stl -clmax 0.015 -nt 1 -v 1 -o "$W/ell_m.stl" >/dev/null 2>&1
awk '$1 == "vertex" { printf "vertex %.17g %.17g %.17g\n", $2 * 1000, $3 * 1000, $4 * 1000; next } { print }' \
    "$W/ell_m.stl" >"$W/ell_mm.stl"
for unit in m mm; do
    /usr/bin/time -f "%e" -o "$W/units_$unit.wall" $BIN run --template examples/3d/template.mesh \
        --target-surface "$W/ell_$unit.stl" --clamp-ball "$(cat examples/3d/clamp)" \
        --align similarity --quiet -o "$W/units_$unit" 2>/dev/null || true
done
jq -rn --slurpfile m "$W/units_m/summary.json" --slurpfile mm "$W/units_mm/summary.json" \
    --argjson wm "$(cat "$W/units_m.wall")" --argjson wmm "$(cat "$W/units_mm.wall")" '
    ($m[0].alignment.seconds) as $am | ($mm[0].alignment.seconds) as $amm |
    "align units (template in m, target STL in m / in mm, --align similarity): whole command " +
    "\($wm) s / \($wmm) s, mixed / same = \($wmm / $wm * 100 | floor / 100) (goal ~1); " +
    "alignment \($am * 1000 | floor) / \($amm * 1000 | floor) ms = " +
    "\($am / $wm * 100 | floor)% / \($amm / $wmm * 100 | floor)% of the command (goal <= 10%); " +
    "scale \($m[0].alignment.scale) / \($mm[0].alignment.scale), final boundary RMS " +
    "\($m[0].boundary_rms) m / \($mm[0].boundary_rms) mm"'
