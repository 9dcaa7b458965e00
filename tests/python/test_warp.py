"""shapematch.warp against `shapematch warp` (the same files byte for byte,
the same points bit for bit) and against an exact affine map (result
folders made by tests/cli/warp_check.py: result = A x + b at every
template vertex, so the piecewise-linear map is that affine map
everywhere, outside points included)."""
import math
import os
import random
import shutil
import subprocess
import sys
import tempfile
import unittest

ROOT = os.environ.get("SM_ROOT", os.path.abspath(os.path.join(os.path.dirname(__file__), "..", "..")))
BIN = os.environ.get("SM_BIN", os.path.join(ROOT, "build", "release"))
sys.path.insert(0, os.path.join(ROOT, "python"))
os.environ.setdefault("SHAPEMATCH_LIBDIR", BIN)
import shapematch  # noqa: E402

CHECK = os.path.join(ROOT, "tests", "cli", "warp_check.py")
sys.path.insert(0, os.path.dirname(CHECK))
import warp_check  # noqa: E402  (A, B, the tensor helpers)

TEMPLATES = {2: os.path.join(ROOT, "examples", "2d", "template.mesh"),
             3: os.path.join(ROOT, "examples", "3d", "template.mesh")}


def affine(x):
    d = len(x)
    return [warp_check.B[i] + sum(warp_check.A[i][k] * x[k] for k in range(d)) for i in range(d)]


def rows(a):
    return [list(r) for r in (a.tolist() if hasattr(a, "tolist") else a)]


