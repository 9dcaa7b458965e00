#!/usr/bin/env bash
# `shapematch warp` end to end on result folders made from the bundled
# templates under known maps (tests/cli/warp_check.py: an affine map and a
# smooth bend), every answer checked by that script's brute force:
# points forward (barycentric images, inside flags, outside points
# extrapolated), inverse(forward(x)) = x, the template and its Gmsh copy
# warped to .mesh, .meshb and .vtu, its boundary as OBJ, STL, PLY, OFF,
# VTK and VTU, a vector
# field to A v (and normalized), a symmetric tensor field (Medit type 3)
# to A T Aᵀ and back; malformed CSV lines named, --strict, usage errors
# with their exit codes.  2D and 3D.
source "$(dirname "$0")/../lib/cli.sh"
CHECK="python3 $ROOT/tests/cli/warp_check.py"
T2=$ROOT/examples/2d/template.mesh
T3=$ROOT/examples/3d/template.mesh
# the disk and the ball of the examples have radius 0.25 and 0.3
for case in 2d:bend:$T2: 2d:affine:$T2:0.25 3d:affine:$T3:0.3; do
    IFS=: read -r dim kind tmpl radius <<<"$case"
    dir=$WORK/$dim-$kind
    mkdir -p "$dir"
    $CHECK make "$tmpl" "$dir" "$kind"
    $CHECK points "$tmpl" "$dir/p.csv" 100 7
    expect_ok "$dim $kind: warp --points" "$BIN" warp --result "$dir" --points "$dir/p.csv" \
        -o "$dir/fwd.csv"
    expect_ok "$dim $kind: forward images and inside flags (brute force or exact)" \
        $CHECK forward "$tmpl" "$kind" "$dir/p.csv" "$dir/fwd.csv" $radius
    cols=2
    [ "$dim" = 3d ] && cols=3
    cut -d, -f1-$cols "$dir/fwd.csv" >"$dir/fwd-xyz.csv"
    expect_ok "$dim $kind: warp --inverse" "$BIN" warp --result "$dir" --inverse \
        --points "$dir/fwd-xyz.csv" -o "$dir/back.csv"
    if [ "$kind" = affine ]; then
        expect_ok "$dim $kind: inverse(forward(x)) = x, outside points included" \
            $CHECK roundtrip "$dir/p.csv" "$dir/back.csv" "$tmpl"
    else # inside points only: outside, the nearest elements differ
        paste -d, "$dir/p.csv" <(cut -d, -f$((cols + 1)) "$dir/fwd.csv") |
            awk -F, 'NR == 1 || $NF == 1' | cut -d, -f1-$cols >"$dir/p-in.csv"
        paste -d, "$dir/back.csv" <(cut -d, -f$((cols + 1)) "$dir/fwd.csv") |
            awk -F, 'NR == 1 || $NF == 1' | cut -d, -f1-$cols >"$dir/back-in.csv"
        expect_ok "$dim $kind: inverse(forward(x)) = x to 1e-9 of the diameter" \
            $CHECK roundtrip "$dir/p-in.csv" "$dir/back-in.csv" "$tmpl"
    fi
    expect_ok "$dim $kind: the template warped (.mesh)" "$BIN" warp --result "$dir" \
        --mesh "$tmpl" -o "$dir/t.mesh"
    expect_ok "$dim $kind: its vertices are the map's" $CHECK mesh "$tmpl" "$kind" "$tmpl" \
        "$dir/t.mesh"
done

# --- formats: Gmsh in, .meshb and .vtu out; surfaces as OBJ and STL (3D affine)
dir=$WORK/3d-affine
# (gmsh renumbers: its .mesh of the same nodes gives the order to compare in)
gmsh "$T3" -0 -format msh41 -v 1 -o "$WORK/t3.msh" >/dev/null 2>&1
gmsh "$WORK/t3.msh" -0 -format mesh -v 1 -o "$WORK/t3-gmsh.mesh" >/dev/null 2>&1
expect_ok "3d: a Gmsh copy of the template warped to .vtu" "$BIN" warp --result "$dir" \
    --mesh "$WORK/t3.msh" -o "$dir/t.vtu"
