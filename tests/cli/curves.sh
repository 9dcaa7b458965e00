#!/usr/bin/env bash
# 2D curves as target surfaces (issue 38 item 2): a circle of radius 0.32
# written as an OBJ polyline ("l", one closed line and four open pieces
# with "i/t" references) and as a PLY "edge" element (ASCII and binary),
# tests/cli/curves_check.py.  The distance of `sdf --surface` is checked
# at every background vertex against the exact |x - c| - R, the result
# of `run` on the 2D disk example against the circle itself (boundary
# vertices within 1e-3 of radius 0.32); the four files give the same
# result bit for bit; a curve off the plane z = 0 and an OBJ with
# nothing joining its vertices are refused with a message naming what
# the file holds; so are an STL given as the template, an image as a
# surface and a surface as an image (core/io/sm_io.c's format table).
source "$(dirname "$0")/../lib/cli.sh"
check_rc() { if [ "$1" = 0 ]; then ok "$2"; else not_ok "$2" "${3:-}"; fi; }
PY=/usr/bin/python3
[ -x "$PY" ] || PY=python3
CHECK="$ROOT/tests/cli/curves_check.py"
export OMP_NUM_THREADS=1

"$PY" "$CHECK" write "$WORK"
check_rc $? "curves_check.py wrote the circle as OBJ and PLY"

for f in circle.obj circle_pieces.obj circle.ply circle_bin.ply; do
    "$BIN" sdf --surface "$WORK/$f" -o "$WORK/sdf_$f" >/dev/null 2>"$WORK/err"
    check_rc $? "sdf --surface $f (a 2D curve)" "$(cat "$WORK/err")"
    e=$("$PY" "$CHECK" sdf "$WORK/sdf_$f/background.mesh" "$WORK/sdf_$f/background.sol")
    "$PY" -c "import sys; sys.exit(0 if $e <= 3e-5 else 1)"
    check_rc $? "$f: distance within 3e-5 of the circle's exact distance everywhere ($e)"
done

RUN=(--template "$ROOT/examples/2d/template.mesh" --clamp-ball 0.5,0.5,0.04 --quiet)
for f in circle.obj circle_pieces.obj circle.ply circle_bin.ply; do
    "$BIN" run "${RUN[@]}" --target-surface "$WORK/$f" -o "$WORK/run_$f" >/dev/null 2>"$WORK/err"
    check_rc $? "run --target-surface $f converges" "$(cat "$WORK/err")"
done
e=$("$PY" "$CHECK" radius "$WORK/run_circle.obj/result.mesh")
"$PY" -c "import sys; sys.exit(0 if $e <= 1e-3 else 1)"
check_rc $? "the disk of radius 0.25 ends on the circle of radius 0.32 (max |r - R| $e)"
for f in circle_pieces.obj circle.ply circle_bin.ply; do
    cmp -s "$WORK/run_circle.obj/result.mesh" "$WORK/run_$f/result.mesh"
    check_rc $? "$f gives circle.obj's result bit for bit"
done

"$BIN" sdf --surface "$WORK/tilted.obj" -o "$WORK/tilted" >/dev/null 2>"$WORK/err"
rc=$?
grep -q "OBJ with 2 line segments and no faces is read as a 2D curve, which needs z = 0 on every vertex (vertex 1 has z = 0.1)" "$WORK/err"
check_rc $(( rc == 2 && $? == 0 ? 0 : 1 )) "a curve off z = 0 is refused naming the vertex (rc $rc)" "$(cat "$WORK/err")"
printf 'v 0 0 0\nv 1 0 0\n' >"$WORK/points.obj"
"$BIN" sdf --surface "$WORK/points.obj" -o "$WORK/points" >/dev/null 2>"$WORK/err"
grep -q "OBJ without faces or lines (2 vertices and nothing joining them)" "$WORK/err"
check_rc $? "an OBJ of bare vertices says what it holds" "$(cat "$WORK/err")"
sed -e 's/element edge 512/element edge 0/' -e '/^[0-9]* [0-9]*$/d' "$WORK/circle.ply" >"$WORK/noedge.ply"
"$BIN" sdf --surface "$WORK/noedge.ply" -o "$WORK/noedge" >/dev/null 2>"$WORK/err"
grep -q "PLY without faces or edges (512 vertices and nothing joining them)" "$WORK/err"
check_rc $? "a PLY of bare vertices says what it holds" "$(cat "$WORK/err")"

# a file of another kind than the option asks for is named for what it is
printf 'solid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\nendloop\nendfacet\nendsolid t\n' >"$WORK/t.stl"
"$BIN" run --template "$WORK/t.stl" --target-surface "$WORK/circle.obj" --clamp-ball 0,0,1 \
    -o "$WORK/no" >/dev/null 2>"$WORK/err"
rc=$?
grep -q "t.stl: a surface (STL), not a volume mesh (meshes are read as .*): a surface is a target (--target-surface, target_surface)" "$WORK/err"
check_rc $(( rc == 2 && $? == 0 ? 0 : 1 )) "an STL given as the template is named a surface (rc $rc)" "$(cat "$WORK/err")"
"$PY" "$ROOT/tests/cli/image2d.py" write "$WORK" >/dev/null
"$BIN" sdf --surface "$WORK/disk.nrrd" -o "$WORK/no" >/dev/null 2>"$WORK/err"
grep -q "disk.nrrd: an image (NRRD), not a surface (.*): a label map is a target image (--target-image, target_image)" "$WORK/err"
check_rc $? "an image given as a surface is named an image" "$(cat "$WORK/err")"
"$BIN" run --template "$ROOT/examples/2d/template.mesh" --target-image "$WORK/circle.ply" \
    --clamp-ball 0.5,0.5,0.04 -o "$WORK/no" >/dev/null 2>"$WORK/err"
grep -q "circle.ply: a surface (PLY), not an image" "$WORK/err"
check_rc $? "a surface given as the target image is named a surface" "$(cat "$WORK/err")"

echo "1..$n"
[ "$failed" = 0 ]
