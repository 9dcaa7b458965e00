#!/usr/bin/env bash
# `make bench` (and `make bench-batch`), populations (docs/populations.md):
# 16 targets on examples/3d's template (its background mesh, with 16
# ellipsoid-like level sets of semi-axes 0.3 (s1, s2, 1), s1, s2 in
# [0.85, 1.15], made here), run as 16 separate `shapematch run`s (one
# after another, and two at a time) and as one `shapematch batch` (--jobs
# 1 and 2): wall times and their ratios (goal: batch <= 0.6x the separate
# runs), the peak memory of the batch (the sum of the proportional set
# sizes, PSS, of its processes, sampled every 20 ms: shared copy-on-write
# pages counted once) against 16x a single run's peak; then the model's
# build time for N = 16 (from the batch) and, synthetic, for N = 1000
# shapes (BATCH_SYNTH_POINTS points, default 10000) and for N = 16 shapes
# of 1M points (through the core's sm_shape_model_build, ctypes).
# Each target stops after BATCH_MAX_ITER iterations (default 40; a full
# run of the example takes ~270) to keep the benchmark short; the
# set-up's share, and so the batch's gain, is smaller in full runs.
# Figures, not verdicts.
set -euo pipefail
cd "$(dirname "$0")/.."
BIN=$PWD/build/release/shapematch
LIB=$PWD/build/release/libshapematch.so
PY=/usr/bin/python3
[ -x "$PY" ] || PY=python3
W=$PWD/build/bench-batch
ITER=${BATCH_MAX_ITER:-40}
SYNTH=${BATCH_SYNTH_POINTS:-10000}
rm -rf "$W" && mkdir -p "$W"
CLAMP=$(tr -d ' \n' <examples/3d/clamp)

"$PY" - "$W" <<'PY'
import gzip, sys
import numpy as np
w = sys.argv[1]
tok = gzip.open("examples/3d/background.mesh.gz", "rt").read().split()
i = tok.index("Vertices")
n = int(tok[i + 1])
v = np.array(tok[i + 2:i + 2 + 4 * n], dtype=float).reshape(n, 4)[:, :3] - 0.5
rng = np.random.default_rng(25)
with open(w + "/list.csv", "w") as lst:
    lst.write("name,target_mesh,target_sol\n")
    for k in range(16):
        s1, s2 = rng.uniform(0.85, 1.15, 2)
        a = 0.3 * np.array([s1, s2, 1.0])
        d = (np.sqrt(((v / a) ** 2).sum(1)) - 1) * a.min()
        with open("%s/t%02d.sol" % (w, k), "w") as f:
            f.write("MeshVersionFormatted 2\nDimension 3\nSolAtVertices\n%d\n1 1\n" % n)
            f.write("\n".join("%.17g" % x for x in d))
            f.write("\nEnd\n")
        lst.write("t%02d,%s/examples/3d/background.mesh.gz,t%02d.sol\n" % (k, __import__("os").getcwd(), k))
PY

# peak.py CMD...: runs CMD, prints "WALL PEAK_PSS_MB" (PSS of the process
# tree, sampled every 20 ms)
cat >"$W/peak.py" <<'PY'
import os, subprocess, sys, time
def tree(root):
    kids = {}
    for p in os.listdir("/proc"):
        if p.isdigit():
            try:
                ppid = int(open("/proc/%s/stat" % p).read().rsplit(")", 1)[1].split()[1])
            except OSError:
                continue
            kids.setdefault(ppid, []).append(int(p))
    out, stack = [], [root]  # depth-first over the process tree
    while stack:
        p = stack.pop()
        out.append(p)
        stack += kids.get(p, [])
    return out
def pss(pid):
    try:
        for line in open("/proc/%d/smaps_rollup" % pid):
            if line.startswith("Pss:"):
                return int(line.split()[1])
    except OSError:
        pass
    return 0
