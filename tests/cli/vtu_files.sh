#!/usr/bin/env bash
# The .vtu files for ParaView: result.vtu zlib-compressed (the default) and
# ASCII (--format vtu-ascii) hold the same arrays, decoded by an
# independent reader (tests/lib/vtu.py: ElementTree, base64, zlib);
# --format ...,gz never makes a .vtu.gz and vtu-ascii,gz is refused;
# --save-every 3 of a 4-iteration run writes iter-NNNNN.vtu beside each
# iter-NNNNN.mesh for the first state, iteration 3 and the final state 4
# (the same points, displacement = points - template, distance = d at the
# points by an independent P1 interpolation of the background's .sol; the
# last one equal to result.vtu) and a snapshots.pvd listing the three; `sdf -o x.vtu` writes one file (not a directory) and `sdf -o x.sol`
# without --background is refused.  meshio (python3-meshio) and VTK
# (python3-vtk9) read result.vtu and the collection when installed.
source "$(dirname "$0")/../lib/cli.sh"
EX=$ROOT/examples/2d
CLAMP=$(tr -d ' \n' <"$EX/clamp")
run() { # OUT FORMAT [more...]
    local out=$1 fmt=$2
    shift 2
    "$BIN" run --template "$EX/template.mesh" --target-mesh "$EX/background.mesh.gz" \
        --target-sol "$EX/background.sol.gz" --clamp-ball "$CLAMP" --max-iter 4 --quiet \
        --format "$fmt" -o "$WORK/$out" "$@" >"$WORK/$out.err" 2>&1
}
run z mesh,vtu,gz --save-every 3
rc=$?
run a vtu-ascii
rc_a=$?
if { [ $rc = 0 ] || [ $rc = 10 ]; } && { [ $rc_a = 0 ] || [ $rc_a = 10 ]; }; then
    ok "runs with --format mesh,vtu,gz --save-every 3 and --format vtu-ascii"
else
    not_ok "runs with --format mesh,vtu,gz --save-every 3 and --format vtu-ascii" \
        "$(cat "$WORK/z.err" "$WORK/a.err")"
fi
run g vtu-ascii,gz
rc=$?
check "vtu-ascii,gz is refused (usage, exit 1) and writes nothing" \
    test $rc = 1 -a ! -e "$WORK/g/result.vtu.gz" -a ! -e "$WORK/g/result.vtu"
grep -q "ParaView" "$WORK/g.err" || not_ok "the refusal says why" "$(cat "$WORK/g.err")"

"$BIN" sdf --surface "$ROOT/tests/data/formats/cells/surface-le.ply" -o "$WORK/d.vtu" \
    >"$WORK/sdf.err" 2>&1
check "sdf -o d.vtu (a PLY surface) writes one file" test -f "$WORK/d.vtu"
"$BIN" sdf --surface "$ROOT/tests/data/formats/cells/surface.off" -o "$WORK/d.sol" \
    >"$WORK/sdf2.err" 2>&1
rc=$?
check "sdf -o d.sol without --background is refused (usage, exit 1), nothing created" \
    test $rc = 1 -a ! -e "$WORK/d.sol"

# Debian's python3, where python3-meshio is installed (a python3 earlier
# on the PATH may lack it)
PY=/usr/bin/python3
[ -x "$PY" ] || PY=python3
"$PY" - "$WORK" "$ROOT/tests/lib" "$EX/template.mesh" "$EX" <<'PY'
import gzip, os, sys, xml.etree.ElementTree as ET
sys.path.insert(0, sys.argv[2])
import vtu
W = sys.argv[1]
def check(ok, what, why=""):
    print("%s - %s%s" % ("ok" if ok else "not ok", what, "" if ok or not why else "\n# " + str(why)[:400]))
def medit_vertices(path):
    t = open(path).read().split()
    k = t.index("Vertices"); n = int(t[k + 1])
    dim = int(t[t.index("Dimension") + 1])
    return [[float(t[k + 2 + i * (dim + 1) + c]) for c in range(dim)] for i in range(n)]
try:
    pz, z = vtu.read(os.path.join(W, "z", "result.vtu"))
    pa, a = vtu.read(os.path.join(W, "a", "result.vtu"))
    head = open(os.path.join(W, "z", "result.vtu"), "rb").read(400).decode("latin-1")
    check('compressor="vtkZLibDataCompressor"' in head and 'format="ascii"' not in
          open(os.path.join(W, "z", "result.vtu")).read(), "result.vtu is zlib-compressed by default")
    check(set(z) == set(a) and all(z[k] == a[k] for k in z) and pz == pa,
          "zlib and ASCII result.vtu hold the same %d arrays, value for value" % len(z))
    size_z = os.path.getsize(os.path.join(W, "z", "result.vtu"))
    size_a = os.path.getsize(os.path.join(W, "a", "result.vtu"))
    check(size_z < size_a, "compressed %d bytes, ASCII %d" % (size_z, size_a))
except Exception as e:
    check(False, "result.vtu decodes", repr(e))
files = sorted(os.listdir(os.path.join(W, "z")))
check("result.vtu" in files and "result.vtu.gz" not in files and "result.mesh.gz" in files,
      "with gz: result.mesh.gz but result.vtu (compressed inside)", files)
import json
s = json.load(open(os.path.join(W, "z", "summary.json")))
check(s.get("outputs", {}).get("mesh", {}).get("vtu") == "result.vtu",
      "summary.json names result.vtu", s.get("outputs"))
