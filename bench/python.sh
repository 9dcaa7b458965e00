#!/usr/bin/env bash
# `make bench` (from bench/run.sh): what the Python package costs over the
# command.  On each bundled example, alternating, BENCH_PY_RUNS times
# (default 7), median wall times of
#   cli     shapematch run ... -o DIR          (process, job, result files)
#   script  python3 -c 'shapematch.match(...).write(DIR)'  (the same files;
#           interpreter start and import included)
#   match   shapematch.match(...) in a running interpreter (no files)
# Goal (issue 26): script within 5% of cli.  2D: the default stop rules;
# 3D: --tol-boundary 2.9e-4 (the paper's size end to end, as bench/run.sh).
set -euo pipefail
cd "$(dirname "$0")/.."
BIN=${SM_BIN:-build/release}
RUNS=${BENCH_PY_RUNS:-7}
W=$(mktemp -d)
trap 'rm -rf "$W"' EXIT
PY=/usr/bin/python3
export PYTHONPATH=$PWD/python SHAPEMATCH_LIBDIR=$PWD/$BIN

echo "== Python: shapematch.match against shapematch run (median of $RUNS; goal: script within 5% of cli) =="
$PY - "$BIN" "$RUNS" "$W" <<'EOF'
import os, statistics, subprocess, sys, time
import shapematch

BIN, RUNS, W = sys.argv[1], int(sys.argv[2]), sys.argv[3]
cases = {
    "2d": dict(ball="0.5,0.5,0.04", extra={}),
    "3d": dict(ball="0.5,0.5,0.5,0.05", extra={"tol_boundary": 2.9e-4}),
}
for name, c in cases.items():
    ex = "examples/" + name
    files = dict(target_mesh=ex + "/background.mesh.gz", target_sol=ex + "/background.sol.gz")
    ball = tuple(float(x) for x in c["ball"].split(","))
    cli = [BIN + "/shapematch", "run", "--template", ex + "/template.mesh",
           "--target-mesh", files["target_mesh"], "--target-sol", files["target_sol"],
           "--clamp-ball", c["ball"], "--quiet", "-o", W + "/cli"]
    for k, v in c["extra"].items():
        cli += ["--" + k.replace("_", "-"), repr(v)]
    script = ("import shapematch; shapematch.match(%r, target_mesh=%r, target_sol=%r, "
              "clamp_ball=%r, **%r).write(%r)" % (ex + "/template.mesh", files["target_mesh"],
                                                 files["target_sol"], ball, c["extra"], W + "/py"))
    t = {"cli": [], "script": [], "match": []}
    for _ in range(RUNS):
        t0 = time.perf_counter()
        subprocess.run(cli, check=True)
        t["cli"].append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        subprocess.run([sys.executable, "-c", script], check=True)
        t["script"].append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        r = shapematch.match(ex + "/template.mesh", clamp_ball=ball, **files, **c["extra"])
        t["match"].append(time.perf_counter() - t0)
        r.close()
    m = {k: statistics.median(v) for k, v in t.items()}
    same = open(W + "/cli/result.mesh", "rb").read() == open(W + "/py/result.mesh", "rb").read()
    print("%s: cli %.3f s, script %.3f s (%+.1f%%), match in-process %.3f s (%+.1f%%); "
          "%d iterations; result.mesh identical: %s" % (
              name, m["cli"], m["script"], 100 * (m["script"] / m["cli"] - 1), m["match"],
              100 * (m["match"] / m["cli"] - 1), r.summary["iterations"], "yes" if same else "NO"))
EOF
