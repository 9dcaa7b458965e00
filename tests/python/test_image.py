"""Image targets from Python (issue 26 over issue 23): match(target_image=)
against `shapematch run --target-image` bit for bit, the params label,
level and image_space passed through, the refusals; sm_run_files' layout
against the C compiler's; Client.submit(target_image=) against the
daemon's worker; batch's target_image column.  The label map is the
sphere of radius 10 that tests/cli/image_shapes.py rasterises (an
oblique, anisotropic NIfTI-1 grid), the template a ball of radius 8.5
meshed by gmsh at test time (as tests/cli/image_run.sh)."""
import os
import shutil
import subprocess
import sys
import tempfile
import unittest

import test_shapematch as base
import shapematch

DAEMON = os.environ.get("SM_TEST_DAEMON")
TOKEN = os.environ.get("SM_TEST_TOKEN")
SHAPES = os.path.join(base.ROOT, "tests", "cli", "image_shapes.py")
# AMG: the same bits on any number of threads (test_shapematch.Match3D),
# so the CLI, the package and the daemon's worker agree bit for bit
KW = dict(clamp_ball=(4, 39, 9, 4.5), max_iter=5, solver="amg")
CLI_ARGS = ["--clamp-ball", "4,39,9,4.5", "--max-iter", "5", "--solver", "amg"]
CASE = {}


