"""Every input of match() as arrays in memory (issue 38 item 3, issue 36
item 5: sm_run_files' in-memory members, no temporary file): the
template, the target mesh and its distance, a target surface (a 2D
circle polyline and a 3D box); each equal bit for bit to the same input
as a file (the box to 1e-14: see there), the circle's result checked against the exact circle; the
structs mirrored by ctypes checked against the C compiler's offsetof."""
import math
import os
import shutil
import subprocess
import tempfile
import unittest

from test_shapematch import BIN, CASE2, EX2, ROOT, TEMPLATE2, read_medit_block, \
    read_medit_vertices
import shapematch
from shapematch import _lib

N, R, C = 256, 0.32, (0.5, 0.5)


def circle():
    v = [(C[0] + R * math.cos(2 * math.pi * i / N), C[1] + R * math.sin(2 * math.pi * i / N))
         for i in range(N)]
    return v, [(i, (i + 1) % N) for i in range(N)]


class NoTemporaryFiles(object):
    """tempfile.mkdtemp and mkstemp raise while active: a match on arrays
    must not write any."""

    def __enter__(self):
        self.saved = tempfile.mkdtemp, tempfile.mkstemp

        def refuse(*a, **k):
            raise AssertionError("a temporary file was made")
        tempfile.mkdtemp = tempfile.mkstemp = refuse

    def __exit__(self, *exc):
        tempfile.mkdtemp, tempfile.mkstemp = self.saved


