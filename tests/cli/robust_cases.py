"""The robustness cases of issue 20, shared by tests/cli/robust.sh and
bench/robust.sh: Gmsh geometries of a unit-ball template and of analytic
targets, and the boundary RMS error of a result measured independently of
shapematch, against the analytic target surface (not its STL, not the
background's interpolated distance).

  python3 robust_cases.py geo NAME OUT.geo       write a case's .geo
  python3 robust_cases.py rms NAME result.mesh   print the boundary RMS
                                                 (and the boundary area)
"""
import math
import sys


BALL = 'SetFactory("OpenCASCADE");\nSphere(1) = {0, 0, 0, 1};\n'
# name: (.geo text, semi-axes for the ellipsoids / torus radii / spheres)
ELLIPSOIDS = {
    "ellipsoid": (1.3, 0.9, 0.8),
    "grown": (2.6, 1.8, 1.6),
    "shrunk": (0.65, 0.45, 0.4),
}
TORUS = (0.9, 0.35)
PEANUT = ((-0.5, 0.75), (0.5, 0.75))  # (centre x, radius) of two balls


def geo(name):
    head = 'SetFactory("OpenCASCADE");\nMesh.MeshSizeFromPoints = 0;\n'
    if name == "ball":
        return head + "Sphere(1) = {0, 0, 0, 1};\n"
    if name in ELLIPSOIDS:
        a, b, c = ELLIPSOIDS[name]
        return head + "Sphere(1) = {0, 0, 0, 1};\nDilate {{0, 0, 0}, {%g, %g, %g}} { Volume{1}; }\n" % (a, b, c)
    if name == "torus":
        return head + "Torus(1) = {0, 0, 0, %g, %g};\n" % TORUS
    if name == "peanut":
        (x1, r1), (x2, r2) = PEANUT
        return head + ("Sphere(1) = {%g, 0, 0, %g};\nSphere(2) = {%g, 0, 0, %g};\n"
                       "BooleanUnion{ Volume{1}; Delete; }{ Volume{2}; Delete; }\n" % (x1, r1, x2, r2))
    raise SystemExit("unknown case " + name)


def ellipsoid_distance(p, axes):
    """Exact unsigned distance from point p to the ellipsoid surface: the
    closest point is a_i^2 y_i / (t + a_i^2) for the root t of
    sum (a_i y_i / (t + a_i^2))^2 = 1 (decreasing in t > -min a_i^2),
    found by bisection."""
    a2 = [a * a for a in axes]
    y = [abs(c) for c in p]
    lo = -min(a2)
    hi = math.sqrt(sum(c * c for c in y)) * math.sqrt(max(a2)) + max(a2)
    for _ in range(100):
        t = 0.5 * (lo + hi)
        f = sum((math.sqrt(a2[i]) * y[i] / (t + a2[i])) ** 2 for i in range(3)) - 1.0
        if f > 0:
            lo = t
        else:
            hi = t
    t = 0.5 * (lo + hi)
    return math.sqrt(sum((a2[i] * y[i] / (t + a2[i]) - y[i]) ** 2 for i in range(3)))


def distance(name, p):
    """Unsigned distance from p to the analytic surface of case name."""
    if name in ELLIPSOIDS:
        return ellipsoid_distance(p, ELLIPSOIDS[name])
    if name == "ball":
        return abs(math.sqrt(sum(c * c for c in p)) - 1.0)
    if name == "torus":
        big, small = TORUS
        return abs(math.hypot(math.hypot(p[0], p[1]) - big, p[2]) - small)
    if name == "peanut":
        # the union's surface: the part of each sphere outside the other
        # ball; the distance to such a cap is to its sphere where the
        # point projects into the cap, else to the cap's rim circle
        (x1, r1), (x2, r2) = PEANUT
        xr = (r1 ** 2 - r2 ** 2 + x2 ** 2 - x1 ** 2) / (2 * (x2 - x1))  # rim plane
        rim = math.sqrt(r1 ** 2 - (xr - x1) ** 2)
        rho = math.hypot(p[1], p[2])
        to_rim = math.hypot(p[0] - xr, rho - rim)
        best = math.inf
        for xc, r, side in ((x1, r1, -1), (x2, r2, 1)):
            v = (p[0] - xc, p[1], p[2])
            n = math.sqrt(sum(c * c for c in v))
            in_cap = side * (xc + r * v[0] / max(n, 1e-300) - xr) >= 0
            best = min(best, abs(n - r) if in_cap else to_rim)
        return best
    raise SystemExit("unknown case " + name)


def read_medit(path):
    """Vertices and boundary triangles (0-based) of a Medit ASCII mesh."""
    with open(path) as f:
        tok = f.read().split()
    i, verts, tris = 0, [], []
    while i < len(tok):
        w = tok[i]
        if w == "Vertices":
            n = int(tok[i + 1])
            verts = [tuple(float(x) for x in tok[i + 2 + 4 * k:i + 5 + 4 * k]) for k in range(n)]
            i += 2 + 4 * n
        elif w == "Triangles":
            n = int(tok[i + 1])
            tris = [tuple(int(x) - 1 for x in tok[i + 2 + 4 * k:i + 5 + 4 * k]) for k in range(n)]
            i += 2 + 4 * n
        else:
            i += 1
    return verts, tris


def rms(name, mesh_path):
    """sqrt(int d^2 / area) over the result's boundary triangles, d the
    exact distance at the vertices, integrated exactly for P1."""
    v, t = read_medit(mesh_path)
    used = sorted({k for tri in t for k in tri})
    d = {k: distance(name, v[k]) for k in used}
    integral = total = 0.0
    for i, j, k in t:
        a, b, c = v[i], v[j], v[k]
        e1 = [b[m] - a[m] for m in range(3)]
        e2 = [c[m] - a[m] for m in range(3)]
        cr = (e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0])
        area = 0.5 * math.sqrt(sum(x * x for x in cr))
        da, db, dc = d[i], d[j], d[k]
        integral += area / 6 * (da * da + db * db + dc * dc + da * db + db * dc + dc * da)
        total += area
    return math.sqrt(integral / total), total


if __name__ == "__main__":
    if len(sys.argv) == 4 and sys.argv[1] == "geo":
        with open(sys.argv[3], "w") as f:
            f.write(geo(sys.argv[2]))
    elif len(sys.argv) == 4 and sys.argv[1] == "rms":
        r, area = rms(sys.argv[2], sys.argv[3])
        print("%.6g %.6g" % (r, area))
    else:
        raise SystemExit(__doc__)
