"""Inputs and independent checks for tests/cli/batch.sh (numpy).

  batch_check.py ellipse OUT.mesh A B
      a closed polyline of 400 vertices on the ellipse of semi-axes A, B
      about (0.5, 0.5), as Medit Edges (a 2D target surface)
  batch_check.py model BATCH_DIR PARAMS
      PARAMS: name:a:b,...  Reads each target's result.mesh, does its own
      rigid generalized Procrustes (numpy SVD), PCA (numpy SVD of the
      centred data) and leave-one-out generalization, and compares them
      with BATCH_DIR/model (variances, |scores|, mean.mesh, mode_1.sol up
      to sign, compactness, generalization); then checks that the first two
      modes carry >= 95% of the variance and that the first two scores
      predict a and b linearly (numpy lstsq, R^2 >= 0.98).
  batch_check.py move SRC.mesh DST.mesh ANGLE TX TY
      the mesh rotated by ANGLE (radians) about the origin and translated
  batch_check.py same MODEL_A MODEL_B
      the two models' variances and |scores| agree to 1e-9 (relative)
Prints one line per failed check on stdout; exits 1 if any."""
import json
import math
import os
import sys

import numpy as np


def read_mesh(path):
    """(vertices (n x 2), the lines of the file) of a 2D ASCII Medit mesh."""
    with open(path) as f:
        lines = f.read().split("\n")
    for i, line in enumerate(lines):
        if line.strip() == "Vertices":
            n = int(lines[i + 1])
            v = np.array([[float(t) for t in lines[i + 2 + k].split()[:2]] for k in range(n)])
            return v, lines, i + 2
    raise SystemExit("no Vertices in " + path)


def read_sol(path):
    with open(path) as f:
        tok = f.read().split()
    i = tok.index("SolAtVertices")
    n = int(tok[i + 1])
    return np.array([float(t) for t in tok[i + 4:i + 4 + 2 * n]]).reshape(n, 2)


def ellipse(out, a, b, n=400):
    with open(out, "w") as f:
        f.write("MeshVersionFormatted 2\nDimension 2\nVertices\n%d\n" % n)
        for i in range(n):
            t = 2 * math.pi * i / n
            f.write("%.17g %.17g 0\n" % (0.5 + a * math.cos(t), 0.5 + b * math.sin(t)))
        f.write("Edges\n%d\n" % n)
        f.writelines("%d %d 1\n" % (i + 1, (i + 1) % n + 1) for i in range(n))
        f.write("End\n")


def kabsch(x, r):
    cx, cr = x.mean(0), r.mean(0)
    u, _, vt = np.linalg.svd((x - cx).T @ (r - cr))
    d = np.sign(np.linalg.det(vt.T @ u.T))
    rot = vt.T @ np.diag([1.0, d]) @ u.T
    return (x - cx) @ rot.T + cr


def gpa(shapes):
    ref = shapes[0]
    for _ in range(200):
        mean = np.mean([kabsch(s, ref) for s in shapes], 0)
        done = np.abs(mean - ref).max() < 1e-13
        ref = mean
        if done:
            break
    ref = kabsch(ref, shapes[0])
    al = [kabsch(s, ref) for s in shapes]
    return al, np.mean(al, 0)


