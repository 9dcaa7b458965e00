"""An independent check of summary.json's two-sided distance (issue 33):
numpy reads the result mesh and the target (an STL, or a background mesh
and its .sol, whose zero level set it extracts itself by marching
tetrahedra), samples both surfaces its own way (every triangle cut into
16 equal parts, one sample at each part's centroid weighted by its area;
the vertices count toward the max, and the facets near the max are
sampled 256 times for it) and finds every exact point-triangle
distance by a pruned brute force (scipy's k-d tree over the triangles'
centroids only bounds which triangles can be nearest: each point is
measured against every triangle whose centroid lies within its distance
to the nearest centroid plus the largest triangle radius).

  python3 coverage_check.py RESULT_DIR (--stl T.stl | --field BG.mesh BG.sol)

Prints one line per figure, "name ours theirs", and exits 1 when a figure
differs by more than 5% (or by more than 1e-9 when both are below it).
"""
import json
import struct
import sys

import numpy as np
from scipy.spatial import cKDTree


def tokens(path):
    with open(path) as f:
        for line in f:
            yield from line.split("#", 1)[0].split()


def read_medit(path):
    tk = list(tokens(path))
    verts = tets = None
    i = 0
    while i < len(tk):
        w = tk[i].lower()
        if w == "vertices":
            n = int(tk[i + 1])
            verts = np.array(tk[i + 2:i + 2 + 4 * n], float).reshape(n, 4)[:, :3]
            i += 2 + 4 * n
        elif w == "tetrahedra":
            n = int(tk[i + 1])
            tets = np.array(tk[i + 2:i + 2 + 5 * n], int).reshape(n, 5)[:, :4] - 1
            i += 2 + 5 * n
        else:
            i += 1
    return verts, tets


def read_sol(path):
    tk = list(tokens(path))
    i = [w.lower() for w in tk].index("solatvertices")
    n = int(tk[i + 1])
    return np.array(tk[i + 4:i + 4 + n], float)


def read_stl(path):
    data = open(path, "rb").read()
    n = struct.unpack("<I", data[80:84])[0]
    rec = np.frombuffer(data[84:84 + 50 * n], dtype=np.dtype(
        [("n", "<f4", 3), ("v", "<f4", (3, 3)), ("a", "<u2")]))
    return rec["v"].astype(float)  # (n, 3, 3)


def boundary_triangles(verts, tets):
    faces = np.concatenate([tets[:, [0, 1, 2]], tets[:, [0, 1, 3]], tets[:, [0, 2, 3]],
                            tets[:, [1, 2, 3]]])
    key = np.sort(faces, axis=1)
    _, inv, cnt = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    return verts[faces[cnt[inv.ravel()] == 1]]


def level_set(verts, tets, d):
    """Marching tetrahedra on the P1 field d: the zero set's triangles."""
    tris = []
    s = d[tets] < 0
    for t, sg in zip(tets, s):
        neg, pos = t[sg], t[~sg]
        if len(neg) == 0 or len(pos) == 0:
            continue

        def cut(a, b):
            u = d[a] / (d[a] - d[b])
            return verts[a] + u * (verts[b] - verts[a])
        if len(neg) == 1 or len(pos) == 1:
            lone, other = (neg[0], pos) if len(neg) == 1 else (pos[0], neg)
            tris.append([cut(lone, o) for o in other])
        else:
            q = [cut(neg[0], pos[0]), cut(neg[0], pos[1]), cut(neg[1], pos[1]), cut(neg[1], pos[0])]
            tris.append([q[0], q[1], q[2]])
            tris.append([q[2], q[3], q[0]])
    return np.array(tris)


def samples(tris, k=4):
    """Centroids of the k*k parts of every triangle, with their areas."""
    bary = []
    for i in range(k):
        for j in range(k - i):
            bary.append(((i + 1 / 3) / k, (j + 1 / 3) / k))
            if i + j < k - 1:
                bary.append(((i + 2 / 3) / k, (j + 2 / 3) / k))
    b = np.array(bary)
    a, e1, e2 = tris[:, 0], tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]
    pts = a[:, None, :] + b[None, :, 0, None] * e1[:, None, :] + b[None, :, 1, None] * e2[:, None, :]
    area = 0.5 * np.linalg.norm(np.cross(e1, e2), axis=1)
    w = np.repeat(area / len(b), len(b))
    return pts.reshape(-1, 3), w


