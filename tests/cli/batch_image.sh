#!/usr/bin/env bash
# `shapematch batch --target-image` (docs/populations.md): label-map
# images as a batch's targets, given by the option or by the target_image
# column of LIST.csv, with --label / --level / --image-space applying to
# every target as in `run`.  The sphere (radius 10) and the ellipsoid of
# tests/cli/image_shapes.py, rasterised at test time (NIfTI-1), matched
# from a gmsh ball: each target's result is identical, bit for bit, to a
# separate `run --target-image` of it (one thread; the batch's reuse
# claim); an image that is not one fails its target alone; a row naming
# an image and a surface is refused.
source "$(dirname "$0")/../lib/cli.sh"
check_rc() { if [ "$1" = 0 ]; then ok "$2"; else not_ok "$2" "${3:-}"; fi; }
SHAPES="$ROOT/tests/cli/image_shapes.py"
PY=/usr/bin/python3
[ -x "$PY" ] || PY=python3

mkdir -p "$WORK/sph" "$WORK/ell"
"$PY" "$SHAPES" write "$WORK/sph" sphere >/dev/null && "$PY" "$SHAPES" write "$WORK/ell" ellipsoid >/dev/null
check_rc $? "image_shapes.py wrote the sphere and the ellipsoid"
cat >"$WORK/ball.geo" <<'GEO'
SetFactory("OpenCASCADE");
Sphere(1) = {4, 39, 9, 8.5};
Mesh.MeshSizeFromPoints = 0;
GEO
gmsh "$WORK/ball.geo" -3 -format msh41 -clmax 3 -nt 1 -v 1 -o "$WORK/ball.msh" >/dev/null 2>&1
check_rc $? "gmsh meshed the ball"
export OMP_NUM_THREADS=1
RUN=(--template "$WORK/ball.msh" --clamp-ball 4,39,9,4.5 --max-iter 8 --label 1 --quiet)

"$BIN" run "${RUN[@]}" --target-image "$WORK/sph/s1.nii" -o "$WORK/run-sph" 2>/dev/null &&
    "$BIN" run "${RUN[@]}" --target-image "$WORK/ell/s1.nii" -o "$WORK/run-ell" 2>/dev/null
check_rc $? "run --target-image of each image"

"$BIN" batch "${RUN[@]}" --target-image "$WORK/sph/s1.nii" --target-image "$WORK/ell/s1.nii" \
    --jobs 2 --no-model -o "$WORK/b1" 2>"$WORK/b1.err"
check_rc $? "batch --target-image twice exits 0" "$(cat "$WORK/b1.err")"
cmp -s "$WORK/run-sph/result.mesh" "$WORK/b1/targets/s1/result.mesh" &&
    cmp -s "$WORK/run-ell/result.mesh" "$WORK/b1/targets/s1-2/result.mesh" &&
    cmp -s "$WORK/run-ell/displacement.sol" "$WORK/b1/targets/s1-2/displacement.sol"
check_rc $? "each target's result is its own run's, bit for bit (names s1, s1-2)"
jq -e '[.targets[] | .status] == ["finished", "finished"] and (.targets[1].target | endswith("ell/s1.nii"))' \
    "$WORK/b1/summary.json" >/dev/null
check_rc $? "summary.json: both finished, each naming its image" "$(head -c 400 "$WORK/b1/summary.json")"

# LIST.csv: the target_image column (paths relative to the list), with an
# image that is not one: that target fails alone (exit 11), the other's
# result is its run's
printf 'not an image\n' >"$WORK/bad.nii"
printf 'name,target_image\nsphere,sph/s1.nii\n# a comment\nbroken,bad.nii\n' >"$WORK/list.csv"
"$BIN" batch "${RUN[@]}" --targets "$WORK/list.csv" --jobs 2 --no-model -o "$WORK/b2" 2>"$WORK/b2.err"
rc=$?
[ $rc = 11 ] && cmp -s "$WORK/run-sph/result.mesh" "$WORK/b2/targets/sphere/result.mesh" &&
    jq -e '[.targets[] | [.name, .status]] | .[0] == ["sphere", "finished"] and .[1][0] == "broken" and .[1][1] != "finished"' \
        "$WORK/b2/summary.json" >/dev/null
check_rc $? "LIST.csv with target_image: the sphere's result is its run's, the broken image fails alone (exit 11)" \
    "rc $rc: $(cat "$WORK/b2.err")"

# an image and a surface on one row: refused, nothing run
printf 'target_image,target_surface\nsph/s1.nii,x.stl\n' >"$WORK/both.csv"
"$BIN" batch "${RUN[@]}" --targets "$WORK/both.csv" -o "$WORK/no" 2>"$WORK/both.err"
rc=$?
[ $rc != 0 ] && grep -q "exclude each other" "$WORK/both.err" && [ ! -e "$WORK/no" ]
check_rc $? "a row with target_image and target_surface is refused (exit $rc), nothing run" "$(cat "$WORK/both.err")"
echo "1..$n"
[ "$failed" -eq 0 ]