class ArraysIn(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.tmp = tempfile.mkdtemp(prefix="sm-py-inputs-")
        tv, _ = read_medit_vertices(TEMPLATE2)
        tris = read_medit_block(TEMPLATE2, "Triangles", 3)
        edges = read_medit_block(TEMPLATE2, "Edges", 2)
        cls.template = {"vertices": tv, "elements": [[a - 1, b - 1, c - 1] for a, b, c, _ in tris],
                        "element_refs": [t[3] for t in tris],
                        "facets": [[a - 1, b - 1] for a, b, _ in edges],
                        "facet_refs": [e[2] for e in edges]}
        cls.files = shapematch.match(TEMPLATE2, max_iter=15, **CASE2)

    @classmethod
    def tearDownClass(cls):
        shutil.rmtree(cls.tmp, ignore_errors=True)

    def test_every_part_of_a_sampled_target_as_arrays(self):
        """template, target_mesh and target_sol as arrays: the files' result bit for bit"""
        bg = shapematch._read_mesh(CASE2["target_mesh"])
        core = _lib.core()
        import ctypes
        sol = ctypes.POINTER(_lib.Sol)()
        err = _lib.Error()
        self.assertEqual(core.sm_sol_read(CASE2["target_sol"].encode(), ctypes.byref(sol),
                                          ctypes.byref(err)), 0)
        d = [sol.contents.values[i] for i in range(sol.contents.nverts)]
        core.sm_sol_free(sol)
        with NoTemporaryFiles():
            r = shapematch.match(self.template, target_mesh=(bg["vertices"], bg["elements"]),
                                 target_sol=d, clamp_ball=CASE2["clamp_ball"], max_iter=15)
        self.assertEqual(r.vertices.tolist(), self.files.vertices.tolist())
        self.assertEqual(r.summary["inputs"]["template"], "template (array)")
        self.assertEqual(r.summary["inputs"]["target_mesh"], "target_mesh (array)")
        self.assertEqual(r.summary["inputs"]["target_sol"], "target_sol (array)")
        # the element references reach the clamp (reference 2: the clamp disk)
        kw = {k: v for k, v in CASE2.items() if k != "clamp_ball"}
        a = shapematch.match(self.template, clamp_elements=[2], max_iter=3, **kw)
        b = shapematch.match(TEMPLATE2, clamp_elements=[2], max_iter=3, **kw)
        self.assertEqual(a.vertices.tolist(), b.vertices.tolist())

    def test_a_circle_polyline_as_arrays(self):
        """target_surface=(vertices, segments): the OBJ file's result bit for bit, on the circle"""
        v, seg = circle()
        path = os.path.join(self.tmp, "circle.obj")
        with open(path, "w") as f:
            f.writelines("v %.17g %.17g 0\n" % p for p in v)
            f.writelines("l %d %d\n" % (a + 1, b + 1) for a, b in seg)
        kw = dict(clamp_ball=(0.5, 0.5, 0.04), max_iter=60)
        with NoTemporaryFiles():
            r = shapematch.match(TEMPLATE2, target_surface=(v, seg), **kw)
        f = shapematch.match(TEMPLATE2, target_surface=path, **kw)
        self.assertEqual(r.vertices.tolist(), f.vertices.tolist())
        self.assertEqual(r.summary["inputs"]["target_surface"], "target_surface (array)")
        # the template's boundary (its vertices of the file's Edges, ref 1) on the circle
        boundary = {a - 1 for a, b, ref in read_medit_block(TEMPLATE2, "Edges", 2) if ref == 1}
        worst = max(abs(math.dist(r.vertices.tolist()[i], C) - R) for i in boundary)
        self.assertLess(worst, 1e-3)
        r2 = shapematch.match(TEMPLATE2, target_surface={"vertices": v, "faces": seg}, **kw)
        self.assertEqual(r2.vertices.tolist(), r.vertices.tolist())

    def test_a_3d_surface_as_arrays(self):
        """a box as 12 triangles: the same result as the box as an OBJ file"""
        tpl = os.path.join(ROOT, "examples", "3d", "template.mesh")
        if not os.path.exists(tpl):
            self.skipTest("no 3D template")
        lo, hi = -0.1, 1.1
        v = [(x, y, z) for z in (lo, hi) for y in (lo, hi) for x in (lo, hi)]
        quads = [(0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5)]
        tris = [t for q in quads for t in ((q[0], q[1], q[2]), (q[0], q[2], q[3]))]
        path = os.path.join(self.tmp, "box.obj")
        with open(path, "w") as f:
            f.writelines("v %r %r %r\n" % p for p in v)
            f.writelines("f %d %d %d\n" % (a + 1, b + 1, c + 1) for a, b, c in tris)
        with open(os.path.join(ROOT, "examples", "3d", "clamp")) as f:
            ball = tuple(float(x) for x in f.read().strip().split(","))
        # on the example's background: no background to generate (seconds)
        kw = dict(clamp_ball=ball, max_iter=1,
                  target_mesh=os.path.join(ROOT, "examples", "3d", "background.mesh.gz"))
        a = shapematch.match(tpl, target_surface=(v, tris), **kw)
        b = shapematch.match(tpl, target_surface=path, **kw)
        # the same surface: the same result, up to the last bit of a sum the
        # threads share (the sanitized build once differed by 1 ulp at one
        # coordinate); the other cases are bit for bit
        import numpy
        self.assertTrue(numpy.allclose(a.vertices, b.vertices, rtol=1e-14, atol=1e-14),
                        numpy.abs(a.vertices - b.vertices).max())

    def test_bad_arrays_name_the_part_and_entry(self):
        v, seg = circle()
        with self.assertRaises(shapematch.ShapematchError) as e:
            shapematch.match(TEMPLATE2, target_surface=(v, seg[:-1] + [(0, N)]),
                             clamp_ball=(0.5, 0.5, 0.04))
        self.assertIn("target_surface (array): segment %d: vertex index %d out of range" %
                      (N - 1, N), str(e.exception))
        with self.assertRaises(shapematch.ShapematchError) as e:
            shapematch.match(TEMPLATE2, target_surface=([(0, 0, 0), (1, 0, 0), (0, 1, 0)],
                                                        [(0, 1, 2)]), clamp_ball=(0.5, 0.5, 0.04))
        self.assertIn("dimension mismatch: the template is 2D but the target surface is 3D",
                      str(e.exception))
        with self.assertRaises(shapematch.ShapematchError) as e:
            shapematch.match(TEMPLATE2, target_mesh=CASE2["target_mesh"], target_sol=[0.0] * 5,
                             clamp_ball=(0.5, 0.5, 0.04))
        self.assertIn("target_sol (array): has 5 values but the target mesh", str(e.exception))
        with self.assertRaises(TypeError):
            shapematch.match(TEMPLATE2, target_surface=[[0, 1]], clamp_ball=(0.5, 0.5, 0.04))


class Layout(unittest.TestCase):
    @unittest.skipUnless(shutil.which("cc"), "no C compiler")
    def test_ctypes_structs_are_the_headers(self):
        """RunFiles, RunMesh, RunSurface: the size and every offset of the C compiler's"""
        import ctypes
        pairs = [("sm_run_files", _lib.RunFiles), ("sm_run_mesh", _lib.RunMesh),
                 ("sm_run_surface", _lib.RunSurface)]
        src = "#include <stddef.h>\n#include <stdio.h>\n#include \"shapematch_job.h\"\n" \
              "int main(void) {\n"
        want = []
        for cname, py in pairs:
            src += ' printf("%%zu\\n", sizeof(%s));\n' % cname
            want.append(ctypes.sizeof(py))
            for n, _ in py._fields_:
                src += ' printf("%%zu\\n", offsetof(%s, %s));\n' % (cname, n)
                want.append(getattr(py, n).offset)
        src += "}\n"
        d = tempfile.mkdtemp(prefix="sm-py-layout-")
        try:
            with open(os.path.join(d, "l.c"), "w") as f:
                f.write(src)
            exe = os.path.join(d, "l")
            subprocess.run(["cc", "-std=c11", "-I", os.path.join(ROOT, "proto", "job"), "-I",
                            os.path.join(ROOT, "core", "include"), "-o", exe,
                            os.path.join(d, "l.c")], check=True)
            got = [int(x) for x in subprocess.run([exe], check=True, capture_output=True,
                                                  text=True).stdout.split()]
        finally:
            shutil.rmtree(d, ignore_errors=True)
        self.assertEqual(got, want)


class VersionAndHelp(unittest.TestCase):
    def test_version_is_the_makefiles(self):
        """shapematch.__version__: the VERSION line of the Makefile"""
        with open(os.path.join(ROOT, "Makefile")) as f:
            line = [x for x in f if x.startswith("VERSION :=")][0]
        self.assertEqual(shapematch.__version__, line.split(":=")[1].strip())

    def test_help_documents_every_public_name(self):
        """help(shapematch): every name of __all__ and every public method
        has a docstring"""
        import inspect
        import pydoc
        text = pydoc.render_doc(shapematch, renderer=pydoc.plaintext)
        # the client is imported when first used (its json import is a cost
        # match() does not pay): the package's page names it
        for name in ("match(", "batch(", "warp(", "help(shapematch.Client)", "__version__"):
            self.assertIn(name, text)
        text = pydoc.render_doc(shapematch.Client, renderer=pydoc.plaintext)
        for name in ("warp(self, job", "batch(self, template", "submit("):
            self.assertIn(name, text)
        missing = []
        for name in shapematch.__all__:
            obj = getattr(shapematch, name)
            if isinstance(obj, str):
                continue
            if not (obj.__doc__ or "").strip():
                missing.append(name)
            if inspect.isclass(obj):
                for m, f in vars(obj).items():
                    if not m.startswith("_") and callable(f) and not (f.__doc__ or "").strip():
                        missing.append("%s.%s" % (name, m))
        self.assertEqual(missing, [])


if __name__ == "__main__":
    unittest.main()