expect_ok "3d: the .vtu points are the map's" $CHECK vtu "$T3" affine "$WORK/t3-gmsh.mesh" \
    "$dir/t.vtu"
expect_ok "3d: warped to .meshb and back with --inverse" sh -c \
    "'$BIN' warp -q --result '$dir' --mesh '$T3' -o '$dir/t.meshb' &&
     '$BIN' warp -q --result '$dir' --inverse --mesh '$dir/t.meshb' -o '$dir/back.mesh'"
expect_ok "3d: .meshb round trip gives the template" $CHECK mesh "$T3" identity "$T3" \
    "$dir/back.mesh"
$CHECK surface "$T3" "$WORK/s.obj" "$WORK/s.stl"
expect_ok "3d: the boundary as OBJ warped" "$BIN" warp --result "$dir" --mesh "$WORK/s.obj" \
    -o "$dir/s.obj"
expect_ok "3d: OBJ vertices are the map's" $CHECK surfcheck "$WORK/s.obj" "$dir/s.obj" 1e-12
expect_ok "3d: a surface written as Medit and back with --inverse" sh -c \
    "'$BIN' warp -q --result '$dir' --mesh '$WORK/s.obj' -o '$dir/s.mesh' &&
     '$BIN' warp -q --result '$dir' --inverse --mesh '$dir/s.mesh' -o '$dir/s-back.obj'"
expect_ok "3d: the surface came back" $CHECK surfcheck "$WORK/s.obj" "$dir/s-back.obj" 1e-12 \
    identity
expect_ok "3d: the boundary as STL warped" "$BIN" warp --result "$dir" --mesh "$WORK/s.stl" \
    -o "$dir/s.stl"
expect_ok "3d: STL vertices are the map's (single precision)" $CHECK surfcheck "$WORK/s.stl" \
    "$dir/s.stl" 2e-6
for fmt in ply off vtk vtu; do
    expect_ok "3d: the boundary warped to .$fmt (sm_surface_write)" "$BIN" warp -q \
        --result "$dir" --mesh "$WORK/s.obj" -o "$dir/s.$fmt"
    expect_ok "3d: .$fmt vertices are the map's (read by the check script)" $CHECK surfcheck \
        "$WORK/s.obj" "$dir/s.$fmt" 1e-12
    expect_ok "3d: .$fmt read back by shapematch and warped back to the boundary" sh -c \
        "'$BIN' warp -q --result '$dir' --inverse --mesh '$dir/s.$fmt' -o '$dir/s-back-$fmt.obj' &&
         $CHECK surfcheck '$WORK/s.obj' '$dir/s-back-$fmt.obj' 1e-12 identity"
done

# --- fields: a constant vector (1, 2[, 3]) under the affine map
for dim in 2d 3d; do
    dir=$WORK/$dim-affine
    python3 - "$dir" "$dim" <<'PY'
import sys
d, dim = sys.argv[1], 3 if sys.argv[2] == "3d" else 2
toks = open(d + "/displacement.sol").read().split()
n = int(toks[toks.index("SolAtVertices") + 1])
v = " ".join(["1", "2", "3"][:dim])
open(d + "/v.sol", "w").write("MeshVersionFormatted 2\nDimension %d\nSolAtVertices\n%d\n1 2\n%s\nEnd\n"
                              % (dim, n, "\n".join([v] * n)))
PY
    tmpl=$T2
    [ "$dim" = 3d ] && tmpl=$T3
    expect_ok "$dim: a vector field warped" "$BIN" warp --result "$dir" --field "$dir/v.sol" \
        -o "$dir/Av.sol"
    expect_ok "$dim: it equals A v" $CHECK field "$tmpl" "$dir/Av.sol" 0
    expect_ok "$dim: --normalize" "$BIN" warp --result "$dir" --normalize --field "$dir/v.sol" \
        -o "$dir/Av1.sol"
    expect_ok "$dim: it equals A v / |A v|" $CHECK field "$tmpl" "$dir/Av1.sol" 1
    $CHECK tensor_make "$tmpl" "$dir/T.sol"
    expect_ok "$dim: a symmetric tensor field (type 3) warped" "$BIN" warp --result "$dir" \
        --field "$dir/T.sol" -o "$dir/ATAt.solb"
    expect_ok "$dim: it equals A T Aᵀ at every vertex" sh -c \
        "'$BIN' warp -q --result '$dir' --field '$dir/T.sol' -o '$dir/ATAt.sol' &&
         $CHECK tensor_check '$tmpl' '$dir/ATAt.sol' affine"
    expect_ok "$dim: back with --inverse (.solb in) it is T again" sh -c \
        "'$BIN' warp -q --result '$dir' --inverse --field '$dir/ATAt.solb' -o '$dir/T-back.sol' &&
         $CHECK tensor_check '$tmpl' '$dir/T-back.sol' identity"
