#!/usr/bin/env bash
# No clamp option: the template is held by a ball at its deepest
# interior point (core sm_clamp_default_ball), and the run says which.
# On the 3D example's ball the centre is the ball's (0.5, 0.5, 0.5) and
# the run converges as accurately as with the documented clamp; on a
# non-convex template (a dumbbell made with gmsh) the depth reported is
# numpy's brute-force maximum over the vertices and element centroids of
# the exact distance to the boundary triangles; 2D too; an explicit clamp
# wins; Python's match without a clamp gives the CLI's result.
source "$(dirname "$0")/../lib/cli.sh"
check_rc() { if [ "$1" = 0 ]; then ok "$2"; else not_ok "$2" "${3:-}"; fi; }
PY=/usr/bin/python3
[ -x "$PY" ] || PY=python3
EX=$ROOT/examples
cd "$WORK" || exit 1

"$BIN" run --template "$EX/3d/template.mesh" --target-mesh "$EX/3d/background.mesh.gz" \
    --target-sol "$EX/3d/background.sol.gz" -q -o ex3 2>ex3.err
rc=$?
[ $rc = 0 ] && grep -q "warning: clamp-default: no clamp given: the ball of radius" ex3.err &&
    jq -e '.parameters.clamp.kind == "ball" and ([.parameters.clamp.center[] - 0.5 | fabs] | max) < 0.01
        and (.warnings | map(.code) | index("clamp-default")) != null and .converged
        and .boundary_rms <= 5e-5' ex3/summary.json >/dev/null
check_rc $? "3D example without a clamp: the ball's centre, converged, boundary RMS <= 5e-5" \
    "rc $rc: $(cat ex3.err; jq -c '.parameters.clamp, .boundary_rms' ex3/summary.json 2>&1)"

"$BIN" run --template "$EX/2d/template.mesh" --target-mesh "$EX/2d/background.mesh.gz" \
    --target-sol "$EX/2d/background.sol.gz" -q -o ex2 2>ex2.err
rc=$?
{ [ $rc = 0 ] || [ $rc = 10 ]; } && grep -q "clamp-default" ex2.err &&
    jq -e '.parameters.clamp.kind == "ball" and (.parameters.clamp.center | length) == 2' \
        ex2/summary.json >/dev/null
check_rc $? "2D example without a clamp: a disk, reported" "rc $rc: $(cat ex2.err)"

# a dumbbell: two balls joined by a thin bar; its deepest point is in a
# ball, not at the centroid (the bar's middle)
cat >db.geo <<'GEO'
SetFactory("OpenCASCADE");
Sphere(1) = {-1, 0, 0, 0.6};
Sphere(2) = {1.1, 0, 0, 0.5};
Cylinder(3) = {-1, 0, 0, 2.1, 0, 0, 0.15};
BooleanUnion{ Volume{1}; Delete; }{ Volume{2}; Volume{3}; Delete; }
Mesh.MeshSizeMax = 0.12;
GEO
gmsh -3 db.geo -format mesh -o db.mesh -v 0 >/dev/null 2>&1 &&
    "$BIN" sdf --surface db.mesh -o dbt --background-size 0.1 >/dev/null 2>&1
check_rc $? "gmsh makes a dumbbell, sdf its distance"
"$BIN" run --template db.mesh --target-mesh dbt/background.mesh --target-sol dbt/background.sol \
    --max-iter 2 -q -o db 2>db.err
rc=$?
"$PY" - db.mesh db/summary.json >db.check 2>&1 <<'PYEOF'
import json, re, sys
import numpy as np
tok = open(sys.argv[1]).read().split()
def block(name, width):
    i = tok.index(name)
    n = int(tok[i + 1])
    return np.array(tok[i + 2:i + 2 + n * width], dtype=float).reshape(n, width)
v = block('Vertices', 4)[:, :3]
t = block('Tetrahedra', 5)[:, :4].astype(int) - 1
# the boundary: faces of one tetrahedron
faces = {}
for e in t:
    for f in ((0, 1, 2), (0, 1, 3), (0, 2, 3), (1, 2, 3)):
        k = tuple(sorted(e[list(f)]))
        faces[k] = faces.get(k, 0) + 1