t0 = time.time()
proc = subprocess.Popen(sys.argv[1:], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
peak = 0
while proc.poll() is None:
    peak = max(peak, sum(pss(p) for p in tree(proc.pid)))
    time.sleep(0.02)
print("%.2f %.1f" % (time.time() - t0, peak / 1024.0))
sys.exit(proc.returncode)
PY
cd "$W"
OPTS=(--clamp-ball "$CLAMP" --max-iter "$ITER" -q)
T=$OLDPWD/examples/3d/template.mesh
BG=$OLDPWD/examples/3d/background.mesh.gz
read -r single_wall single_pss < <("$PY" peak.py "$BIN" run --template "$T" --target-mesh "$BG" \
    --target-sol t00.sol "${OPTS[@]}" -o single || true)
t0=$EPOCHREALTIME
for k in $(seq -w 0 15); do
    "$BIN" run --template "$T" --target-mesh "$BG" --target-sol "t$k.sol" "${OPTS[@]}" \
        -o "sep/t$k" >/dev/null 2>&1 || true
done
t1=$EPOCHREALTIME
seq -w 0 15 | xargs -P 2 -I{} "$BIN" run --template "$T" --target-mesh "$BG" \
    --target-sol "t{}.sol" "${OPTS[@]}" -o "par/t{}" >/dev/null 2>&1 || true
t2=$EPOCHREALTIME
read -r b1_wall b1_pss < <("$PY" peak.py "$BIN" batch --template "$T" --targets list.csv \
    "${OPTS[@]}" --jobs 1 -o batch1 || true)
read -r b2_wall b2_pss < <("$PY" peak.py "$BIN" batch --template "$T" --targets list.csv \
    "${OPTS[@]}" --jobs 2 -o batch2 || true)
same=yes
for k in $(seq -w 0 15); do
    cmp -s "sep/t$k/result.mesh" "batch2/targets/t$k/result.mesh" || same=no
done

"$PY" - "$t0" "$t1" "$t2" "$single_wall" "$single_pss" "$b1_wall" "$b1_pss" "$b2_wall" \
    "$b2_pss" "$same" "$ITER" <<'PY'
import json, sys
t0, t1, t2, sw, sp, b1w, b1p, b2w, b2p = map(float, sys.argv[1:10])
same, it = sys.argv[10], sys.argv[11]
seq, par = t1 - t0, t2 - t1
s = json.load(open("batch2/summary.json"))
m = json.load(open("batch2/model/summary.json"))
print("batch: 16 targets on examples/3d's template (--max-iter %s), load %s" %
      (it, open("/proc/loadavg").read().split()[0]))
print("  16 separate runs, one after another   %7.2f s" % seq)
print("  16 separate runs, two at a time       %7.2f s" % par)
print("  batch --jobs 1                        %7.2f s   %.2fx the runs one after another" % (b1w, b1w / seq))
print("  batch --jobs 2                        %7.2f s   %.2fx the runs two at a time, %.2fx one after another" % (b2w, b2w / par, b2w / seq))
print("  template set-up (once, in the batch)  %7.2f s   count %d" % (s["template_setup"]["seconds"], s["template_setup"]["count"]))
print("  result.mesh identical to the separate runs: %s" % same)
print("  peak PSS: one run %.0f MB, batch --jobs 1 %.0f MB, --jobs 2 %.0f MB (%.2fx one run; 16x = %.0f MB)" %
      (sp, b1p, b2p, b2p / sp, 16 * sp))
t = m["timings"]
print("  model N=16 (%d vertices): read %.3f s, build %.3f s, write %.3f s" %
      (m["vertices"], t["read"], t["build"], t["write"]))
PY

"$PY" - "$LIB" "$SYNTH" <<'PY'
import ctypes as C, sys, time
import numpy as np
lib = C.CDLL(sys.argv[1])
class Opts(C.Structure):
    _fields_ = [("align", C.c_int), ("eval_modes", C.c_int), ("eval_shapes", C.c_int),
                ("samples", C.c_int), ("seed", C.c_uint64)]
class Err(C.Structure):
    _fields_ = [("code", C.c_int), ("msg", C.c_char * 512)]
lib.sm_shape_model_build.restype = C.c_int
def build(n, pts):
    rng = np.random.default_rng(1)
    base = rng.normal(size=(pts, 3))
    modes = rng.normal(size=(2, pts, 3))
    shapes = [np.ascontiguousarray(base + rng.normal() * modes[0] * 0.1 + rng.normal() * modes[1] * 0.05
                                   + 0.001 * rng.normal(size=(pts, 3))).ravel() for _ in range(n)]
    ptrs = (C.POINTER(C.c_double) * n)(*[s.ctypes.data_as(C.POINTER(C.c_double)) for s in shapes])
    m, e = C.c_void_p(), Err()
    t = time.time()
    st = lib.sm_shape_model_build(ptrs, n, C.c_int64(pts), 3, C.byref(Opts(1, 0, 0, 0, 0)), C.byref(m), C.byref(e))
    dt = time.time() - t
    lib.sm_shape_model_free(m)
    return st, dt, e.msg.decode()
for n, pts in ((1000, int(sys.argv[2])), (16, 1000000)):
    st, dt, msg = build(n, pts)
    print("  model N=%d synthetic, %d points (%.0f MB of shapes): %.2f s%s" %
          (n, pts, n * pts * 24 / 2**20, dt, "" if st == 0 else " FAILED " + msg))
print("  (N=1000 shapes of 1M points would hold 24 GB of coordinates: not run here)")
PY
