"""A star-shaped closed polyline for the CLI tests of surfaces with holes
(issue 21), and the exact sign of the distance to it.

  star_curve.py write OUT.mesh DROP REVERSE SEED
      2000 vertices at the angles 2 pi i / 2000 of r = 0.3 (1 + 0.25 cos 5t)
      about (0.5, 0.5), as Medit Edges; DROP: the fraction of edges removed
      at random; REVERSE: the probability of reversing each edge.
  star_curve.py check BACKGROUND.mesh BACKGROUND.sol MARGIN
      counts the background vertices farther than MARGIN from the closed
      polyline whose sign (negative inside) is wrong.  Exact: the polygon
      is star-shaped about the centre with its vertices in angular order, so
      a point is inside when it is on the inner side of the edge of its
      angular sector; distances by brute force over the edges near the
      point (a bucket grid of cell MARGIN: edges are shorter than MARGIN,
      so an edge within MARGIN of the point has its end points within
      2 MARGIN, two cells at most)."""
import math
import random
import sys

N = 2000
CX, CY = 0.5, 0.5


def vertices():
    out = []
    for i in range(N):
        t = 2 * math.pi * i / N
        r = 0.3 * (1 + 0.25 * math.cos(5 * t))
        out.append((CX + r * math.cos(t), CY + r * math.sin(t)))
    return out


def write(path, drop, reverse, seed):
    rnd = random.Random(seed)
    p = vertices()
    gone = set(rnd.sample(range(N), int(round(drop * N))))
    edges = []
    for i in range(N):
        if i in gone:
            continue
        a, b = i, (i + 1) % N
        edges.append((b, a) if rnd.random() < reverse else (a, b))
    with open(path, "w") as f:
        f.write("MeshVersionFormatted 2\nDimension 2\nVertices\n%d\n" % N)
        f.writelines("%.17g %.17g 0\n" % v for v in p)
        f.write("Edges\n%d\n" % len(edges))
        f.writelines("%d %d 1\n" % (a + 1, b + 1) for a, b in edges)
        f.write("End\n")


def seg_dist(q, a, b):
    ax, ay = b[0] - a[0], b[1] - a[1]
    l2 = ax * ax + ay * ay
    t = max(0.0, min(1.0, ((q[0] - a[0]) * ax + (q[1] - a[1]) * ay) / l2))
    return math.hypot(q[0] - a[0] - t * ax, q[1] - a[1] - t * ay)


def check(mesh, sol, margin):
    p = vertices()
    longest = max(math.dist(p[i], p[(i + 1) % N]) for i in range(N))
    assert longest < margin
    cells = {}
    for i, v in enumerate(p):
        cells.setdefault((int(v[0] // margin), int(v[1] // margin)), []).append(i)
    toks = open(mesh).read().split()
    k = toks.index("Vertices")
    nv = int(toks[k + 1])
    pts = [(float(toks[k + 2 + 3 * j]), float(toks[k + 3 + 3 * j])) for j in range(nv)]
    toks = open(sol).read().split()
    k = toks.index("SolAtVertices")
    assert int(toks[k + 1]) == nv
    d = [float(x) for x in toks[k + 4: k + 4 + nv]]
    far = bad = 0
    for q, dq in zip(pts, d):
        cx, cy = int(q[0] // margin), int(q[1] // margin)
        near = False
        for dx in (-2, -1, 0, 1, 2):
            for dy in (-2, -1, 0, 1, 2):
                for i in cells.get((cx + dx, cy + dy), ()):
                    if (seg_dist(q, p[i], p[(i + 1) % N]) <= margin or
                            seg_dist(q, p[i - 1], p[i]) <= margin):
                        near = True
                        break
                if near:
                    break
            if near:
                break
        if near:
            continue
        far += 1
        t = math.atan2(q[1] - CY, q[0] - CX) % (2 * math.pi)
        i = min(int(t / (2 * math.pi) * N), N - 1)
        a, b = p[i], p[(i + 1) % N]
        inside = (b[0] - a[0]) * (q[1] - a[1]) - (b[1] - a[1]) * (q[0] - a[0]) > 0
        bad += inside != (dq < 0)
    print("%d sign errors at %d of %d vertices farther than %g from the curve"
          % (bad, far, nv, margin))
    return bad == 0 and far > 1000


if __name__ == "__main__":
    if sys.argv[1] == "write":
        write(sys.argv[2], float(sys.argv[3]), float(sys.argv[4]), int(sys.argv[5]))
    else:
        sys.exit(0 if check(sys.argv[2], sys.argv[3], float(sys.argv[4])) else 1)
