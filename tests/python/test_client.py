"""shapematch.Client against a real shapematchd on loopback, started by
tests/integration/python.sh (SM_TEST_DAEMON: its URL, SM_TEST_TOKEN: a
token it accepts; SM_TEST_DAEMON_RATE: a second daemon that accepts one
submission per 2 s), and against a fake server that answers 503."""
import http.server
import json
import os
import shutil
import tempfile
import threading
import time
import unittest

import test_shapematch as base
import shapematch
from shapematch import _client

DAEMON = os.environ.get("SM_TEST_DAEMON")
TOKEN = os.environ.get("SM_TEST_TOKEN")


class Sse(unittest.TestCase):
    def test_parser(self):
        lines = [b": keepalive\n", b"id: 3\n", b"event: progress\n", b'data: {"a":\n',
                 b"data: 1}\n", b"\n", b"event: status\n", b"data:{\"s\":2}\r\n", b"\r\n"]
        self.assertEqual(list(_client.sse_events(lines)),
                         [("3", "progress", '{"a":\n1}'), (None, "status", '{"s":2}')])

    def test_retry_after_forms(self):
        self.assertEqual(_client._retry_after("7"), 7.0)
        self.assertEqual(_client._retry_after(None), 1.0)
        self.assertAlmostEqual(_client._retry_after("Thu, 01 Jan 1970 00:00:10 GMT", now=4.0), 6.0)


class Fake503(unittest.TestCase):
    def test_503_retried_after_retry_after(self):
        hits = []

        class H(http.server.BaseHTTPRequestHandler):
            def do_GET(self):
                hits.append(time.monotonic())
                if len(hits) < 3:
                    self.send_response(503)
                    self.send_header("Retry-After", "1")
                    self.send_header("Content-Length", "0")
                    self.end_headers()
                    return
                body = json.dumps({"jobID": "abc", "status": "running"}).encode()
                self.send_response(200)
                self.send_header("Content-Type", "application/json")
                self.send_header("Content-Length", str(len(body)))
                self.end_headers()
                self.wfile.write(body)

            def log_message(self, *a):
                pass

        srv = http.server.HTTPServer(("127.0.0.1", 0), H)
        t = threading.Thread(target=srv.serve_forever)
        t.start()
        try:
            c = shapematch.Client("http://127.0.0.1:%d" % srv.server_port)
            self.assertEqual(c.job("abc").status()["status"], "running")
            self.assertEqual(len(hits), 3)
            self.assertGreaterEqual(hits[1] - hits[0], 0.95)
            self.assertGreaterEqual(hits[2] - hits[1], 0.95)
            hits.clear()
            c.retries = 1
            with self.assertRaises(shapematch.HTTPError) as e:
                c.job("abc").status()
            self.assertEqual(e.exception.status, 503)
        finally:
            srv.shutdown()
            t.join()
            srv.server_close()