def setUpModule():
    tmp = tempfile.mkdtemp(prefix="sm-py-image-")
    CASE["tmp"] = tmp
    subprocess.run([sys.executable, SHAPES, "write", tmp, "sphere"], check=True,
                   stdout=subprocess.DEVNULL)
    with open(os.path.join(tmp, "ball.geo"), "w") as f:
        f.write('SetFactory("OpenCASCADE");\nSphere(1) = {4, 39, 9, 8.5};\n'
                "Mesh.MeshSizeFromPoints = 0;\n")
    subprocess.run(["gmsh", os.path.join(tmp, "ball.geo"), "-3", "-format", "msh41", "-clmax",
                    "3", "-nt", "1", "-v", "1", "-o", os.path.join(tmp, "ball.msh")],
                   check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    CASE["template"] = os.path.join(tmp, "ball.msh")
    CASE["image"] = os.path.join(tmp, "s1.nii")


def tearDownModule():
    shutil.rmtree(CASE["tmp"], ignore_errors=True)


def cli_run(out, *extra):
    """shapematch run --target-image on the case; (exit code, vertices,
    summary)."""
    import json
    cp = subprocess.run([os.path.join(base.BIN, "shapematch"), "run", "--template",
                         CASE["template"], "--target-image", CASE["image"], "-q", "-o", out]
                        + CLI_ARGS + list(extra), check=False, stderr=subprocess.DEVNULL)
    verts, _ = base.read_medit_vertices(os.path.join(out, "result.mesh"))
    with open(os.path.join(out, "summary.json")) as f:
        return cp.returncode, verts, json.load(f)


def image_report(summary):
    """The summary's target_image object without its timing."""
    return {k: v for k, v in summary["target_image"].items() if k != "sdf_seconds"}


class MatchImage(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.out = os.path.join(CASE["tmp"], "cli")
        cls.cli_rc, cls.cli_vertices, cls.cli_summary = cli_run(
            cls.out, "--label", "1", "--image-space", "lps", "--level", "0.25")
        cls.result = shapematch.match(CASE["template"], target_image=CASE["image"], label=1,
                                      image_space="lps", level=0.25, **KW)

    def test_vertices_bit_for_bit_with_the_cli(self):
        """match(target_image=...) gives run --target-image's vertices bit for bit"""
        r = self.result
        self.assertEqual(r.summary["iterations"], self.cli_summary["iterations"])
        self.assertEqual(r.exit_code, self.cli_rc)
        self.assertGreater(r.summary["iterations"], 0)
        self.assertEqual([tuple(v) for v in r.vertices.tolist()], self.cli_vertices)

    def test_summary_reports_the_image_and_its_label(self):
        """the summary's target_image object and inputs name are the CLI's"""
        s, c = self.result.summary, self.cli_summary
        self.assertEqual(image_report(s), image_report(c))
        t = s["target_image"]
        self.assertEqual((t["label"], t["level"], t["image_space"]), (1, 0.25, "lps"))
        self.assertEqual(t["voxels"], 1921)  # image_shapes.py's count
        self.assertEqual(s["inputs"]["target_image"], CASE["image"])
        self.assertEqual(c["inputs"]["target_image"], CASE["image"])

    def test_image_space_ras_is_passed_through(self):
        """image_space="ras": run --image-space ras's vertices; the box mirrored in x and y"""
        out = os.path.join(CASE["tmp"], "cli-ras")
        # the RAS sphere lies far from the template: a background twice
        # as large, its cells coarser to keep the field build short
        _, cli, _ = cli_run(out, "--image-space", "ras", "--max-iter", "1",
                            "--background-size", "4")
        r = shapematch.match(CASE["template"], target_image=CASE["image"], image_space="ras",
                             background_size=4, **dict(KW, max_iter=1))
        self.assertEqual([tuple(v) for v in r.vertices.tolist()], cli)
        ras, lps = r.summary["target_image"], self.result.summary["target_image"]
        self.assertEqual(ras["image_space"], "ras")
        # LPS -> RAS negates x and y exactly: the box's corners swap
        self.assertEqual(ras["bbox_min"], [-lps["bbox_max"][0], -lps["bbox_max"][1],
                                           lps["bbox_min"][2]])
        self.assertEqual(ras["bbox_max"], [-lps["bbox_min"][0], -lps["bbox_min"][1],
                                           lps["bbox_max"][2]])

    def test_write_gives_the_cli_result_mesh(self):
        d = os.path.join(CASE["tmp"], "py-write")
        self.result.write(d, formats="mesh")
        with open(os.path.join(d, "result.mesh"), "rb") as a, \
                open(os.path.join(self.out, "result.mesh"), "rb") as b:
            self.assertEqual(a.read(), b.read())


class ImageRefusals(unittest.TestCase):
    def test_an_empty_label_raises_naming_it(self):
        with self.assertRaises(shapematch.ShapematchError) as e:
            shapematch.match(CASE["template"], target_image=CASE["image"], label=2, **KW)
        self.assertIn("label-empty: no voxel of the image has label 2", str(e.exception))
        self.assertIn("s1.nii", str(e.exception))
        self.assertEqual(e.exception.status, "invalid")

    def test_a_second_target_is_refused(self):
        with self.assertRaises(shapematch.ShapematchError) as e:
            shapematch.match(CASE["template"], target_image=CASE["image"],
                             target_surface=CASE["template"], **KW)
        self.assertIn("target_image excludes target_surface", str(e.exception))

    def test_a_2d_template_is_refused(self):
        with self.assertRaises(shapematch.ShapematchError) as e:
            shapematch.match(base.TEMPLATE2, target_image=CASE["image"],
                             clamp_ball=(0.5, 0.5, 0.04))
        self.assertIn("image (34 x 30 x 22 voxels): a 2D template needs a 2D image", str(e.exception))

    def test_arrays_are_refused(self):
        with self.assertRaises(TypeError):
            shapematch.match(CASE["template"], target_image=[[0, 1]], **KW)

    def test_a_missing_image_names_the_file(self):
        missing = os.path.join(CASE["tmp"], "missing.nii")
        with self.assertRaises(shapematch.ShapematchError) as e:
            shapematch.match(CASE["template"], target_image=missing, **KW)
        self.assertIn(missing, str(e.exception))


class RunFilesLayout(unittest.TestCase):
    @unittest.skipUnless(shutil.which("cc"), "no C compiler")
    def test_ctypes_struct_is_the_headers(self):
        """_lib.RunFiles: the size and every offset of the C compiler's sm_run_files"""
        import ctypes
        from shapematch import _lib
        names = [f[0] for f in _lib.RunFiles._fields_]
        src = "#include <stddef.h>\n#include <stdio.h>\n#include \"shapematch_job.h\"\n" \
              "int main(void) {\n printf(\"%zu\\n\", sizeof(sm_run_files));\n" + "".join(
                  ' printf("%%zu\\n", offsetof(sm_run_files, %s));\n' % n for n in names) + "}\n"
        d = tempfile.mkdtemp(prefix="sm-py-layout-")
        try:
            with open(os.path.join(d, "l.c"), "w") as f:
                f.write(src)
            exe = os.path.join(d, "l")
            subprocess.run(["cc", "-std=c11", "-I", os.path.join(base.ROOT, "proto", "job"), "-I",
                            os.path.join(base.ROOT, "core", "include"), "-o", exe,
                            os.path.join(d, "l.c")], check=True)
            got = [int(x) for x in subprocess.run([exe], check=True, capture_output=True,
                                                  text=True).stdout.split()]
        finally:
            shutil.rmtree(d, ignore_errors=True)
        want = [ctypes.sizeof(_lib.RunFiles)] + [getattr(_lib.RunFiles, n).offset for n in names]
        self.assertEqual(got, want)


class BatchImage(unittest.TestCase):
    def test_image_column_only_when_a_target_has_one(self):
        from shapematch import _LIST_COLUMNS, _target_dict, _target_row
        t = _target_dict({"name": "s", "target_image": CASE["image"]})
        self.assertEqual(_target_row(t, _LIST_COLUMNS + ("target_image",)),
                         "s,,,,," + CASE["image"])
        with self.assertRaises(TypeError):
            _target_dict({"target_imag": CASE["image"]})

    def test_batch_of_an_image_target_is_match(self):
        """batch's target_image column: the target's result is match's"""
        out = os.path.join(CASE["tmp"], "batch")
        try:
            s = shapematch.batch(CASE["template"], [{"name": "s1", "target_image": CASE["image"]}],
                                 out, jobs=1, model_align="none", **KW)
        except shapematch.ShapematchError as e:
            # a reader of five columns (name .. landmarks) says one of these
            if "unknown column 'target_image'" in str(e) or "more than 5 columns" in str(e):
                self.skipTest("this library's LIST.csv reader has no target_image column yet")
            raise
        self.assertEqual(s["failed"], [])
        got, _ = base.read_medit_vertices(os.path.join(out, "targets", "s1", "result.mesh"))
        r = shapematch.match(CASE["template"], target_image=CASE["image"], **KW)
        self.assertEqual(got, [tuple(v) for v in r.vertices.tolist()])


@unittest.skipUnless(DAEMON, "no daemon (run by tests/integration/python.sh)")
@unittest.skipIf(os.environ.get("SM_VARIANT") == "asan",
                 "the package's side is the release run's; daemon_image.sh runs the worker's "
                 "image path under ASan")
class ClientImage(unittest.TestCase):
    def test_submit_target_image_equals_local_match(self):
        """Client.submit(target_image=...): the worker's vertices are match's, bit for bit"""
        c = shapematch.Client(DAEMON, token=TOKEN)
        job = c.submit(CASE["template"], target_image=CASE["image"], label=1, **KW)
        r = job.wait()
        local = shapematch.match(CASE["template"], target_image=CASE["image"], label=1, **KW)
        self.assertEqual(r.summary["target_image"]["voxels"], 1921)
        self.assertEqual(r.vertices.tolist(), local.vertices.tolist())


if __name__ == "__main__":
    unittest.main()
