"""Templates meshed from a surface or a label map from Python (issue 34):
match(template_surface=PATH) against `shapematch run --template-surface`
(the same meshed template and result), the surface as arrays against the
same surface as a file, template_image with template_label, and the
refusals (an open surface: the defect named; two templates)."""
import json
import os
import shutil
import subprocess
import sys
import tempfile
import unittest

import numpy as np

import test_shapematch as base
import shapematch

CHECK = os.path.join(base.ROOT, "tests", "cli", "template_mesh_check.py")
V = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], float)
F = np.array([(0, 2, 4), (2, 1, 4), (1, 3, 4), (3, 0, 4), (2, 0, 5), (1, 2, 5), (3, 1, 5),
              (0, 3, 5)])
KW = dict(max_iter=4, solver="amg")
CASE = {}


def setUpModule():
    tmp = tempfile.mkdtemp(prefix="sm-py-template-")
    CASE["tmp"] = tmp
    with open(os.path.join(tmp, "octa.off"), "w") as f:
        f.write("OFF\n6 8 0\n")
        f.writelines("%r %r %r\n" % tuple(p) for p in V)
        f.writelines("3 %d %d %d\n" % tuple(t) for t in F)
    # the target: the octahedron stretched and moved
    with open(os.path.join(tmp, "target.off"), "w") as f:
        f.write("OFF\n6 8 0\n")
        f.writelines("%r %r %r\n" % (1.1 * p[0] + 0.05, p[1], 0.95 * p[2]) for p in V)
        f.writelines("3 %d %d %d\n" % tuple(t) for t in F)
    subprocess.run([sys.executable, CHECK, "label", os.path.join(tmp, "lab.nii.gz")], check=True)


def tearDownModule():
    shutil.rmtree(CASE["tmp"], ignore_errors=True)


def path(name):
    return os.path.join(CASE["tmp"], name)


class TemplateSurface(unittest.TestCase):
    def test_path_as_cli(self):
        """match(template_surface=path) meshes as `run --template-surface` and gives its result"""
        r = shapematch.match(template_surface=path("octa.off"), target_surface=path("target.off"),
                             template_size=0.3, **KW)
        out = path("cli")
        subprocess.run([os.path.join(base.BIN, "shapematch"), "run", "--template-surface", path("octa.off"),
                        "--target-surface", path("target.off"), "--template-size", "0.3",
                        "--max-iter", "4", "--solver", "amg", "-q", "-o", out],
                       check=True, stderr=subprocess.DEVNULL)
        with open(os.path.join(out, "summary.json")) as f:
            cli = json.load(f)
        m = r.summary["template"]["meshed"]
        self.assertEqual(m["elements"], cli["template"]["meshed"]["elements"])
        self.assertEqual(r.summary["inverted_elements"], 0)
        self.assertAlmostEqual(m["volume"], 4.0 / 3.0, places=12)  # the octahedron's, exact
        self.assertEqual(r.summary["boundary_rms"], cli["boundary_rms"])
        self.assertIn("clamp-default", [w["code"] for w in r.warnings])
        r.write(path("py"))
        self.assertTrue(os.path.exists(path("py/template.mesh")))

    def test_arrays_as_file(self):
        """template_surface=(vertices, facets) gives the file's template and result"""
        a = shapematch.match(template_surface=(V, F), target_surface=path("target.off"),
                             template_size=0.3, **KW)
        b = shapematch.match(template_surface=path("octa.off"), target_surface=path("target.off"),
                             template_size=0.3, **KW)
        self.assertEqual(a.summary["template"]["meshed"]["elements"],
                         b.summary["template"]["meshed"]["elements"])
        self.assertTrue(np.array_equal(a.vertices, b.vertices))

    def test_image(self):
        """template_image with template_label: the label meshed at the voxel size"""
        r = shapematch.match(template_image=path("lab.nii.gz"), template_label=1,
                             target_surface=path("target.off"), max_iter=1, solver="amg")
        m = r.summary["template"]["meshed"]
        self.assertEqual((m["from"], m["label"], m["size"]), ("image", 1, 1.5))

    def test_refusals(self):
        """an open surface names the defect; two templates are refused"""
        with self.assertRaises(shapematch.ShapematchError) as c:
            shapematch.match(template_surface=(V, F[1:]), target_surface=path("target.off"))
        self.assertIn("open: 3 edges", str(c.exception))
        with self.assertRaises(TypeError):
            shapematch.match(path("octa.off"), template_surface=(V, F),
                             target_surface=path("target.off"))


if __name__ == "__main__":
    unittest.main()
