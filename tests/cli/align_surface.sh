#!/usr/bin/env bash
# --align on surface targets (STL made by the real gmsh at test time):
# the background is generated after the alignment, around the moved
# template and the target, so a target moved 100 diameters away matches
# as well as the unmoved one (within 10%, the result's boundary against
# the exact sphere, computed here) on a background of the same size; a
# target in millimetres against a template in metres aligns and converges
# like the same pair in one unit (scale 1000 times the other's, boundary
# RMS 1000 times, within 10%) without --background-size; the alignment
# ran on the exact surface (summary alignment.exact).
source "$(dirname "$0")/../lib/cli.sh"
check_rc() { if [ "$1" = 0 ]; then ok "$2"; else not_ok "$2" "${3:-}"; fi; }
export OMP_NUM_THREADS=1

cp "$ROOT/tests/lib/case/ball.geo" "$WORK/sphere.geo"
cp "$ROOT/tests/lib/case/small_ball.geo" "$WORK/small.geo"
cat >"$WORK/ellipsoid.geo" <<'GEO'
SetFactory("OpenCASCADE");
Sphere(1) = {0, 0, 0, 1};
Dilate {{0, 0, 0}, {1.3, 0.9, 0.7}} { Volume{1}; }
Mesh.MeshSizeFromPoints = 0;
GEO
gmsh "$WORK/sphere.geo" -2 -format stl -clmax 0.1 -nt 1 -v 1 -o "$WORK/sphere.stl" >/dev/null 2>&1 &&
    gmsh "$WORK/ellipsoid.geo" -2 -format stl -clmax 0.1 -nt 1 -v 1 -o "$WORK/ell.stl" >/dev/null 2>&1 &&
    gmsh "$WORK/small.geo" -3 -format msh41 -clmax 0.2 -nt 1 -v 1 -o "$WORK/small.msh" >/dev/null 2>&1
check_rc $? "gmsh made the sphere and ellipsoid STLs and the ball template"

# ASCII STL with every vertex through "x*S+TX,y*S+TY,z*S+TZ"
stl_map() { # IN OUT SCALE TX TY TZ
    python3 - "$@" <<'PY'
import sys
src, dst, s, tx, ty, tz = sys.argv[1], sys.argv[2], *map(float, sys.argv[3:])
out = []
for line in open(src):
    f = line.split()
    if f and f[0] == "vertex":
        x, y, z = map(float, f[1:4])
        line = "vertex %.17g %.17g %.17g\n" % (x * s + tx, y * s + ty, z * s + tz)
    out.append(line)
open(dst, "w").writelines(out)
PY
}
stl_map "$WORK/sphere.stl" "$WORK/moved.stl" 1 100 -50 30
stl_map "$WORK/ell.stl" "$WORK/ell_mm.stl" 1000 0 0 0

run() { local name=$1; shift; "$BIN" run --template "$WORK/small.msh" --clamp-ball 0,0,0,0.3 \
    --quiet "$@" -o "$WORK/$name" >"$WORK/$name.out" 2>"$WORK/$name.err"; }

# RMS over the result's boundary vertices of |x - c| - 1 (the exact
# sphere, not the faceted STL: both runs share its chord error)
sphere_rms() { # RESULT.mesh CX CY CZ
    python3 - "$@" <<'PY'
import math, sys
tok = open(sys.argv[1]).read().split()
c = [float(v) for v in sys.argv[2:5]]
i = tok.index("Vertices")
x = [[float(tok[i + 2 + 4 * v + k]) for k in range(3)] for v in range(int(tok[i + 1]))]
j = tok.index("Triangles")
b = {int(tok[j + 2 + 4 * t + k]) - 1 for t in range(int(tok[j + 1])) for k in range(3)}
e = [math.dist(x[v], c) - 1 for v in b]
print("%.6e" % math.sqrt(sum(v * v for v in e) / len(e)))
PY
}

# ---- the background after the alignment: a moved STL as good as the unmoved
run here --target-surface "$WORK/sphere.stl" --align rigid
rc_here=$?
run far --target-surface "$WORK/moved.stl" --align rigid
rc_far=$?
HERE=$(sphere_rms "$WORK/here/result.mesh" 0 0 0)
FAR=$(sphere_rms "$WORK/far/result.mesh" 100 -50 30)
VH=$(jq .target_surface.background_vertices "$WORK/here/summary.json")
VF=$(jq .target_surface.background_vertices "$WORK/far/summary.json")
if [ "$rc_here" = "$rc_far" ] && [ -n "$HERE" ] && [ -n "$FAR" ] &&
    awk -v h="$HERE" -v f="$FAR" -v vh="$VH" -v vf="$VF" \
        'BEGIN { exit !(f <= 1.1 * h && vf >= 0.9 * vh && vf <= 1.1 * vh) }' &&
    [ "$(jq .alignment.exact "$WORK/far/summary.json")" = true ] &&
    grep -q "background generated around the moved template" "$WORK/far.err"; then
    ok "a target 100 diameters away, --align rigid: boundary RMS $FAR against the unmoved $HERE (the exact sphere), background $VF vertices against $VH"
else
    not_ok "moved STL (exit $rc_far/$rc_here, RMS $FAR vs $HERE, background $VF vs $VH)" \
        "$(head -c 600 "$WORK/far.err")"
fi

# ---- units: the target in millimetres, the template in metres
run m --target-surface "$WORK/ell.stl" --align similarity
rc_m=$?
run mm --target-surface "$WORK/ell_mm.stl" --align similarity
rc_mm=$?
read -r SM RM < <(jq -r '"\(.alignment.scale) \(.boundary_rms)"' "$WORK/m/summary.json")
read -r SMM RMM < <(jq -r '"\(.alignment.scale) \(.boundary_rms)"' "$WORK/mm/summary.json")
if [ "$rc_m" = "$rc_mm" ] && [ -n "$SMM" ] &&
    awk -v sm="$SM" -v smm="$SMM" -v rm="$RM" -v rmm="$RMM" 'BEGIN {
        r = smm / (1000 * sm); q = rmm / (1000 * rm)
        exit !(r > 0.999 && r < 1.001 && q > 0.9 && q < 1.1) }' &&
    ! grep -q "units" "$WORK/mm.err"; then
    ok "millimetres against metres, --align similarity, no --background-size: scale $SMM (one unit: $SM), boundary RMS $RMM mm (one unit: $RM m), exit $rc_mm as in one unit"
else
    not_ok "mixed units (exit $rc_mm/$rc_m, scale $SMM vs $SM, RMS $RMM vs $RM)" \
        "$(head -c 600 "$WORK/mm.err")"
fi
# the same pair without an alignment is still refused with its advice
"$BIN" run --template "$WORK/small.msh" --target-surface "$WORK/ell_mm.stl" \
    --clamp-ball 0,0,0,0.3 --quiet -o "$WORK/noalign" >/dev/null 2>"$WORK/noalign.err"
rc=$?
[ $rc = 2 ] && grep -q "different units" "$WORK/noalign.err"
check_rc $? "mixed units without --align: refused before any background (exit $rc)" \
    "$(head -c 400 "$WORK/noalign.err")"