class Warp(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.tmp = tempfile.mkdtemp(prefix="sm-pywarp-")
        cls.dirs = {}
        # 2D (the 3D cases are the CLI's, tests/cli/warp.sh): the same code
        for dim, tmpl in ((2, TEMPLATES[2]),):
            d = os.path.join(cls.tmp, "%dd" % dim)
            os.makedirs(d)
            subprocess.run([sys.executable, CHECK, "make", tmpl, d, "affine"], check=True)
            cls.dirs[dim] = d
        r = random.Random(5)
        # inside and outside the disk (radius 0.25) and the ball (0.3) about 0.5
        cls.points = {2: [[r.uniform(0.1, 0.9) for _ in range(2)] for _ in range(300)]}

    @classmethod
    def tearDownClass(cls):
        shutil.rmtree(cls.tmp, ignore_errors=True)

    def cli(self, *args):
        subprocess.run([os.path.join(BIN, "shapematch"), "warp", "-q"] + list(args), check=True)

    def test_points_as_the_cli_and_exact(self):
        for dim in (2,):
            d, pts = self.dirs[dim], self.points[dim]
            csv = os.path.join(self.tmp, "p%d.csv" % dim)
            with open(csv, "w") as f:
                f.write("".join(",".join("%.17g" % c for c in p) + "\n" for p in pts))
            self.cli("--result", d, "--points", csv, "-o", csv + ".out")
            with open(csv + ".out") as f:
                cli = [list(map(float, line.split(","))) for line in f.read().split()[1:]]
            out, inside = shapematch.warp(d, points=pts)
            out, inside = rows(out), list(inside.tolist() if hasattr(inside, "tolist") else inside)
            self.assertEqual(out, [c[:dim] for c in cli], "%dD: the CLI's points" % dim)
            self.assertEqual(inside, [int(c[dim]) for c in cli])
            self.assertTrue(0 < sum(inside) < len(pts), "inside and outside points")
            worst = max(math.dist(y, affine(x)) for x, y in zip(pts, out))
            self.assertLess(worst, 1e-12, "%dD: A x + b, outside points included" % dim)
            back, _ = shapematch.warp(d, points=out, inverse=True)
            worst = max(math.dist(x, y) for x, y in zip(pts, rows(back)))
            self.assertLess(worst, 1e-12, "%dD: inverse(forward(x)) = x" % dim)

    def test_strict(self):
        with self.assertRaises(shapematch.ShapematchError) as e:
            shapematch.warp(self.dirs[2], points=[[0.5, 0.5], [5, 5]], strict=True)
        self.assertIn("point 2 is outside the template", str(e.exception))
        self.assertEqual(e.exception.status, "invalid")

    def test_outside(self):
        """outside="flag": NaN rows where inside is 0, the rest as
        extrapolated; "skip": the inside rows only, inside one flag per
        point given; the CLI's --outside the same numbers."""
        d, pts = self.dirs[2], self.points[2]
        ref, inside = shapematch.warp(d, points=pts)
        ref, inside = rows(ref), list(inside.tolist() if hasattr(inside, "tolist") else inside)
        self.assertTrue(0 < sum(inside) < len(pts))
        flagged, fin = shapematch.warp(d, points=pts, outside="flag")
        for r, f, i in zip(ref, rows(flagged), inside):
            if i:
                self.assertEqual(f, r)
            else:
                self.assertTrue(all(math.isnan(c) for c in f))
        kept, kin = shapematch.warp(d, points=pts, outside="skip")
        self.assertEqual(list(kin.tolist() if hasattr(kin, "tolist") else kin), inside)
        self.assertEqual(rows(kept), [r for r, i in zip(ref, inside) if i])
        csv = os.path.join(self.tmp, "skip.csv")
        with open(csv, "w") as f:
            f.write("".join(",".join("%.17g" % c for c in p) + "\n" for p in pts))
        self.cli("--result", d, "--points", csv, "--outside", "skip", "-o", csv + ".out")
        with open(csv + ".out") as f:
            cli = [list(map(float, line.split(",")))[:2] for line in f.read().split()[1:]]
        self.assertEqual(cli, rows(kept))
        with self.assertRaises(ValueError):
            shapematch.warp(d, points=pts, outside="nearest")
        with self.assertRaises(TypeError):
            shapematch.warp(d, points=pts, outside="skip", strict=True)

    def test_mesh_files_as_the_cli(self):
        d, tmpl = self.dirs[2], TEMPLATES[2]
        for ext in ("mesh", "vtu"):
            mine = os.path.join(self.tmp, "py." + ext)
            theirs = os.path.join(self.tmp, "cli." + ext)
            v = shapematch.warp(d, mesh=tmpl, output=mine)
            self.cli("--result", d, "--mesh", tmpl, "-o", theirs)
            with open(mine, "rb") as a, open(theirs, "rb") as b:
                self.assertEqual(a.read(), b.read(), ext)
        ref = warp_check.read_medit(tmpl)[1]
        self.assertLess(max(math.dist(y, affine(x)) for x, y in zip(ref, rows(v))), 1e-12)
        # arrays: the vertices moved, the same numbers
        v2 = shapematch.warp(d, mesh=(ref, [[0, 1, 2]]))
        self.assertEqual(rows(v2), rows(v))

    def test_tensor_field_as_the_cli_and_analytic(self):
        for dim in (2,):
            d, tmpl = self.dirs[dim], TEMPLATES[dim]
            t = os.path.join(self.tmp, "T%d.sol" % dim)
            warp_check.cmd_tensor_make(tmpl, t)
            mine, theirs = t + ".py.sol", t + ".cli.sol"
            vals = shapematch.warp(d, field=t, output=mine)
            self.cli("--result", d, "--field", t, "-o", theirs)
            with open(mine, "rb") as a, open(theirs, "rb") as b:
                self.assertEqual(a.read(), b.read())
            warp_check.cmd_tensor_check(tmpl, mine, "affine")  # exits on a mismatch
            # arrays in: the same values; back with inverse: T again
            back = shapematch.warp(d, field=vals, inverse=True)
            warp_check.cmd_tensor_check(tmpl, self.write_sol(back, dim), "identity")

    def write_sol(self, values, dim):
        path = os.path.join(self.tmp, "back.sol")
        r = rows(values)
        with open(path, "w") as f:
            f.write("MeshVersionFormatted 2\nDimension %d\nSolAtVertices\n%d\n1 3\n" % (dim, len(r)))
            f.write("".join(" ".join("%.17g" % c for c in row) + "\n" for row in r) + "End\n")
        return path

    def test_vector_field_normalized(self):
        d = self.dirs[2]
        nv = len(warp_check.read_medit(TEMPLATES[2])[1])
        got = rows(shapematch.warp(d, field=[[1.0, 2.0]] * nv, normalize=True))
        want = affine([1.0, 2.0])
        want = [w - b for w, b in zip(want, warp_check.B[:2])]
        n = math.sqrt(sum(w * w for w in want))
        self.assertLess(max(math.dist(g, [w / n for w in want]) for g in got), 1e-12)

    def test_a_result_object(self):
        ex = os.path.join(ROOT, "examples", "2d")
        r = shapematch.match(TEMPLATES[2], target_mesh=os.path.join(ex, "background.mesh.gz"),
                             target_sol=os.path.join(ex, "background.sol.gz"),
                             clamp_ball=(0.5, 0.5, 0.04), max_iter=5)
        # a template vertex goes exactly onto its result vertex
        out, inside = shapematch.warp(r, points=r.initial_vertices)
        self.assertEqual(rows(out), rows(r.vertices))
        self.assertTrue(all(inside.tolist() if hasattr(inside, "tolist") else inside))
        r.close()

    def test_errors(self):
        with self.assertRaises(TypeError):
            shapematch.warp(self.dirs[2])
        with self.assertRaises(TypeError):
            shapematch.warp(self.dirs[2], points=[[0, 0]], field=[1.0])
        with self.assertRaises(ValueError):
            shapematch.warp(self.dirs[2], points=[[0, 0, 0]])
        with self.assertRaises(shapematch.ShapematchError) as e:
            shapematch.warp(self.tmp, points=[[0, 0]])
        self.assertIn("has no result.mesh", str(e.exception))


if __name__ == "__main__":
    unittest.main()
