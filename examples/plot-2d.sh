#!/usr/bin/env bash
# Draws examples/2d/matching.png (used by the README): the template's
# boundary, the target contour and the matched boundary, plus the matched
# mesh.  Needs gnuplot (Debian: apt-get install gnuplot-nox) and a built
# client (make release).
#   examples/plot-2d.sh [OUT.png]
set -euo pipefail
cd "$(dirname "$0")/.."
OUT=${1:-examples/2d/matching.png}
BIN=${SM_BIN:-build/release}
command -v gnuplot >/dev/null || { echo "plot-2d.sh: needs gnuplot (apt-get install gnuplot-nox)" >&2; exit 1; }
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
"$BIN/shapematch" run --template examples/2d/template.mesh \
    --target-mesh examples/2d/background.mesh.gz --target-sol examples/2d/background.sol.gz \
    --clamp-ball "$(cat examples/2d/clamp)" --tol-boundary 1e-4 --quiet -o "$work/out"

# segments "x1 y1\nx2 y2\n\n" of the Edges with reference 1 (the boundary),
# or of every triangle edge with "all"
segments() { # MESH all|boundary
    awk -v what="$2" '
      /^ *[A-Za-z]/ { kw = tolower($1); if (kw == "vertices" || kw == "edges" || kw == "triangles") { getline; n = $1; k = 0; sect = kw }; next }
      sect == "vertices" && k < n { k++; x[k] = $1; y[k] = $2; next }
      sect == "edges" && k < n { k++; if (what == "boundary" && $3 == 1) printf "%s %s\n%s %s\n\n", x[$1], y[$1], x[$2], y[$2]; next }
      sect == "triangles" && k < n { k++; if (what == "all") printf "%s %s\n%s %s\n%s %s\n%s %s\n\n", x[$1], y[$1], x[$2], y[$2], x[$3], y[$3], x[$1], y[$1]; next }' "$1"
}
segments examples/2d/template.mesh boundary >"$work/template.dat"
segments "$work/out/result.mesh" boundary >"$work/result.dat"
segments "$work/out/result.mesh" all >"$work/mesh.dat"
# the target: R(theta) = 0.25 (1 + 0.2 cos 5 theta) around (0.5, 0.5) (examples/tools/shapes.h)
awk 'BEGIN { for (i = 0; i <= 2000; i++) { t = 2 * 3.14159265358979 * i / 2000; r = 0.25 * (1 + 0.2 * cos(5 * t)); print 0.5 + r * cos(t), 0.5 + r * sin(t) } }' >"$work/target.dat"
summary=$(awk -F'[:,]' '/"iterations"/ { it = $2 } /"boundary_l2"/ { l2 = $2 } END { printf "%d iterations, ||d||_{L2} = %.2g", it, l2 }' "$work/out/summary.json")
gnuplot <<GP
set terminal pngcairo size 1200,600 font "sans,11"
set output "$OUT"
set multiplot layout 1,2
set size ratio -1
set xrange [0.18:0.82]; set yrange [0.18:0.82]
unset xtics; unset ytics
set key bottom center horizontal
set title "template (grey), target contour (red), matched boundary (blue)"
plot "$work/template.dat" w l lc rgb "#999999" lw 2 t "template", \
     "$work/target.dat" w l lc rgb "#d62728" lw 4 t "target d = 0", \
     "$work/result.dat" w l lc rgb "#1f4fb4" lw 1.5 t "matched"
set title "matched mesh (examples/2d: $summary)"
plot "$work/mesh.dat" w l lc rgb "#1f4fb4" lw 0.6 notitle
unset multiplot
GP
echo "wrote $OUT"
