#!/usr/bin/env python3
"""Why the 2D example's exact figure is 4x its boundary_rms (issue 33).

Usage: chord_check.py RESULT_DIR BACKGROUND.mesh[.gz] BACKGROUND.sol[.gz]

Independently of shapematch, on the result's boundary polygon:
  - the exact distance to the field's zero level set (marching triangles
    here, in numpy) over dense samples of every edge: must agree with the
    summary's result_to_target RMS within 5% (the measurement is right);
  - the exact distance to the analytic star r = 0.25 (1 + 0.2 cos 5t)
    (examples/README.md) over the same samples, and at the two Gauss
    points of every edge: the latter must agree with boundary_rms within
    10% (J's figure samples where a chord crosses the curve);
  - the chord error of the best polygon with the result's edges on the
    star, kappa h^2 / (2 sqrt 180) per edge (the L2-best offset of a chord
    of length h on a curve of curvature kappa): the dense exact RMS must
    be within 25% of it, i.e. the result is as close as a polygon of its
    edges can be and the remaining gap is the template's resolution.
Prints the figures; exit 1 when a check fails."""
import gzip, json, sys
import numpy as np
from scipy.spatial import cKDTree


def tokens(path):
    op = gzip.open if path.endswith(".gz") else open
    with op(path, "rt") as f:
        return f.read().split()


def read_mesh(path):
    tk = tokens(path)
    i = tk.index("Vertices")
    n = int(tk[i + 1])
    v = np.array(tk[i + 2:i + 2 + 3 * n], float).reshape(n, 3)[:, :2]
    i = tk.index("Triangles")
    m = int(tk[i + 1])
    t = np.array(tk[i + 2:i + 2 + 4 * m], int).reshape(m, 4)[:, :3] - 1
    return v, t


def read_sol(path, n):
    tk = tokens(path)
    i = tk.index("SolAtVertices")
    return np.array(tk[i + 4:i + 4 + n], float)


def segment_distance(p, a, b, tree, k=16):
    """Exact distance from points p to the union of segments a-b: the k
    segments of nearest midpoints, point-to-segment each."""
    _, idx = tree.query(p, k=k)
    pa, ab = p[:, None, :] - a[idx], (b - a)[idx]
    t = np.clip((pa * ab).sum(2) / np.maximum((ab * ab).sum(2), 1e-300), 0, 1)
    return np.sqrt(((pa - t[..., None] * ab) ** 2).sum(2)).min(1)


def level_set(v, t, d):
    """The zero level set of the P1 field d as segments (marching triangles)."""
    a, b = [], []
    for tri in t:
        s = d[tri]
        if (s > 0).all() or (s < 0).all():
            continue
        pts = []
        for i, j in ((0, 1), (1, 2), (2, 0)):
            di, dj = s[i], s[j]
            if (di < 0) != (dj < 0):
                w = di / (di - dj)
                pts.append(v[tri[i]] + w * (v[tri[j]] - v[tri[i]]))
        if len(pts) == 2:
            a.append(pts[0]), b.append(pts[1])
    return np.array(a), np.array(b)


def main():
    res, bgm, bgs = sys.argv[1:4]
    s = json.load(open(res + "/summary.json"))
    v, t = read_mesh(res + "/result.mesh")
    e = np.sort(np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]]), 1)
    u, c = np.unique(e, axis=0, return_counts=True)
    edges = u[c == 1]
    p0, p1 = v[edges[:, 0]], v[edges[:, 1]]
    length = np.linalg.norm(p1 - p0, axis=1)
    ns = 64
    tt = (np.arange(ns) + 0.5) / ns
    dense = (p0[:, None] * (1 - tt)[None, :, None] + p1[:, None] * tt[None, :, None]).reshape(-1, 2)
    w = np.repeat(length / ns, ns)
    rms = lambda d, w: float(np.sqrt((w * d * d).sum() / w.sum()))

    bv, bt = read_mesh(bgm)
    a, b = level_set(bv, bt, read_sol(bgs, len(bv)))
    d_ls = segment_distance(dense, a, b, cKDTree((a + b) / 2))
    theta = np.linspace(0, 2 * np.pi, 2_000_001)[:-1]
    r = 0.25 * (1 + 0.2 * np.cos(5 * theta))
    star = np.c_[0.5 + r * np.cos(theta), 0.5 + r * np.sin(theta)]
    sa, sb = star, np.roll(star, -1, axis=0)
    stree = cKDTree((sa + sb) / 2)
    d_star = segment_distance(dense, sa, sb, stree, k=4)
    g = np.array([0.5 - 0.5 / np.sqrt(3), 0.5 + 0.5 / np.sqrt(3)])
    gauss = (p0[:, None] * (1 - g)[None, :, None] + p1[:, None] * g[None, :, None]).reshape(-1, 2)
    d_gauss = segment_distance(gauss, sa, sb, stree, k=4)
    # curvature of the polar curve at each edge's midpoint
    th = np.arctan2(*((p0 + p1) / 2 - 0.5).T[::-1])
    r, r1, r2 = (0.25 * (1 + 0.2 * np.cos(5 * th)), -0.25 * np.sin(5 * th),
                 -1.25 * np.cos(5 * th))
    kappa = np.abs(r * r + 2 * r1 * r1 - r * r2) / (r * r + r1 * r1) ** 1.5
    chord = kappa * length ** 2 / (2 * np.sqrt(180))

    ours = s["distance"]["result_to_target"]["rms"]
    figs = dict(summary_rms=ours, level_set_rms=rms(d_ls, w), star_rms=rms(d_star, w),
                star_gauss_rms=float(np.sqrt((d_gauss ** 2).mean())),
                boundary_rms=s["boundary_rms"], chord_floor_rms=rms(chord, length),
                edges=len(edges), edge_mean=float(length.mean()))
    print(" ".join("%s %.3g" % kv for kv in figs.items()))
    ok = (abs(ours / figs["level_set_rms"] - 1) < 0.05
          and abs(figs["star_gauss_rms"] / figs["boundary_rms"] - 1) < 0.10
          and abs(figs["star_rms"] / figs["chord_floor_rms"] - 1) < 0.25)
    sys.exit(0 if ok else 1)


main()