done

# --- bad inputs and usage
dir=$WORK/2d-affine
printf 'x,y\n0.5,0.5\n0.4,0.4\n0.3,zz\n' >"$WORK/bad.csv"
expect_fail "malformed CSV: its line named, exit 2" 2 "line 4, field 2: 'zz'" \
    "$BIN" warp --result "$dir" --points "$WORK/bad.csv" -o "$WORK/o.csv"
printf '0.5,0.5\n0.4,0.4,0.1\n' >"$WORK/bad2.csv"
expect_fail "mixed coordinate counts: line 2 named" 2 "line 2: expected 2 coordinates, found 3" \
    "$BIN" warp --result "$dir" --points "$WORK/bad2.csv" -o "$WORK/o.csv"
printf '0.5,0.5,0.5\n' >"$WORK/p3.csv"
expect_fail "3D points on a 2D map" 2 "3D points and the map is 2D" \
    "$BIN" warp --result "$dir" --points "$WORK/p3.csv" -o "$WORK/o.csv"
printf '0.5,0.5\n5,5\n' >"$WORK/out.csv"
expect_fail "--strict refuses a point outside" 2 "line 2: point (5, 5) is outside the template" \
    "$BIN" warp --result "$dir" --strict --points "$WORK/out.csv" -o "$WORK/o.csv"
printf 'x,y\n\n0.5,0.5\r\n  \n0.25,0.5\n5,5\n' >"$WORK/out-lines.csv"
expect_fail "--strict names the CSV line (header and blank lines counted)" 2 \
    "out-lines.csv: line 6: point (5, 5) is outside the template (distance " \
    "$BIN" warp --result "$dir" --strict --points "$WORK/out-lines.csv" -o "$WORK/o.csv"
expect_ok "without --strict it is flagged" "$BIN" warp -q --result "$dir" \
    --points "$WORK/out.csv" -o "$WORK/o.csv"
if [ "$(sed -n 3p "$WORK/o.csv" | cut -d, -f3)" = 0 ]; then
    ok "the outside point's inside column is 0"
else
    not_ok "the outside point's inside column is 0" "$(cat "$WORK/o.csv")"
fi
expect_ok "-o - writes to standard output" sh -c \
    "'$BIN' warp -q --result '$dir' --points '$WORK/out.csv' -o - | grep -q '^x,y,inside$'"
expect_ok "warp --help names its options" sh -c \
    "'$BIN' warp --help | grep -q -- '--inverse' && '$BIN' --help | grep -q '^  warp '"
expect_fail "no map given: usage" 1 "exactly one of --result DIR and --job ID" \
    "$BIN" warp --points "$WORK/out.csv" -o "$WORK/o.csv"
expect_fail "two inputs: usage" 1 "exactly one of --points, --mesh and --field" \
    "$BIN" warp --result "$dir" --points "$WORK/out.csv" --mesh "$T2" -o "$WORK/o.csv"
expect_fail "--normalize without --field: usage" 1 "--normalize is for --field" \
    "$BIN" warp --result "$dir" --normalize --points "$WORK/out.csv" -o "$WORK/o.csv"
expect_fail "a folder without a result" 2 "has no result.mesh" \
    "$BIN" warp --result "$WORK" --points "$WORK/out.csv" -o "$WORK/o.csv"
expect_fail "an output extension it cannot write: usage" 1 "chosen by its extension" \
    "$BIN" warp --result "$dir" --mesh "$T2" -o "$WORK/o.msh"
[ "$failed" = 0 ]
