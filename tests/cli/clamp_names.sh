#!/usr/bin/env bash
# Clamp and free-boundary references by Gmsh physical name: a ball in a
# shell made by the real gmsh, physical volumes "core" (1) and "shell" (2)
# and surface "skin" (3, the whole boundary).  --clamp-elements core runs
# with references [1] in summary.json; an unknown name is refused with the
# names there are; names and numbers mix; --free-boundary skin frees the
# whole boundary (the run says no facet carries the load); an empty clamp
# lists the references that exist and the template's bounding box.
source "$(dirname "$0")/../lib/cli.sh"
B=${SM_BIN:-$ROOT/build/release}/shapematch
cd "$WORK" || exit 1
cp "$ROOT/tests/lib/case/ball_shell.geo" t.geo
cat >s.geo <<'GEO'
SetFactory("OpenCASCADE");
Sphere(1) = {0, 0, 0, 0.9};
Mesh.MeshSizeMax = 0.3;
GEO
if ! gmsh -3 t.geo -format msh41 -o t.msh >gmsh.log 2>&1 ||
    ! gmsh -2 s.geo -format ply2 -o s.ply2 >>gmsh.log 2>&1; then
    not_ok "gmsh makes the meshes" "$(tail -5 gmsh.log)"
    exit 0
fi
"$B" run --template t.msh --target-surface s.ply2 --clamp-elements core --max-iter 2 -q \
    -o o1 >o1.err 2>&1
rc=$?
refs=$(python3 -c "import json; print(json.load(open('o1/summary.json'))['parameters']['clamp']['refs'])" 2>&1)
check "--clamp-elements core runs (exit $rc) with refs [1]: $refs" \
    test \( $rc = 0 -o $rc = 10 \) -a "$refs" = "[1]"
"$B" run --template t.msh --target-surface s.ply2 --clamp-elements core,2 --max-iter 2 -q \
    -o o5 >o5.err 2>&1
check "names and numbers mix: core,2 clamps every vertex" grep -q "nothing could move" o5.err
"$B" run --template t.msh --target-surface s.ply2 --clamp-elements kore --max-iter 2 -q \
    -o o2 >o2.err 2>&1
rc=$?
check "an unknown name is refused (usage, exit 1)" test $rc = 1 -a ! -e o2/summary.json
check "... naming the element names there are" grep -q '"core" (1), "shell" (2)' o2.err
"$B" run --template t.msh --target-surface s.ply2 --clamp-elements 77 --max-iter 2 -q \
    -o o3 >o3.err 2>&1
rc=$?
check "an empty clamp is refused (exit $rc)" test $rc != 0 -a $rc != 10
check "... listing the references that exist and the bounding box" \
    grep -q 'the element references are 1 ("core"), 2 ("shell"); the template spans \[-0.7' o3.err
"$B" run --template t.msh --target-surface s.ply2 --clamp-elements 1 --free-boundary skin \
    --max-iter 2 -q -o o4 >o4.err 2>&1
check "--free-boundary skin frees the whole boundary" grep -q "all are in the free boundary" o4.err
"$B" run --template t.msh --target-surface s.ply2 --clamp-elements 1 --free-boundary skim \
    --max-iter 2 -q -o o6 >o6.err 2>&1
check "--free-boundary skim: refused, naming the facets' names" grep -q '"skin" (3)' o6.err
