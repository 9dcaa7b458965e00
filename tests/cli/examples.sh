#!/usr/bin/env bash
# The bundled examples end to end through `shapematch run`: each reaches
# ||d||_L2(boundary) <= 1e-3 with no inverted element (checked here from
# the written files, independently of the program's own counters), J never
# increases, and template + cumulative displacement equals the result mesh.
source "$(dirname "$0")/../lib/cli.sh"

for case in 2d 3d; do
    EX=$ROOT/examples/$case
    pick() { local f; for f in "$EX/$1" "$EX/$1.gz"; do [ -f "$f" ] && { echo "$f"; return 0; }; done; return 1; }
    if ! t=$(pick template.mesh) || ! b=$(pick background.mesh) || ! s=$(pick background.sol) || [ ! -s "$EX/clamp" ]; then
        not_ok "examples/$case is complete" "missing template.mesh, background.mesh, background.sol or clamp in $EX"
        continue
    fi
    out=$WORK/$case
    start=$SECONDS
    "$BIN" run --template "$t" --target-mesh "$b" --target-sol "$s" \
        --clamp-ball "$(tr -d ' \n' <"$EX/clamp")" --tol-boundary 1e-3 --max-iter 200 --quiet \
        -o "$out" >"$WORK/$case.out" 2>"$WORK/$case.err"
    rc=$?
    if [ $rc -ne 0 ]; then
        not_ok "examples/$case runs (exit $rc)" "$(head -c 400 "$WORK/$case.err")"
        continue
    fi
    ok "examples/$case runs ($((SECONDS - start)) s)"
    python3 - "$t" "$out" <<'PY'
import csv, gzip, json, sys

def tokens(path):
    opener = gzip.open if path.endswith(".gz") else open
    with opener(path, "rt") as f:
        for line in f:
            line = line.split("#", 1)[0]
            yield from line.split()

def read_mesh(path):
    tk = tokens(path)
    dim, verts, elems = None, [], []
    for w in tk:
        k = w.lower()
        if k == "dimension":
            dim = int(next(tk))
        elif k == "vertices":
            n = int(next(tk))
            for _ in range(n):
                verts.append([float(next(tk)) for _ in range(dim)])
                next(tk)
        elif k in ("triangles", "tetrahedra", "edges"):
            n = int(next(tk))
            width = {"edges": 2, "triangles": 3, "tetrahedra": 4}[k]
            rows = [[int(next(tk)) - 1 for _ in range(width + 1)][:width] for _ in range(n)]
            if (dim == 2 and k == "triangles") or (dim == 3 and k == "tetrahedra"):
                elems = rows
    return dim, verts, elems

def read_sol(path, dim):
    tk = tokens(path)
    for w in tk:
        if w.lower() == "solatvertices":
            n = int(next(tk)); nf = int(next(tk)); typ = int(next(tk))
            width = 1 if typ == 1 else dim
            return [[float(next(tk)) for _ in range(width)] for _ in range(n)]

def volume(x, e):
    if len(e) == 3:
        (ax, ay), (bx, by), (cx, cy) = (x[i] for i in e)
        return (bx - ax) * (cy - ay) - (by - ay) * (cx - ax)
    a, b, c, d = (x[i] for i in e)
    u = [b[k] - a[k] for k in range(3)]; v = [c[k] - a[k] for k in range(3)]; w = [d[k] - a[k] for k in range(3)]
    return (u[0] * (v[1] * w[2] - v[2] * w[1]) - u[1] * (v[0] * w[2] - v[2] * w[0]) + u[2] * (v[0] * w[1] - v[1] * w[0]))

template, out = sys.argv[1], sys.argv[2]
case = "examples/" + out.rstrip("/").split("/")[-1]
def report(ok, what, why=""):
    print("%s - %s %s%s" % ("ok" if ok else "not ok", case, what, "" if ok or not why else "\n# " + why))

s = json.load(open(out + "/summary.json"))
report(s["boundary_l2"] <= 1e-3, "reaches boundary_l2 <= 1e-3 (%.3g after %d iterations, %s)" % (
    s["boundary_l2"], s["iterations"], s["stop_reason"]), "boundary_l2 %g" % s["boundary_l2"])
report(s.get("warnings") == [], "warns of nothing", json.dumps(s.get("warnings")))
dim, x0, t0 = read_mesh(template)
_, x1, t1 = read_mesh(out + "/result.mesh")
flipped = sum(1 for e in t0 if volume(x0, e) * volume(x1, e) <= 0)
report(t0 == t1 and flipped == 0, "keeps the topology and inverts no element", "%d inverted" % flipped)
J = [float(r["J"]) for r in csv.DictReader(open(out + "/history.csv"))]
report(len(J) == s["iterations"] + 1 and all(b <= a for a, b in zip(J, J[1:])),
       "J never increases (%.6g -> %.6g)" % (J[0], J[-1]), "history %s" % J[:5])
disp = read_sol(out + "/displacement.sol", dim)
err = max(abs(x0[i][k] + disp[i][k] - x1[i][k]) for i in range(len(x0)) for k in range(dim))
moved = max(abs(disp[i][k]) for i in range(len(x0)) for k in range(dim))
report(err <= 1e-12 and moved > 1e-3, "template + displacement == result (max diff %.2g, max move %.3g)" % (err, moved))
PY
done
