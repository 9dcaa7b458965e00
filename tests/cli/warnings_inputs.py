import math, sys
def box(path, solpath, x0, x1, y0, y1, n, d):
    vs = []
    for j in range(n + 1):
        for i in range(n + 1):
            vs.append((x0 + (x1 - x0) * i / n, y0 + (y1 - y0) * j / n))
    tris = []
    for j in range(n):
        for i in range(n):
            a = j * (n + 1) + i + 1; b = a + 1; c = a + n + 1; e = c + 1
            tris += [(a, b, e), (a, e, c)]
    with open(path, "w") as f:
        f.write("MeshVersionFormatted 2\nDimension 2\nVertices\n%d\n" % len(vs))
        f.writelines("%.17g %.17g 0\n" % v for v in vs)
        f.write("Triangles\n%d\n" % len(tris))
        f.writelines("%d %d %d 1\n" % t for t in tris)
        f.write("End\n")
    with open(solpath, "w") as f:
        f.write("MeshVersionFormatted 2\nDimension 2\nSolAtVertices\n%d\n1 1\n" % len(vs))
        f.writelines("%.17g\n" % d(v) for v in vs)
        f.write("End\n")
circle = lambda v: math.hypot(v[0] - 0.5, v[1] - 0.5) - 0.3
out = sys.argv[1]
box(out + "/part.mesh", out + "/part.sol", 0.0, 0.6, 0.0, 1.0, 120, circle)
box(out + "/full.mesh", out + "/inverted.sol", 0.0, 1.0, 0.0, 1.0, 150, lambda v: -circle(v))
box(out + "/full2.mesh", out + "/elsewhere.sol", 0.0, 1.0, 0.0, 1.0, 150,
    lambda v: math.hypot(v[0] - 0.12, v[1] - 0.12) - 0.08)
