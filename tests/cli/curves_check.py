"""2D curves as target surfaces (issue 38): a circle written as an OBJ
polyline ("l") and as a PLY "edge" element, and exact checks against the
circle itself, not against the program's earlier output.

  curves_check.py write DIR
      DIR/circle.obj (one closed "l" line), DIR/circle_pieces.obj (the
      same circle as 4 open "l" lines), DIR/circle.ply (ASCII, edges),
      DIR/circle_bin.ply (binary little endian, edges), DIR/tilted.obj
      (the circle with one vertex at z = 0.1): N = 512 vertices at the
      angles 2 pi i / N of radius R = 0.32 about (0.5, 0.5).
  curves_check.py sdf MESH SOL
      the largest error of the distance at the background vertices
      against |x - c| - R (the polygon lies within R (1 - cos(pi/N)) of
      the circle, 1.9e-5 here: the bound is 3e-5).
  curves_check.py radius RESULT.mesh
      the largest | |x - c| - R | over the result's boundary vertices
      (Medit Edges of reference 1)."""
import math
import struct
import sys

N = 512
R = 0.32
C = (0.5, 0.5)


def points():
    return [(C[0] + R * math.cos(2 * math.pi * i / N), C[1] + R * math.sin(2 * math.pi * i / N))
            for i in range(N)]


def write(d):
    p = points()
    v = "".join("v %.17g %.17g 0\n" % q for q in p)
    with open(d + "/circle.obj", "w") as f:
        f.write("# a circle as one closed polyline\n" + v)
        f.write("l " + " ".join(str(i + 1) for i in range(N)) + " 1\n")
    with open(d + "/circle_pieces.obj", "w") as f:
        f.write(v)
        for k in range(4):
            idx = [(i % N) + 1 for i in range(k * N // 4, (k + 1) * N // 4 + 1)]
            f.write("l " + " ".join("%d/%d" % (i, i) for i in idx) + "\n")
    with open(d + "/tilted.obj", "w") as f:
        f.write(v.replace(" 0\n", " 0.1\n", 1) + "l 1 2 3\n")
    edges = [(i, (i + 1) % N) for i in range(N)]
    with open(d + "/circle.ply", "w") as f:
        f.write("ply\nformat ascii 1.0\nelement vertex %d\nproperty double x\nproperty double y\n"
                "property double z\nelement edge %d\nproperty int vertex1\nproperty int vertex2\n"
                "end_header\n" % (N, N))
        f.writelines("%.17g %.17g 0\n" % q for q in p)
        f.writelines("%d %d\n" % e for e in edges)
    with open(d + "/circle_bin.ply", "wb") as f:
        f.write(b"ply\nformat binary_little_endian 1.0\nelement vertex %d\nproperty double x\n"
                b"property double y\nproperty double z\nelement edge %d\nproperty int vertex1\n"
                b"property int vertex2\nproperty uchar red\nend_header\n" % (N, N))
        for q in p:
            f.write(struct.pack("<3d", q[0], q[1], 0.0))
        for e in edges:
            f.write(struct.pack("<2iB", e[0], e[1], 200))


def medit(path):
    tok = open(path).read().split()
    i = tok.index("Vertices")
    dim = int(tok[tok.index("Dimension") + 1])
    n = int(tok[i + 1])
    x = [[float(tok[i + 2 + (dim + 1) * v + k]) for k in range(dim)] for v in range(n)]
    return tok, x, dim


def sdf(mesh, sol):
    _, x, _ = medit(mesh)
    tok = open(sol).read().split()
    i = tok.index("SolAtVertices")
    vals = [float(t) for t in tok[i + 4:i + 4 + len(x)]]
    return max(abs(d - (math.dist(q[:2], C) - R)) for q, d in zip(x, vals))


def radius(path):
    tok, x, _ = medit(path)
    j = tok.index("Edges")
    b = set()
    for e in range(int(tok[j + 1])):
        a, c, ref = (int(t) for t in tok[j + 2 + 3 * e:j + 5 + 3 * e])
        if ref == 1:
            b.update((a - 1, c - 1))
    return max(abs(math.dist(x[v][:2], C) - R) for v in b)


if __name__ == "__main__":
    if sys.argv[1] == "write":
        write(sys.argv[2])
    elif sys.argv[1] == "sdf":
        print("%.3e" % sdf(sys.argv[2], sys.argv[3]))
    else:
        print("%.3e" % radius(sys.argv[2]))