def model(bdir, params):
    bad = []
    rows = [p.split(":") for p in params.split(",")]
    names = [r[0] for r in rows]
    ab = np.array([[float(r[1]), float(r[2])] for r in rows])
    shapes = [read_mesh("%s/targets/%s/result.mesh" % (bdir, nm))[0] for nm in names]
    al, mean = gpa(shapes)
    x = np.array([a.ravel() - mean.ravel() for a in al])
    n = len(shapes)
    u, s, vt = np.linalg.svd(x, full_matrices=False)
    var = s ** 2 / (n - 1)
    summ = json.load(open(bdir + "/model/summary.json"))
    k = summ["modes"]
    mv = np.array(summ["variance"])
    if abs(var[:k] - mv).max() > 1e-9 * var[0]:
        bad.append("variances differ from numpy's: %s vs %s" % (mv, var[:k]))
    with open(bdir + "/model/scores.csv") as f:
        head = f.readline().strip().split(",")
        sc = {}
        for line in f:
            t = line.strip().split(",")
            sc[t[0]] = [float(v) for v in t[1:]]
    if head != ["target"] + ["mode%d" % (i + 1) for i in range(k)]:
        bad.append("scores.csv header %s" % head)
    scores = np.array([sc[nm] for nm in names])
    ref = u[:, :k] * s[:k]
    if abs(abs(scores) - abs(ref)).max() > 1e-8 * s[0]:
        bad.append("|scores| differ from numpy's by %g" % abs(abs(scores) - abs(ref)).max())
    mm = read_mesh(bdir + "/model/mean.mesh")[0]
    if abs(mm - mean).max() > 1e-12:
        bad.append("mean.mesh differs from numpy's mean by %g" % abs(mm - mean).max())
    m1 = read_sol(bdir + "/model/mode_1.sol").ravel()
    e1 = vt[0] * s[0] / math.sqrt(n - 1)
    if min(abs(m1 - e1).max(), abs(m1 + e1).max()) > 1e-9 * abs(e1).max():
        bad.append("mode_1.sol is not sqrt(lambda_1) u_1")
    # modes.vtu through the suites' own reader (tests/lib/vtu.py): the mean
    # as points, mode1.. as mode_K.sol, padded to 3D
    sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "lib"))
    import vtu
    _, arr = vtu.read(bdir + "/model/modes.vtu")
    pts = np.array(arr["Points"]).reshape(-1, 3)
    if abs(pts[:, :2] - mm).max() > 0 or abs(pts[:, 2]).max() > 0:
        bad.append("modes.vtu's points are not mean.mesh's")
    for kk in range(1, summ["modes_written"] + 1):
        f = np.array(arr.get("mode%d" % kk, [])).reshape(-1, 3)
        sol = read_sol(bdir + "/model/mode_%d.sol" % kk)
        if f.shape != (len(sol), 3) or abs(f[:, :2] - sol).max() > 0 or abs(f[:, 2]).max() > 0:
            bad.append("modes.vtu's mode%d is not mode_%d.sol" % (kk, kk))
    comp = np.cumsum(var) / var.sum()
    if abs(np.array(summ["compactness"]) - comp[:len(summ["compactness"])]).max() > 1e-12:
        bad.append("compactness differs from numpy's")
    gen = []
    for m in range(1, len(summ["generalization"]) + 1):
        tot = 0.0
        for i in range(n):
            o = np.delete(x, i, 0)
            mo = o.mean(0)
            _, sv, w = np.linalg.svd(o - mo, full_matrices=False)
            w = w[:min(m, int((sv > 1e-9 * sv[0]).sum()))]  # the others' modes
            r = x[i] - mo
            r = r - w.T @ (w @ r)
            tot += np.linalg.norm(r.reshape(-1, 2), axis=1).mean()
        gen.append(tot / n)
    if abs(np.array(summ["generalization"]) - gen).max() > 1e-9 * max(gen):
        bad.append("generalization %s vs numpy's %s" % (summ["generalization"], gen))
    # specificity: the library's generator (xorshift64*, Box-Muller) redone
    # here, the samples built in R^P and their nearest shape found by brute
    # force; mode signs taken from the scores
    sign = np.sign((scores * ref).sum(0))
    ev = summ["evaluation"]
    state = [ev["seed"]]
    mask = (1 << 64) - 1

    def uniform():
        x = state[0]
        x ^= x >> 12
        x ^= (x << 25) & mask
        x ^= x >> 27
        state[0] = x
        return (((x * 0x2545F4914F6CDD1D) & mask) >> 11) * 2.0 ** -53 + 0.5 * 2.0 ** -53

    def normal():
        u, v = uniform(), uniform()
        return math.sqrt(-2 * math.log(u)) * math.cos(6.283185307179586 * v)

    e = ev["modes"]
    modes = (vt[:e].T * sign[:e]).T
    spec = np.zeros(e)
    for _ in range(ev["samples"]):
        bb = [normal() * math.sqrt(mv[k]) for k in range(e)]
        smp = np.zeros(x.shape[1])
        for k in range(e):
            smp += bb[k] * modes[k]
            near = x[np.argmin(((x - smp) ** 2).sum(1))]
            spec[k] += np.linalg.norm((smp - near).reshape(-1, 2), axis=1).mean()
    spec /= ev["samples"]
    if abs(np.array(summ["specificity"]) - spec).max() > 1e-9 * spec.max():
        bad.append("specificity %s vs numpy's %s" % (summ["specificity"], spec))
    if comp[1] < 0.95:
        bad.append("the first two modes carry %.4f of the variance (< 0.95)" % comp[1])
    a = np.c_[scores[:, :2], np.ones(n)]
    for j, pname in enumerate("ab"):
        c = np.linalg.lstsq(a, ab[:, j], rcond=None)[0]
        res = ((a @ c - ab[:, j]) ** 2).sum() / ((ab[:, j] - ab[:, j].mean()) ** 2).sum()
        if 1 - res < 0.98:
            bad.append("scores predict %s with R^2 %.4f (< 0.98)" % (pname, 1 - res))
    return bad


def move(src, dst, ang, tx, ty):
    v, lines, at = read_mesh(src)
    c, s = math.cos(ang), math.sin(ang)
    for k, (x, y) in enumerate(v):
        rest = lines[at + k].split()[2:]
        lines[at + k] = "%.17g %.17g %s" % (c * x - s * y + tx, s * x + c * y + ty, " ".join(rest))
    with open(dst, "w") as f:
        f.write("\n".join(lines))
    return []


def same(a, b):
    sa, sb = json.load(open(a + "/summary.json")), json.load(open(b + "/summary.json"))
    va, vb = np.array(sa["variance"]), np.array(sb["variance"])
    bad = []
    if va.shape != vb.shape or abs(va - vb).max() > 1e-9 * va[0]:
        bad.append("variances differ: %s vs %s" % (va, vb))
    ca = np.loadtxt(a + "/scores.csv", delimiter=",", skiprows=1, usecols=range(1, len(va) + 1))
    cb = np.loadtxt(b + "/scores.csv", delimiter=",", skiprows=1, usecols=range(1, len(vb) + 1))
    if abs(abs(ca) - abs(cb)).max() > 1e-9 * math.sqrt(va[0]):
        bad.append("|scores| differ by %g" % abs(abs(ca) - abs(cb)).max())
    return bad


def main():
    cmd = sys.argv[1]
    if cmd == "ellipse":
        ellipse(sys.argv[2], float(sys.argv[3]), float(sys.argv[4]))
        return 0
    if cmd == "model":
        bad = model(sys.argv[2], sys.argv[3])
    elif cmd == "move":
        bad = move(sys.argv[2], sys.argv[3], *map(float, sys.argv[4:7]))
    else:
        bad = same(sys.argv[2], sys.argv[3])
    for b in bad:
        print(b)
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