def point_triangle(p, tri):
    """Exact distances from points p (n, 3) to triangles tri (n, 3, 3)."""
    a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
    e0, e1 = b - a, c - a
    n = np.cross(e0, e1)
    nn = np.einsum("ij,ij->i", n, n)
    ok = nn > 1e-300
    # the plane's foot and its barycentric coordinates
    t = np.where(ok, np.einsum("ij,ij->i", p - a, n) / np.where(ok, nn, 1), 0)
    q = p - t[:, None] * n
    v0, v1, v2 = e0, e1, q - a
    d00 = np.einsum("ij,ij->i", v0, v0)
    d01 = np.einsum("ij,ij->i", v0, v1)
    d11 = np.einsum("ij,ij->i", v1, v1)
    d20 = np.einsum("ij,ij->i", v2, v0)
    d21 = np.einsum("ij,ij->i", v2, v1)
    den = d00 * d11 - d01 * d01
    den = np.where(np.abs(den) > 1e-300, den, 1)
    bv = (d11 * d20 - d01 * d21) / den
    bw = (d00 * d21 - d01 * d20) / den
    inside = ok & (bv >= 0) & (bw >= 0) & (bv + bw <= 1)
    best = np.where(inside, np.linalg.norm(p - q, axis=1), np.inf)
    for s0, s1 in ((a, b), (b, c), (a, c)):
        e = s1 - s0
        ee = np.einsum("ij,ij->i", e, e)
        u = np.clip(np.einsum("ij,ij->i", p - s0, e) / np.where(ee > 0, ee, 1), 0, 1)
        best = np.minimum(best, np.linalg.norm(p - (s0 + u[:, None] * e), axis=1))
    return best


def distances(points, tris, k=24):
    """Exact distance from each point to the nearest of tris: measured
    against the k triangles of nearest centroids, which hold the nearest
    triangle whenever the k-th centroid is farther than the distance found
    plus the largest triangle radius (no other triangle can be nearer);
    the other points against every triangle within that bound."""
    cent = tris.mean(axis=1)
    radius = np.linalg.norm(tris - cent[:, None, :], axis=2).max()
    tree = cKDTree(cent)
    k = min(k, len(tris))
    cd, ci = tree.query(points, k=k)
    cd, ci = cd.reshape(len(points), k), ci.reshape(len(points), k)
    d = point_triangle(np.repeat(points, k, axis=0), tris[ci.ravel()]).reshape(len(points), k).min(axis=1)
    for i in np.nonzero(cd[:, -1] <= d + radius)[0]:
        cand = tree.query_ball_point(points[i], d[i] + radius + 1e-12)
        d[i] = point_triangle(np.repeat(points[i][None, :], len(cand), axis=0), tris[cand]).min()
    return d


def figures(pts, w, extra_pts, tris, facets, k=4):
    """rms, mean, p99 over the samples; the max over the samples, the
    vertices and, on the facets whose samples come within 80% of it,
    samples 4 times finer per side (the max is often inside a facet)."""
    d = distances(pts, tris)
    dv = distances(extra_pts, tris)
    order = np.argsort(d)
    cum = np.cumsum(w[order])
    p99 = d[order][np.searchsorted(cum, 0.99 * cum[-1])]
    mx = max(d.max(), dv.max())
    per = d.reshape(len(facets), k * k).max(axis=1)
    near = facets[per >= 0.8 * mx]
    if len(near):
        fp, _ = samples(near, 4 * k)
        mx = max(mx, distances(fp, tris).max())
    return {"rms": float(np.sqrt(np.sum(w * d * d) / np.sum(w))), "mean": float(np.sum(w * d) / np.sum(w)),
            "max": float(mx), "p99": float(p99)}


def main():
    out = sys.argv[1]
    verts, tets = read_medit(out + "/result.mesh")
    res = boundary_triangles(verts, tets)
    if sys.argv[2] == "--stl":
        target = read_stl(sys.argv[3])
    else:
        bv, bt = read_medit(sys.argv[3])
        target = level_set(bv, bt, read_sol(sys.argv[4]))
    s = json.load(open(out + "/summary.json"))["distance"]
    rp, rw = samples(res)
    tp, tw = samples(target)
    theirs = {"result_to_target": figures(rp, rw, res.reshape(-1, 3), target, res),
              "target_to_result": figures(tp, tw, target.reshape(-1, 3), res, target)}
    bad = 0
    for side, names in (("result_to_target", ("rms", "max", "mean")),
                        ("target_to_result", ("rms", "max", "mean", "p99"))):
        for n in names:
            a, b = s[side][n], theirs[side][n]
            good = a is not None and (abs(a - b) <= 0.05 * max(abs(a), abs(b)) or max(abs(a), abs(b)) < 1e-9)
            bad += not good
            print("%s.%s %.6g %.6g%s" % (side, n, a if a is not None else float("nan"), b, "" if good else " BAD"))
    print("method", s["method"])
    sys.exit(1 if bad else 0)


if __name__ == "__main__":
    main()
