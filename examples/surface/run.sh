#!/usr/bin/env bash
# examples/surface: match the 3D example's template onto a surface given as
# an STL, made here by Gmsh (an ellipsoid where the 3D example's target
# is), with no background and no distance file: shapematch computes the
# exact signed distance on a background it generates.
#   examples/surface/run.sh [OUTDIR]      (default: build/example-surface)
set -euo pipefail
cd "$(dirname "$0")/../.."
out=${1:-build/example-surface}
mkdir -p "$out"
cat >"$out/target.geo" <<'GEO'
SetFactory("OpenCASCADE");
Sphere(1) = {0.5, 0.5, 0.5, 1};
Dilate {{0.5, 0.5, 0.5}, {0.33, 0.26, 0.22}} { Volume{1}; }
Mesh.MeshSizeFromPoints = 0;
GEO
gmsh "$out/target.geo" -2 -format stl -bin -clmax 0.02 -nt 1 -v 1 -o "$out/target.stl" >/dev/null
# the one-line command:
build/release/shapematch run --template examples/3d/template.mesh --target-surface "$out/target.stl" \
    --clamp-ball "$(cat examples/3d/clamp)" --tol-boundary 1e-3 --max-iter 100 --quiet -o "$out/match"