try:
    col = ET.parse(os.path.join(W, "z", "snapshots.pvd")).getroot()
    sets = [(int(d.get("timestep")), d.get("file")) for d in col.findall("./Collection/DataSet")]
    check(col.get("type") == "Collection" and
          sets == [(0, "iter-00000.vtu"), (3, "iter-00003.vtu"), (4, "iter-00004.vtu")],
          "snapshots.pvd lists the first state, iteration 3 and the final state 4", sets)
    x0 = medit_vertices(sys.argv[3])
    worst = 0.0
    for it, f in sets:
        p = vtu.read(os.path.join(W, "z", f))[1]
        xm = medit_vertices(os.path.join(W, "z", f.replace(".vtu", ".mesh")))
        pts, d = p["Points"], p["displacement"]
        assert len(pts) == 3 * len(xm) == 3 * len(x0)
        for i, (q, q0) in enumerate(zip(xm, x0)):
            for c in range(2):
                worst = max(worst, abs(pts[3 * i + c] - q[c]), abs(d[3 * i + c] - (q[c] - q0[c])))
    check(worst <= 1e-12, "each iter-N.vtu: the points of iter-N.mesh, displacement = points - template (%.1g)" % worst)
    first = vtu.read(os.path.join(W, "z", "iter-00000.vtu"))[1]
    check(max(map(abs, first["displacement"])) == 0, "iter-00000.vtu is the template (displacement 0)")
except Exception as e:
    check(False, "the snapshots decode", repr(e))
# the distance field of every snapshot against d interpolated here: the
# background's P1 values at the barycentric coordinates of the triangle
# holding each point (found among the nearest triangles by centroid)
try:
    import numpy as np
    from scipy.spatial import cKDTree
    def medit_section(tokens, name, width):
        k = tokens.index(name)
        n = int(tokens[k + 1])
        return np.array(tokens[k + 2:k + 2 + n * width], dtype=float).reshape(n, width)
    t = gzip.open(os.path.join(sys.argv[4], "background.mesh.gz"), "rt").read().split()
    xy = medit_section(t, "Vertices", 3)[:, :2]
    tri = medit_section(t, "Triangles", 4)[:, :3].astype(int) - 1
    s = gzip.open(os.path.join(sys.argv[4], "background.sol.gz"), "rt").read().split()
    k = s.index("SolAtVertices")
    sol = np.array(s[k + 4:k + 4 + int(s[k + 1])], dtype=float)
    tree = cKDTree(xy[tri].mean(axis=1))
    def interpolate(pts):
        out = np.full(len(pts), np.nan)
        _, near = tree.query(pts, k=24)
        for i, p in enumerate(pts):
            for e in near[i]:
                a, b, c = xy[tri[e]]
                m = np.array([[b[0] - a[0], c[0] - a[0]], [b[1] - a[1], c[1] - a[1]]])
                l1, l2 = np.linalg.solve(m, p - a)
                if min(l1, l2, 1 - l1 - l2) >= -1e-12:
                    out[i] = (1 - l1 - l2) * sol[tri[e][0]] + l1 * sol[tri[e][1]] + l2 * sol[tri[e][2]]
                    break
        return out
    worst = 0.0
    for it, f in sets:
        p = vtu.read(os.path.join(W, "z", f))[1]
        pts = np.array(p["Points"]).reshape(-1, 3)[:, :2]
        want = interpolate(pts)
        worst = max(worst, float(np.max(np.abs(np.array(p["distance"]) - want))))
    last = vtu.read(os.path.join(W, "z", sets[-1][1]))[1]
    res = vtu.read(os.path.join(W, "z", "result.vtu"))[1]
    check(worst <= 1e-12 and last["distance"] == res["distance"] and last["Points"] == res["Points"],
          "each snapshot's distance is d at its points (independent P1 interpolation, %.1g); the final one is result.vtu's" % worst)
except Exception as e:
    check(False, "the snapshots' distance fields", repr(e))
try:
    d = vtu.read(os.path.join(W, "d.vtu"))[1]
    check(len(d["distance"]) * 3 == len(d["Points"]) and min(d["distance"]) < 0 < max(d["distance"]),
          "sdf's d.vtu: a distance per point, of both signs")
except Exception as e:
    check(False, "sdf's d.vtu decodes", repr(e))
try:
    import meshio
    m = meshio.read(os.path.join(W, "z", "result.vtu"))
    check(m.points.shape[0] * 3 == len(z["Points"]) and "ref" in m.cell_data,
          "meshio reads result.vtu (%d points)" % m.points.shape[0])
    m = meshio.read(os.path.join(W, "z", "iter-00004.vtu"))
    check(m.points.shape[0] * 3 == len(z["Points"]), "meshio reads iter-00004.vtu")
except ImportError:
    print("ok - # SKIP meshio is not installed (python3-meshio)")
except Exception as e:
    check(False, "meshio reads the .vtu files", repr(e))
try:
    import vtk
    r = vtk.vtkXMLUnstructuredGridReader()
    r.SetFileName(os.path.join(W, "z", "result.vtu"))
    r.Update()
    g = r.GetOutput()
    check(g.GetNumberOfPoints() * 3 == len(z["Points"]) and g.GetCellData().GetArray("ref"),
          "VTK reads result.vtu")
    pr = vtk.vtkPVDReader() if hasattr(vtk, "vtkPVDReader") else None
    if pr is None:
        print("ok - # SKIP this VTK has no vtkPVDReader (ParaView's)")
except ImportError:
    print("ok - # SKIP VTK is not installed (python3-vtk9)")
except Exception as e:
    check(False, "VTK reads result.vtu", repr(e))
PY
