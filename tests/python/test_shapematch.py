"""The Python package against the library and the CLI (stdlib unittest;
tests/integration/python.sh runs it and speaks TAP).  Env: SM_BIN (build
folder: the programs and the .so files), SM_ROOT, SHAPEMATCH_LIBDIR."""
import array
import ctypes
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import threading
import time
import unittest

ROOT = os.environ.get("SM_ROOT", os.path.abspath(os.path.join(os.path.dirname(__file__), "..", "..")))
BIN = os.environ.get("SM_BIN", os.path.join(ROOT, "build", "release"))
sys.path.insert(0, os.path.join(ROOT, "python"))
os.environ.setdefault("SHAPEMATCH_LIBDIR", BIN)
import shapematch  # noqa: E402
from shapematch import _arrays  # noqa: E402

EX2 = os.path.join(ROOT, "examples", "2d")
CASE2 = dict(target_mesh=os.path.join(EX2, "background.mesh.gz"),
             target_sol=os.path.join(EX2, "background.sol.gz"), clamp_ball=(0.5, 0.5, 0.04))
TEMPLATE2 = os.path.join(EX2, "template.mesh")


def words_of(path):
    with open(path) as f:
        return f.read().split()


def read_medit_vertices(path):
    """The Vertices block of a Medit ASCII file: (coords list, refs list),
    read here independently of the library."""
    words = words_of(path)
    i = words.index("Dimension")
    dim = int(words[i + 1])
    j = words.index("Vertices")
    n = int(words[j + 1])
    vals = words[j + 2:j + 2 + n * (dim + 1)]
    rows = [vals[k * (dim + 1):(k + 1) * (dim + 1)] for k in range(n)]
    return [tuple(float(x) for x in r[:dim]) for r in rows], [int(r[dim]) for r in rows]


def read_medit_block(path, name, nv):
    words = words_of(path)
    j = words.index(name)
    n = int(words[j + 1])
    vals = words[j + 2:j + 2 + n * (nv + 1)]
    return [tuple(int(x) for x in vals[k * (nv + 1):(k + 1) * (nv + 1)]) for k in range(n)]


def grid(n, lo, hi):
    """n x n squares on [lo, hi]^2, each cut into two triangles (0-based)."""
    h = (hi - lo) / n
    verts = [[lo + i * h, lo + j * h] for j in range(n + 1) for i in range(n + 1)]
    tris = []
    for j in range(n):
        for i in range(n):
            a = j * (n + 1) + i
            tris += [[a, a + 1, a + n + 2], [a, a + n + 2, a + n + 1]]
    return verts, tris


def write_medit(path, verts, tris, refs=None):
    with open(path, "w") as f:
        f.write("MeshVersionFormatted 2\nDimension 2\nVertices\n%d\n" % len(verts))
        f.writelines("%r %r 0\n" % (x, y) for x, y in verts)
        f.write("Triangles\n%d\n" % len(tris))
        f.writelines("%d %d %d %d\n" % (a + 1, b + 1, c + 1, (refs[k] if refs else 1))
                     for k, (a, b, c) in enumerate(tris))
        f.write("End\n")


def tiny_case(folder):
    """A quick job (milliseconds): a square template of 128 triangles in
    [-0.5, 0.5]^2 onto the circle of radius 0.8, whose distance is sampled
    on a 24 x 24 grid of [-1.2, 1.2]^2; clamp ball (0, 0, 0.15).  Files
    template.mesh, bg.mesh, bg.sol in folder; returns the keywords."""
    import math
    tv, tt = grid(8, -0.5, 0.5)
    bv, bt = grid(24, -1.2, 1.2)
    write_medit(os.path.join(folder, "template.mesh"), tv, tt)
    write_medit(os.path.join(folder, "bg.mesh"), bv, bt)
    with open(os.path.join(folder, "bg.sol"), "w") as f:
        f.write("MeshVersionFormatted 2\nDimension 2\nSolAtVertices\n%d\n1 1\n" % len(bv))
        f.writelines("%r\n" % (math.hypot(x, y) - 0.8) for x, y in bv)
        f.write("End\n")
    return dict(target_mesh=os.path.join(folder, "bg.mesh"),
                target_sol=os.path.join(folder, "bg.sol"), clamp_ball=(0, 0, 0.15))


