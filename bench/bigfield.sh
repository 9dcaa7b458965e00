#!/usr/bin/env bash
# The target field on a large background (issue 13: a 5M-tetrahedron
# background builds its field in bounded time and memory).  A box
# [-1,1]^3 is meshed by Gmsh (HXT, uniform size) at about BIGFIELD_TETS
# tetrahedra (default 5M; cached under build/bigfield/), the exact signed
# distance to a sphere of radius 0.6 is computed at its vertices
# (`shapematch sdf`), then field_bench builds the field (best of 3) and
# evaluates it; /usr/bin/time gives the benchmark's peak RSS, which
# includes the background mesh and its distance (the inputs) besides the
# field.  Figures only, no pass/fail.
#
#   bench/bigfield.sh
#   BIGFIELD_TETS=1000000 bench/bigfield.sh
set -euo pipefail
cd "$(dirname "$0")/.."
BIN=build/release
TETS=${BIGFIELD_TETS:-5000000}
DIR=build/bigfield/t$TETS
[ -x $BIN/field_bench ] || { echo "bigfield: build first (make release)" >&2; exit 1; }
mkdir -p "$DIR"
if [ ! -s "$DIR/box.mesh" ]; then
    # Gmsh's uniform tetrahedra: about 3.94 per h^3 of volume (measured)
    h=$(awk -v n="$TETS" 'BEGIN { printf "%.6f", exp(log(3.94 * 8 / n) / 3) }')
    printf 'SetFactory("OpenCASCADE");\nBox(1) = {-1, -1, -1, 2, 2, 2};\nMesh.MeshSizeMin = %s;\nMesh.MeshSizeMax = %s;\nMesh.Algorithm3D = 10;\n' \
        "$h" "$h" >"$DIR/box.geo"
    printf 'SetFactory("OpenCASCADE");\nSphere(1) = {0, 0, 0, 0.6};\nMesh.MeshSizeFromPoints = 0;\n' >"$DIR/sphere.geo"
    echo "bigfield: meshing ~$TETS tetrahedra (h = $h) with Gmsh ..." >&2
    gmsh "$DIR/sphere.geo" -2 -format stl -clmax 0.01 -nt 1 -v 1 -o "$DIR/sphere.stl" >/dev/null
    gmsh "$DIR/box.geo" -3 -format mesh -nt 2 -v 1 -o "$DIR/box.mesh.tmp" >/dev/null
    mv "$DIR/box.mesh.tmp" "$DIR/box.mesh"
fi
if [ ! -s "$DIR/box.sol" ]; then
    start=$(date +%s.%N)
    $BIN/shapematch sdf --surface "$DIR/sphere.stl" --background "$DIR/box.mesh" -o "$DIR/box.sol" 2>/dev/null
    echo "signed distance at the background's vertices: $(echo "$(date +%s.%N) - $start" | bc) s wall"
fi
/usr/bin/time -v $BIN/field_bench "$DIR/box.mesh" "$DIR/box.sol" 200000 >"$DIR/field.txt" 2>"$DIR/time.txt"
cat "$DIR/field.txt"
awk '/Maximum resident set size/ { printf "peak RSS of field_bench (inputs + field): %.0f MiB\n", $NF / 1024 }
     /Elapsed \(wall clock\)/ { print "field_bench wall clock: " $NF }' "$DIR/time.txt"