@unittest.skipUnless(DAEMON, "no daemon (run by tests/integration/python.sh)")
class Daemon(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.tmp = tempfile.mkdtemp(prefix="sm-client-")
        cls.kw = base.tiny_case(cls.tmp)
        cls.template = os.path.join(cls.tmp, "template.mesh")
        cls.client = shapematch.Client(DAEMON, token=TOKEN)

    @classmethod
    def tearDownClass(cls):
        shutil.rmtree(cls.tmp, ignore_errors=True)

    def test_token_required(self):
        with self.assertRaises(shapematch.HTTPError) as e:
            shapematch.Client(DAEMON).submit(self.template, max_iter=5, **self.kw)
        self.assertEqual(e.exception.status, 401)

    def test_submit_wait_results_equal_local_match(self):
        job = self.client.submit(self.template, max_iter=20, **self.kw)
        seen = []
        r = job.wait(progress=lambda it, J, err: seen.append(it))
        self.assertEqual(job.status()["status"], "successful")
        self.assertEqual(r.summary["iterations"], 20)
        self.assertEqual(seen, list(range(21)))
        self.assertEqual([h["iteration"] for h in r.history], list(range(21)))
        local = shapematch.match(self.template, max_iter=20, **self.kw)
        # the worker runs the same job runner: the same vertices, bit for bit
        self.assertEqual(r.vertices.tolist(), local.vertices.tolist())
        self.assertEqual(r.displacement.tolist(), local.displacement.tolist())
        self.assertEqual(r.summary["boundary_l2"], local.summary["boundary_l2"])
        d = os.path.join(self.tmp, "res")
        job.results(d)
        for name in ("result.mesh", "result.vtu", "displacement.sol", "history.csv",
                     "summary.json"):
            self.assertTrue(os.path.getsize(os.path.join(d, name)) > 0, name)
        local.write(os.path.join(self.tmp, "local"), formats="mesh")
        with open(os.path.join(d, "result.mesh"), "rb") as a, \
                open(os.path.join(self.tmp, "local", "result.mesh"), "rb") as b:
            self.assertEqual(a.read(), b.read())

    def test_events_in_order_status_last(self):
        job = self.client.submit(self.template, max_iter=5, **self.kw)
        events = list(job.events())
        types = [e["type"] for e in events]
        self.assertEqual(types[0], "accepted")
        self.assertIn("started", types)
        self.assertEqual(types.count("progress"), 6)
        self.assertEqual(types[-2:], ["finished", "status"])
        self.assertEqual([e["seq"] for e in events[:-1]], list(range(1, len(events))))
        # resumed after event 3: the rest, no duplicate
        rest = list(job.events(after=3))
        self.assertEqual([e.get("seq") for e in rest], [e.get("seq") for e in events[3:]])

    def test_cancel_and_stop_from_progress(self):
        endless = dict(self.kw, max_iter=100000000, tol_step=1e-15, tol_stall=0)
        job = self.client.submit(self.template, **endless)
        for e in job.events():
            if e["type"] == "progress" and e["iteration"] >= 3:
                job.cancel()
                break
        with self.assertRaises(shapematch.ShapematchError) as err:
            job.wait()
        self.assertEqual(err.exception.status, "cancelled")
        self.assertEqual(job.status()["status"], "dismissed")
        # progress returning False cancels too
        job = self.client.submit(self.template, **endless)
        with self.assertRaises(shapematch.ShapematchError):
            job.wait(progress=lambda it, J, e: it < 3)
        self.assertEqual(job.status()["status"], "dismissed")

    def test_warp_of_remote_and_local_results(self):
        """warp() on a Client's result, Result.warp, RemoteResult.warp and
        Client.warp (the daemon's) give the same points; a template vertex
        goes to its final position"""
        job = self.client.submit(self.template, max_iter=12, **self.kw)
        remote = job.wait()
        local = shapematch.match(self.template, max_iter=12, **self.kw)
        tv, _ = base.read_medit_vertices(self.template)
        pts = [list(tv[i]) for i in (0, 5, 17, 40)] + [[0.013, -0.021], [0.3, 0.25]]
        a, ia = shapematch.warp(remote, points=pts)
        b, ib = local.warp(points=pts)
        c, ic = remote.warp(points=pts)
        d, idd = self.client.warp(job, points=pts)
        self.assertEqual(a.tolist(), b.tolist())
        self.assertEqual(a.tolist(), c.tolist())
        self.assertEqual(a.tolist(), d.tolist())
        self.assertEqual(list(ia), [1] * len(pts))
        self.assertEqual(list(idd), [1] * len(pts))
        final = local.vertices.tolist()
        for k, i in enumerate((0, 5, 17, 40)):
            for j in range(2):
                self.assertAlmostEqual(a[k][j], final[i][j], delta=1e-12)
        # and back: the inverse of the forward map is the identity
        back, _ = self.client.warp(remote, points=a, inverse=True)
        for p, q in zip(back.tolist(), pts):
            for j in range(2):
                self.assertAlmostEqual(p[j], q[j], delta=1e-10)
        # a mesh through the daemon, written where asked: the result's vertices
        out = os.path.join(self.tmp, "warped.mesh")
        self.assertEqual(self.client.warp(job.id, mesh=self.template, output=out), out)
        got, _ = base.read_medit_vertices(out)
        for p, q in zip(got, final):
            self.assertAlmostEqual(p[0], q[0], delta=1e-12)
            self.assertAlmostEqual(p[1], q[1], delta=1e-12)
        with self.assertRaises(ValueError):
            self.client.warp(job, mesh=self.template)  # no output
        remote.close()

    def test_batch_on_the_daemon_is_the_local_batch(self):
        """Client.batch: two targets, followed by the batch event stream to
        its end; the model's mean shape is the local batch's, byte for byte"""
        import math
        bg = self.kw["target_mesh"]
        bv, _ = base.read_medit_vertices(bg)
        sols = []
        for radius in (0.8, 0.7):
            p = os.path.join(self.tmp, "r%g.sol" % radius)
            with open(p, "w") as f:
                f.write("MeshVersionFormatted 2\nDimension 2\nSolAtVertices\n%d\n1 1\n" % len(bv))
                f.writelines("%r\n" % (math.hypot(x, y) - radius) for x, y in bv)
                f.write("End\n")
            sols.append(p)
        kw = dict(clamp_ball=self.kw["clamp_ball"], max_iter=10)
        batch = self.client.batch(self.template, [(bg, s) for s in sols], names=["r80", "r70"],
                                  model_align="none", **kw)
        seen = []
        doc = batch.wait(progress=seen.append)
        self.assertEqual(doc["status"], "successful")
        self.assertEqual(doc["counts"]["successful"], 2)
        self.assertTrue(seen and all(e["type"] == "batch" for e in seen))
        out = os.path.join(self.tmp, "model-remote")
        summary = batch.model(out)
        self.assertEqual(summary["members"], 2)
        local = os.path.join(self.tmp, "batch-local")
        shapematch.batch(self.template, [{"name": "r80", "target_mesh": bg, "target_sol": sols[0]},
                                         {"name": "r70", "target_mesh": bg, "target_sol": sols[1]}],
                         local, model_align="none", jobs=1, **kw)
        with open(os.path.join(out, "mean.mesh"), "rb") as a, \
                open(os.path.join(local, "model", "mean.mesh"), "rb") as b:
            self.assertEqual(a.read(), b.read())

    def test_a_2d_image_target_on_the_daemon_is_match(self):
        """a 2D label map (tests/cli/image2d.py's disk, NRRD dimension 2) as
        the target of the 2D example: the daemon's result is match()'s, on
        the circle within half a pixel"""
        import math
        import subprocess
        import sys
        subprocess.run([sys.executable, os.path.join(base.ROOT, "tests", "cli", "image2d.py"),
                        "write", self.tmp], check=True, capture_output=True)
        kw = dict(target_image=os.path.join(self.tmp, "disk.nrrd"), clamp_ball=(0.5, 0.5, 0.04),
                  max_iter=40)
        remote = self.client.submit(base.TEMPLATE2, **kw).wait()
        local = shapematch.match(base.TEMPLATE2, **kw)
        self.assertEqual(remote.vertices.tolist(), local.vertices.tolist())
        self.assertEqual(remote.summary["target_image"]["dims"], [66, 52, 1])
        edges = base.read_medit_block(base.TEMPLATE2, "Edges", 2)
        boundary = {a - 1 for a, b, ref in edges if ref == 1}
        v = local.vertices.tolist()
        worst = max(abs(math.dist(v[i], (0.5, 0.5)) - 0.32) for i in boundary)
        self.assertLess(worst, 0.0234375 / 2)

    def test_name_given_at_submit(self):
        # the job's name: in its status document and the job list; a bad
        # one (a control character, or too long) is a 422 naming it
        job = self.client.submit(self.template, max_iter=2, name="ball \u2192 cube #1", **self.kw)
        r = job.wait()
        self.assertEqual(job.status()["name"], "ball \u2192 cube #1")
        listed = self.client._json("GET", "/v1/jobs?limit=1000")["jobs"]
        self.assertIn("ball \u2192 cube #1", [j.get("name") for j in listed if j["jobID"] == job.id])
        # the result's figures by the summary's names (None without distance)
        self.assertEqual(r.distance, r.summary.get("distance"))
        self.assertIn("L2 of d on the boundary", repr(r))
        for bad in ("tab\tname", "x" * 201):
            with self.assertRaises(shapematch.HTTPError) as e:
                self.client.submit(self.template, max_iter=2, name=bad, **self.kw)
            self.assertEqual(e.exception.status, 422)
            self.assertIn("name:", str(e.exception))

    def test_invalid_job_is_a_422_with_the_detail(self):
        with self.assertRaises(shapematch.HTTPError) as e:
            self.client.submit(self.template, max_iter=0, **self.kw)
        self.assertEqual(e.exception.status, 422)
        self.assertIn("max_iter", str(e.exception))

    @unittest.skipUnless(os.environ.get("SM_TEST_DAEMON_RATE"), "no rate-limited daemon")
    def test_429_retried_honouring_retry_after(self):
        c = shapematch.Client(os.environ["SM_TEST_DAEMON_RATE"], token=TOKEN)
        t0 = time.monotonic()
        jobs = [c.submit(self.template, max_iter=2, **self.kw) for _ in range(2)]
        took = time.monotonic() - t0
        self.assertNotEqual(jobs[0].id, jobs[1].id)
        # the second submission got 429 with Retry-After >= 1 s and was retried
        self.assertGreaterEqual(took, 0.9)
        for j in jobs:
            j.wait()