def rss_kib():
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1])
    return 0


class Match2D(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.tmp = tempfile.mkdtemp(prefix="sm-py-")
        out = os.path.join(cls.tmp, "cli")
        subprocess.run([os.path.join(BIN, "shapematch"), "run", "--template", TEMPLATE2,
                        "--target-mesh", CASE2["target_mesh"], "--target-sol", CASE2["target_sol"],
                        "--clamp-ball", "0.5,0.5,0.04", "--max-iter", "60", "-q", "-o", out],
                       check=True)
        cls.cli_out = out
        cls.cli_vertices, _ = read_medit_vertices(os.path.join(out, "result.mesh"))
        with open(os.path.join(out, "summary.json")) as f:
            cls.cli_summary = json.load(f)
        cls.result = shapematch.match(TEMPLATE2, max_iter=60, **CASE2)

    @classmethod
    def tearDownClass(cls):
        shutil.rmtree(cls.tmp, ignore_errors=True)

    def test_vertices_bit_for_bit_with_the_cli(self):
        r = self.result
        self.assertEqual(len(r.vertices), len(self.cli_vertices))
        # result.mesh is written with 17 significant digits: exact doubles
        got = [tuple(row) for row in r.vertices.tolist()]
        self.assertEqual(got, self.cli_vertices)

    def test_summary_matches_the_cli(self):
        s, c = self.result.summary, self.cli_summary
        for key in ("iterations", "stop_reason", "J_final", "boundary_l2", "boundary_rms",
                    "min_quality", "converged", "inverted_elements"):
            self.assertEqual(s[key], c[key], key)
        self.assertEqual(s["parameters"], c["parameters"])

    def test_displacement_is_vertices_minus_template(self):
        r = self.result
        tv, trefs = read_medit_vertices(TEMPLATE2)
        self.assertEqual([tuple(x) for x in r.initial_vertices.tolist()], tv)
        self.assertEqual(list(r.vertex_refs.tolist()), trefs)
        for (a, b), (x, y), (dx, dy) in zip(r.vertices.tolist(), tv, r.displacement.tolist()):
            self.assertEqual((dx, dy), (a - x, b - y))

    def test_elements_are_the_templates_zero_based(self):
        tris = read_medit_block(TEMPLATE2, "Triangles", 3)
        self.assertEqual([tuple(e) for e in self.result.elements.tolist()],
                         [tuple(v - 1 for v in t[:3]) for t in tris])
        self.assertEqual(list(self.result.element_refs.tolist()), [t[3] for t in tris])

    def test_history_one_row_per_iteration(self):
        h = self.result.history
        self.assertEqual([row["iteration"] for row in h], list(range(len(h))))
        self.assertEqual(len(h) - 1, self.result.summary["iterations"])
        self.assertEqual(h[-1]["J"], self.result.summary["J_final"])
        self.assertEqual(self.result.warnings, self.cli_summary["warnings"])

    def test_figures_by_the_summarys_names(self):
        # Result.distance is summary.json's "distance" (None when absent);
        # the repr shows the figures by their names, the L2 norm as such
        r = self.result
        self.assertEqual(r.distance, r.summary.get("distance"))
        text = repr(r)
        self.assertIn("L2 of d on the boundary %.3e" % r.summary["boundary_l2"], text)
        if r.distance is not None:
            self.assertIn("result->target RMS %.3e" % r.distance["result_to_target"]["rms"], text)
            self.assertIn("target->result RMS %.3e" % r.distance["target_to_result"]["rms"], text)
        else:
            self.assertIn("boundary RMS %.3e, max %.3e" % (r.summary["boundary_rms"],
                                                            r.summary["boundary_max"]), text)
        # a summary with the two-sided figures, and an old one without
        two = {"boundary_l2": 3.0, "boundary_rms": 1.0, "boundary_max": 2.0,
               "distance": {"result_to_target": {"rms": 0.25, "max": 0.5, "mean": 0.2},
                            "target_to_result": {"rms": 0.75, "max": 1.5, "mean": 0.5, "p99": 1.25},
                            "unit": "mm", "method": "surface"}}
        self.assertEqual(shapematch._headline(two),
                         "result->target RMS 2.500e-01, max 5.000e-01; target->result RMS "
                         "7.500e-01, max 1.500e+00, p99 1.250e+00 (mm); L2 of d on the boundary "
                         "3.000e+00")
        del two["distance"]
        self.assertEqual(shapematch._headline(two), "boundary RMS 1.000e+00, max 2.000e+00; "
                         "L2 of d on the boundary 3.000e+00")

    def test_write_gives_the_cli_files(self):
        d = os.path.join(self.tmp, "py")
        self.result.write(d)
        for name in ("result.mesh", "displacement.sol"):
            with open(os.path.join(d, name), "rb") as a, \
                    open(os.path.join(self.cli_out, name), "rb") as b:
                self.assertEqual(a.read(), b.read(), name)
        # history.csv: the same rows but for the elapsed time
        with open(os.path.join(d, "history.csv")) as a, \
                open(os.path.join(self.cli_out, "history.csv")) as b:
            ha, hb = a.read().splitlines(), b.read().splitlines()
        col = ha[0].split(",").index("elapsed")
        strip = lambda rows: [r.split(",")[:col] + r.split(",")[col + 1:] for r in rows]  # noqa
        self.assertEqual(strip(ha), strip(hb))
        with self.assertRaises(shapematch.ShapematchError) as e:
            self.result.write(d, formats="mesh,nonsense")
        self.assertIn("nonsense", str(e.exception))

    def test_arrays_in_equal_files_in(self):
        tv, _ = read_medit_vertices(TEMPLATE2)
        tris = read_medit_block(TEMPLATE2, "Triangles", 3)
        elems = [t[:3] for t in tris]
        refs = [t[3] for t in tris]
        verts = array.array("d", [c for v in tv for c in v])
        # a 2-D buffer, 0-based elements as nested lists
        m = memoryview(verts).cast("B").cast("d", [len(tv), 2])
        r = shapematch.match((m, [[v - 1 for v in e] for e in elems], refs), max_iter=60, **CASE2)
        self.assertEqual(r.vertices.tolist(), self.result.vertices.tolist())
        self.assertEqual(r.summary["inputs"]["template"], "template (array)")
        # and the result itself as a template (0 iterations more would be the
        # same shape: check the arrays round trip only)
        self.assertEqual(r.elements.tolist(), self.result.elements.tolist())

    @unittest.skipIf(_arrays.numpy is None, "python3-numpy is not installed")
    def test_numpy_arrays_in_and_out(self):
        np = _arrays.numpy
        r = self.result
        self.assertIsInstance(r.vertices, np.ndarray)
        self.assertEqual(r.vertices.shape, (len(self.cli_vertices), 2))
        r2 = shapematch.match((np.array(r.initial_vertices), r.elements, r.element_refs),
                              max_iter=60, **CASE2)
        self.assertTrue(np.array_equal(r2.vertices, r.vertices))


def write_ellipse(path, a, b, n=200):
    """A closed polyline on the ellipse of semi-axes a, b about (0.5, 0.5)
    (Medit Edges: a 2D target surface)."""
    import math
    with open(path, "w") as f:
        f.write("MeshVersionFormatted 2\nDimension 2\nVertices\n%d\n" % n)
        for i in range(n):
            t = 2 * math.pi * i / n
            f.write("%.17g %.17g 0\n" % (0.5 + a * math.cos(t), 0.5 + b * math.sin(t)))
        f.write("Edges\n%d\n" % n)
        f.writelines("%d %d 1\n" % (i + 1, (i + 1) % n + 1) for i in range(n))
        f.write("End\n")


class Batch2D(unittest.TestCase):
    """shapematch.batch: the CLI's batch, file for file; a failed target
    listed and left out; a bad option raises."""

    def setUp(self):
        self.tmp = tempfile.mkdtemp(prefix="sm-py-batch-")
        self.targets = []
        for a, b in ((0.22, 0.30), (0.30, 0.22), (0.26, 0.26)):
            path = os.path.join(self.tmp, "e%gx%g.mesh" % (a, b))
            write_ellipse(path, a, b)
            self.targets.append(path)

    def tearDown(self):
        shutil.rmtree(self.tmp, ignore_errors=True)

    def test_same_files_as_the_cli_and_a_failed_target(self):
        out = os.path.join(self.tmp, "py")
        missing = os.path.join(self.tmp, "missing.stl")
        s = shapematch.batch(TEMPLATE2, self.targets + [{"name": "gone", "target_surface": missing}],
                             out, clamp_ball=(0.5, 0.5, 0.04), max_iter=40, jobs=2)
        self.assertEqual(s["targets_ok"], 3)
        self.assertEqual(s["failed"], ["gone"])
        self.assertEqual(s["template_setup"]["count"], 1)
        self.assertEqual(len(s["model_summary"]["targets"]), 3)
        cli = os.path.join(self.tmp, "cli")
        args = [os.path.join(BIN, "shapematch"), "batch", "--template", TEMPLATE2,
                "--clamp-ball", "0.5,0.5,0.04", "--max-iter", "40", "-q", "-o", cli]
        for t in self.targets:
            args += ["--target-surface", t]
        subprocess.run(args, check=True)
        for t in self.targets:
            name = os.path.basename(t)[:-len(".mesh")]
            for f in ("result.mesh", "displacement.sol"):
                with open(os.path.join(out, "targets", name, f), "rb") as x, \
                        open(os.path.join(cli, "targets", name, f), "rb") as y:
                    self.assertEqual(x.read(), y.read(), name + "/" + f)
        with open(os.path.join(out, "model", "scores.csv")) as x, \
                open(os.path.join(cli, "model", "scores.csv")) as y:
            self.assertEqual(x.read(), y.read())

    def test_the_hosts_child_keeps_its_exit_status(self):
        """sm_run_batch waits for its own children only (issue 36): a
        subprocess the host started has ended (a zombie) when the batch
        runs, and the host still reads its exit status after it (a
        waitpid(-1) in the library took it, and Popen.wait then read 0)."""
        host = subprocess.Popen(["sh", "-c", "exit 7"])
        stat = "/proc/%d/stat" % host.pid
        for _ in range(1000):  # ended, not yet waited for: a zombie the batch could reap
            with open(stat) as f:
                if f.read().rsplit(") ", 1)[1][0] == "Z":
                    break
            time.sleep(0.01)
        out = os.path.join(self.tmp, "host")
        s = shapematch.batch(TEMPLATE2, self.targets, out, clamp_ball=(0.5, 0.5, 0.04),
                             max_iter=40, jobs=1)
        self.assertEqual(s["targets_ok"], 3)
        self.assertEqual(host.wait(timeout=30), 7)

    def test_template_from_mean_as_the_cli(self):
        """template_from="mean": the CLI's rounds, file for file."""
        out = os.path.join(self.tmp, "pymean")
        s = shapematch.batch(TEMPLATE2, self.targets, out, clamp_ball=(0.5, 0.5, 0.04),
                             max_iter=40, jobs=2, template_from="mean", rounds=2)
        cli = os.path.join(self.tmp, "climean")
        args = [os.path.join(BIN, "shapematch"), "batch", "--template", TEMPLATE2,
                "--clamp-ball", "0.5,0.5,0.04", "--max-iter", "40", "-q", "-o", cli,
                "--template-from", "mean", "--rounds", "2", "--target-surface"] + self.targets
        subprocess.run(args, check=True)
        with open(os.path.join(cli, "summary.json")) as f:
            c = json.load(f)["template_from"]
        t = s["template_from"]
        self.assertEqual(t["mode"], "mean")
        self.assertEqual(t["rounds"], 2)
        self.assertEqual(t["movement"], c["movement"])
        self.assertEqual(s["model_summary"]["template_from"], t)
        for f in ("template.mesh", "model/mean.mesh", "model/scores.csv"):
            with open(os.path.join(out, f), "rb") as x, open(os.path.join(cli, f), "rb") as y:
                self.assertEqual(x.read(), y.read(), f)

    def test_bad_template_from_raises(self):
        for kw in ({"template_from": "nonsense"}, {"template_from": "medoid", "rounds": 3},
                   {"template_from": "mean", "rounds": 1}, {"rounds": 3}):
            with self.assertRaises((shapematch.ShapematchError, TypeError), msg=str(kw)):
                shapematch.batch(TEMPLATE2, self.targets, os.path.join(self.tmp, "bad"),
                                 clamp_ball=(0.5, 0.5, 0.04), **kw)

    def test_bad_model_align_raises(self):
        with self.assertRaises(shapematch.ShapematchError):
            shapematch.batch(TEMPLATE2, self.targets, os.path.join(self.tmp, "x"),
                             clamp_ball=(0.5, 0.5, 0.04), model_align="affine")


class Match3D(unittest.TestCase):
    @unittest.skipIf(os.environ.get("SM_VARIANT") == "asan",
                     "the 2D case runs the same code under ASan; the 3D read takes ~10 s there")
    def test_vertices_bit_for_bit_with_the_cli(self):
        """3D example, 3 iterations: match's vertices are shapematch run's"""
        ex = os.path.join(ROOT, "examples", "3d")
        tmp = tempfile.mkdtemp(prefix="sm-py-")
        kw = dict(target_mesh=os.path.join(ex, "background.mesh.gz"),
                  target_sol=os.path.join(ex, "background.sol.gz"))
        cp = subprocess.run([os.path.join(BIN, "shapematch"), "run", "--template",
                             os.path.join(ex, "template.mesh"), "--target-mesh", kw["target_mesh"],
                             "--target-sol", kw["target_sol"], "--clamp-ball", "0.5,0.5,0.5,0.05",
                             "--max-iter", "3", "--solver", "amg", "-q", "-o", tmp], check=False)
        cli, _ = read_medit_vertices(os.path.join(tmp, "result.mesh"))
        shutil.rmtree(tmp, ignore_errors=True)
        # AMG: its solves are the same bits on any number of threads, where
        # CHOLMOD's factor (BLAS) follows the thread count, which the thread
        # policy takes from the cores idle when each run starts
        r = shapematch.match(os.path.join(ex, "template.mesh"), clamp_ball=(0.5, 0.5, 0.5, 0.05),
                             max_iter=3, solver="amg", **kw)
        self.assertEqual(r.summary["iterations"], 3)
        self.assertEqual((r.exit_code, cp.returncode), (10, 10))  # not converged after 3
        self.assertEqual([tuple(v) for v in r.vertices.tolist()], cli)


class MatchBehaviour(unittest.TestCase):
    def test_progress_every_iteration_and_stop(self):
        seen = []

        def progress(it, J, err):
            seen.append((it, J, err))
            return it < 5

        r = shapematch.match(TEMPLATE2, progress=progress, max_iter=100, **CASE2)
        self.assertEqual(r.status, "cancelled")
        self.assertEqual(r.summary["stop_reason"], "cancelled")
        self.assertEqual(r.exit_code, 5)
        self.assertEqual([s[0] for s in seen], list(range(6)))
        self.assertEqual(r.summary["iterations"], 5)
        self.assertEqual([(h["iteration"], h["J"], h["boundary_l2"]) for h in r.history], seen)

    def test_exception_in_progress_stops_and_propagates(self):
        def progress(it, J, err):
            if it == 2:
                raise KeyError("from the callback")

        with self.assertRaises(KeyError):
            shapematch.match(TEMPLATE2, progress=progress, max_iter=100, **CASE2)

    def test_gil_released_during_the_run(self):
        """the run releases the GIL: another Python thread keeps ticking"""
        stamps, stop = [], threading.Event()

        def ticker():
            while not stop.is_set():
                stamps.append(time.monotonic())
                time.sleep(0.001)

        t = threading.Thread(target=ticker)
        t.start()
        try:
            time.sleep(0.01)
            t0 = time.monotonic()
            # one iteration: the time goes to reading the inputs and building
            # the field, one C call without a callback
            r = shapematch.match(TEMPLATE2, max_iter=1, **CASE2)
            t1 = time.monotonic()
        finally:
            stop.set()
            t.join()
        ticks = [x for x in stamps if t0 <= x <= t1]
        gap = max(b - a for a, b in zip([t0] + ticks, ticks + [t1]))
        read = r.summary["timings"]["read"]
        # a held GIL (ctypes.PyDLL) freezes the ticker for the whole read;
        # released, its gaps are the scheduler's (measured: ~1-10 ms)
        self.assertGreater(read, 0.02)
        self.assertLess(gap, 0.5 * read, "the ticker stopped for %.3f s of a %.3f s read"
                        % (gap, read))

    def test_errors_raise_with_the_core_message(self):
        bad = os.path.join(tempfile.mkdtemp(prefix="sm-py-"), "bad.mesh")
        with open(bad, "w") as f:
            f.write("MeshVersionFormatted 2\nDimension 2\nVertices\n2\n0 0 0\n1 x 0\nEnd\n")
        with self.assertRaises(shapematch.ShapematchError) as e:
            shapematch.match(bad, **CASE2)
        self.assertEqual(e.exception.status, "format")
        self.assertIn(bad, str(e.exception))
        self.assertRegex(str(e.exception), r"bad\.mesh:6: ")
        with self.assertRaises(shapematch.ShapematchError) as e:
            shapematch.match(TEMPLATE2, max_iter=0, **CASE2)
        self.assertIn("max_iter", str(e.exception))
        self.assertEqual(e.exception.status, "invalid")
        with self.assertRaises(shapematch.ShapematchError) as e:
            shapematch.match(TEMPLATE2, no_such_parameter=1, **CASE2)
        self.assertIn("no_such_parameter", str(e.exception))
        with self.assertRaises(shapematch.ShapematchError) as e:
            shapematch.match(TEMPLATE2, target_mesh=CASE2["target_mesh"],
                             target_sol=CASE2["target_sol"], clamp_ball=(5, 5, 0.01))
        self.assertIn("clamp", str(e.exception))
        with self.assertRaises(TypeError):  # two clamps (none: the default ball)
            shapematch.match(TEMPLATE2, target_mesh=CASE2["target_mesh"],
                             target_sol=CASE2["target_sol"], clamp_ball=(0.5, 0.5, 0.1),
                             no_clamp=True)
        with self.assertRaises(shapematch.ShapematchError) as e:  # no target_sol
            shapematch.match(TEMPLATE2, target_mesh=CASE2["target_mesh"], clamp_ball=(0, 0, 1))
        self.assertIn("no target", str(e.exception))
        # arrays are checked by the library, as a file's contents are
        with self.assertRaises(shapematch.ShapematchError) as e:
            shapematch.match(([[0, 0], [1, 0], [0, 1]], [[0, 1, 3]]), **CASE2)
        self.assertIn("template (array): element 0: vertex index 3 out of range [0, 3)",
                      str(e.exception))
        self.assertEqual(e.exception.status, "format")
        with self.assertRaises(shapematch.ShapematchError) as e:
            shapematch.match(([[0, 0], [1, float("nan")], [0, 1]], [[0, 1, 2]]), **CASE2)
        self.assertIn("template (array): vertex 1: coordinate 2 is not a finite number",
                      str(e.exception))
        with self.assertRaises(ValueError):  # the shapes are Python's to check
            shapematch.match(([[0, 0], [1, 0], [0, 1]], [[0, 1, 2]], [1, 2]), **CASE2)

    def test_parameters_come_from_the_table(self):
        names = [p["name"] for p in shapematch.parameters()]
        self.assertIn("max_iter", names)
        self.assertIn("young", names)
        # every flag of `shapematch run --help` that the table names
        help_text = subprocess.run([os.path.join(BIN, "shapematch"), "run", "--help"],
                                   capture_output=True, text=True).stdout
        for p in shapematch.parameters():
            if p["flag"]:
                self.assertIn(p["flag"], help_text)

    def test_matches_in_threads_equal_one_at_a_time(self):
        """matches in several threads at once give the sequential results"""
        tmp = tempfile.mkdtemp(prefix="sm-py-")
        kw = tiny_case(tmp)
        tmpl = os.path.join(tmp, "template.mesh")
        iters = [5, 12, 20, 30]
        alone = [shapematch.match(tmpl, max_iter=k, **kw).vertices.tolist() for k in iters]
        got = [None] * len(iters)

        def run(i):
            got[i] = shapematch.match(tmpl, max_iter=iters[i], **kw).vertices.tolist()

        threads = [threading.Thread(target=run, args=(i,)) for i in range(len(iters))]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
        shutil.rmtree(tmp, ignore_errors=True)
        self.assertEqual(got, alone)
        self.assertNotEqual(alone[0], alone[-1])

    @unittest.skipIf(os.environ.get("SM_VARIANT") == "asan",
                     "ASan's quarantine keeps freed memory: RSS is measured in release")
    def test_many_matches_bounded_rss(self):
        """100 matches in one process: RSS flat (no leak of inputs, field, run)"""
        tmp = tempfile.mkdtemp(prefix="sm-py-")
        kw = tiny_case(tmp)
        tmpl = os.path.join(tmp, "template.mesh")
        n = int(os.environ.get("SM_TEST_MATCHES", "100"))
        for _ in range(10):  # warm-up: allocator pools, OpenMP threads
            shapematch.match(tmpl, max_iter=3, **kw)
        before = rss_kib()
        for i in range(n):
            r = shapematch.match(tmpl, max_iter=3, **kw)
            if i % 10 == 0:  # the result set too (its files are fsync'ed: slow)
                r.write(os.path.join(tmp, "out"), formats="mesh")
        after = rss_kib()
        shutil.rmtree(tmp, ignore_errors=True)
        self.assertEqual(r.summary["iterations"], 3)
        # measured: +16 KiB over 300 runs; a job's inputs, field and run
        # are ~100 KiB here, so a leak of any of them shows as megabytes
        self.assertLess(after - before, 2048, "RSS grew from %d to %d KiB over %d matches" % (
            before, after, n))


class Sdf(unittest.TestCase):
    def test_square_distances_exact(self):
        # the unit square's boundary as 4 segments, counter-clockwise
        sq = ([[0, 0], [1, 0], [1, 1], [0, 1]], [[0, 1], [1, 2], [2, 3], [3, 0]])
        pts = [[0.5, 0.5], [2.0, 0.5], [0.25, 0.5], [2.0, 2.0], [-1.0, 0.5]]
        d = shapematch.sdf(sq, pts).tolist()
        want = [-0.5, 1.0, -0.25, 2 ** 0.5, 1.0]
        for a, b in zip(d, want):
            self.assertAlmostEqual(a, b, places=14)

    def test_against_the_cli(self):
        # shapematch sdf on the 2D template's boundary? use a surface made of
        # the square again, written as a Medit 2D edges file, on the 2D
        # background: the library and `shapematch sdf` agree exactly
        tmp = tempfile.mkdtemp(prefix="sm-py-")
        surf = os.path.join(tmp, "square.mesh")
        with open(surf, "w") as f:
            f.write("MeshVersionFormatted 2\nDimension 2\nVertices\n4\n0.2 0.2 0\n0.8 0.2 0\n"
                    "0.8 0.8 0\n0.2 0.8 0\nEdges\n4\n1 2 0\n2 3 0\n3 4 0\n4 1 0\nEnd\n")
        out = os.path.join(tmp, "d.sol")
        subprocess.run([os.path.join(BIN, "shapematch"), "sdf", "--surface", surf, "--background",
                        CASE2["target_mesh"], "-o", out], check=True, capture_output=True)
        words = words_of(out)
        n = int(words[words.index("SolAtVertices") + 1])
        start = words.index("SolAtVertices") + 4
        cli = [float(x) for x in words[start:start + n]]
        d = shapematch.sdf(surf, CASE2["target_mesh"]).tolist()
        self.assertEqual(d, cli)
        shutil.rmtree(tmp, ignore_errors=True)


class StartUp(unittest.TestCase):
    """What keeps `python3 -c 'shapematch.match(...).write(dir)'` near the
    command's time (bench/python.sh): neither numpy nor json is imported
    unless an array or the summary is read, and the params document is
    encoded exactly as json.dumps would."""

    def test_match_and_write_import_neither_numpy_nor_json(self):
        script = ("import sys, shapematch\n"
                  "r = shapematch.match(%r, max_iter=2, target_mesh=%r, target_sol=%r, "
                  "clamp_ball=(0.5, 0.5, 0.04))\n"
                  "r.write(%r)\n"
                  "print(sorted(m for m in ('numpy', 'json', 're') if m in sys.modules))\n"
                  "r.vertices, r.summary\n"
                  "print('numpy' in sys.modules or shapematch._arrays.numpy is None, "
                  "'json' in sys.modules)\n" % (TEMPLATE2, CASE2["target_mesh"],
                                                CASE2["target_sol"], tempfile.mkdtemp()))
        out = subprocess.run([sys.executable, "-c", script], check=True, capture_output=True,
                             text=True, env=dict(os.environ, PYTHONPATH=os.path.join(ROOT, "python")))
        self.assertEqual(out.stdout.split("\n")[:2], ["[]", "True True"], out.stdout + out.stderr)

    def test_params_json_is_json_dumps(self):
        docs = [{"max_iter": 12, "young": 2.5e-3, "free_boundary": [7, 8], "solver": "amg",
                 "clamp": {"kind": "ball", "center": [0.5, 0.5], "radius": 0.04},
                 "flag": True, "none": None, "neg": -0.0, "big": 2 ** 70, "tiny": 1e-300,
                 "odd": "q\"b\\s\n\t\x01\x7f \u00e9 \U0001F600",
                 "inf": float("inf"), "ninf": float("-inf"), "nan": float("nan")}]
        if _arrays.numpy is not None:
            np = _arrays.numpy
            docs.append({"refs": np.array([1, 2], dtype=np.int32), "x": np.float64(0.1),
                         "center": np.array([0.5, 0.25])})
        for d in docs:
            self.assertEqual(shapematch._json(d), json.dumps(d, default=lambda x: x.tolist()))
        with self.assertRaises(TypeError):
            shapematch._json({"x": object()})


if __name__ == "__main__":
    unittest.main()


class Docs(unittest.TestCase):
    def test_the_first_script_of_docs_python_md_runs(self):
        """docs/python.md's first script runs as written and says what the page says"""
        with open(os.path.join(ROOT, "docs", "python.md")) as f:
            text = f.read()
        blocks = text.split("```text\n")[1:]
        script = next(b.split("```")[0] for b in blocks if b.startswith("import shapematch"))
        tmp = tempfile.mkdtemp(prefix="sm-doc-")
        os.symlink(os.path.join(ROOT, "examples"), os.path.join(tmp, "examples"))
        cwd = os.getcwd()
        out = []
        try:
            os.chdir(tmp)
            exec(compile(script, "docs/python.md", "exec"),
                 {"print": lambda *a: out.append(" ".join(map(str, a)))})
            for name in ("result.mesh", "result.vtu", "displacement.sol", "history.csv",
                         "summary.json"):
                self.assertTrue(os.path.exists(os.path.join(tmp, "out-py", name)), name)
        finally:
            os.chdir(cwd)
            shutil.rmtree(tmp, ignore_errors=True)
        # the repr the page shows in its comment, up to its "..."
        said = re.search(r"# (<shapematch\.Result .*?)\.\.\.>", text).group(1)
        self.assertTrue(out[0].startswith(said), "%s, the page says %s" % (out[0], said))