tri = np.array([k for k, c in faces.items() if c == 1])
a, b, c = v[tri[:, 0]], v[tri[:, 1]], v[tri[:, 2]]
def dist(p):  # exact point-triangle distance, every triangle (Ericson's regions)
    ab, ac, ap = b - a, c - a, p - a
    d1, d2 = (ab * ap).sum(1), (ac * ap).sum(1)
    bp = p - b; d3, d4 = (ab * bp).sum(1), (ac * bp).sum(1)
    cp = p - c; d5, d6 = (ab * cp).sum(1), (ac * cp).sum(1)
    va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2
    den = np.where(va + vb + vc == 0, 1, va + vb + vc)
    v_, w_ = vb / den, vc / den
    q = a + ab * v_[:, None] + ac * w_[:, None]
    def seg(x, y, p):
        d = y - x
        s = np.clip(((p - x) * d).sum(1) / np.maximum((d * d).sum(1), 1e-300), 0, 1)
        return x + d * s[:, None]
    cands = [q, seg(a, b, p), seg(a, c, p), seg(b, c, p)]
    inside = (va >= 0) & (vb >= 0) & (vc >= 0)
    dq = np.linalg.norm(q - p, axis=1)
    de = np.min([np.linalg.norm(x - p, axis=1) for x in cands[1:]], axis=0)
    return np.min(np.where(inside, np.minimum(dq, de), de))
pts = np.vstack([v, v[t].mean(axis=1)])
depth = np.array([dist(p) for p in pts])
best = pts[np.argmax(depth)]
s = json.load(open(sys.argv[2]))
w = [x for x in s['warnings'] if x['code'] == 'clamp-default'][0]
reported = float(re.search(r"deepest point \(([0-9.e+-]+) from", w['message']).group(1))
centre = np.array(s['parameters']['clamp']['center'])
print('depth: numpy %.6g at %s, reported %.6g at %s' % (depth.max(), best, reported, centre))
assert abs(reported - depth.max()) <= 1e-3 * depth.max()
assert np.linalg.norm(centre - best) < 1e-9 or abs(dist(centre) - depth.max()) < 1e-9
assert centre[0] < -0.5, 'the deepest point is in the larger ball'
PYEOF
check_rc $? "dumbbell: the reported depth and centre are numpy's brute-force maximum" \
    "rc $rc: $(cat db.check db.err)"

"$BIN" run --template "$EX/3d/template.mesh" --target-mesh "$EX/3d/background.mesh.gz" \
    --target-sol "$EX/3d/background.sol.gz" --clamp-ball 0.5,0.5,0.5,0.05 --max-iter 2 -q \
    -o explicit 2>explicit.err
! grep -q clamp-default explicit.err && jq -e '.parameters.clamp.radius == 0.05' \
    explicit/summary.json >/dev/null
check_rc $? "an explicit clamp wins: no default, its radius" "$(cat explicit.err)"

# Python in the release variant (python.sh runs the package under ASan)
if [ "${SM_VARIANT:-release}" != release ]; then
    skip "Python match without a clamp: release variant only"
    echo "1..$n"
    exit $((failed > 0))
fi
SHAPEMATCH_LIBDIR=${SM_BIN:-$ROOT/build/release} PYTHONPATH=$ROOT/python "$PY" - "$EX" >py.out 2>&1 <<'PYEOF'
import json, sys
import shapematch
ex = sys.argv[1]
r = shapematch.match(ex + "/3d/template.mesh", target_mesh=ex + "/3d/background.mesh.gz",
                     target_sol=ex + "/3d/background.sol.gz")
cli = json.load(open("ex3/summary.json"))
assert r.summary["parameters"]["clamp"] == cli["parameters"]["clamp"], r.summary["parameters"]
assert r.summary["iterations"] == cli["iterations"]
print("python: the CLI's clamp and", cli["iterations"], "iterations")
PYEOF
check_rc $? "Python match without a clamp: the CLI's ball and iterations" "$(cat py.out)"
echo "1..$n"
exit $((failed > 0))
