#!/usr/bin/env bash
# `make bench` (and `make bench-batch`), populations (docs/populations.md):
# BATCH_TARGETS (default 16) targets on examples/3d's template (its
# background mesh, with ellipsoid-like level sets of semi-axes 0.3 (s1,
# s2, 1), s1, s2 in [0.85, 1.15], made here), each run to the default
# stop rules (BATCH_MAX_ITER caps them, default 500 = the parameter's
# default), five ways in one bench run, one after another:
#   runs 1x1     the separate `shapematch run`s one after another
#   runs 2x      the same two at a time (xargs -P 2)
#   batch j1     `shapematch batch --jobs 1` (warm starts off)
#   batch j2     `shapematch batch --jobs 2`, warm starts off
#   batch j2 w   the same with --warm-start 1
# For each: wall seconds, CPU seconds (user + sys of the whole process
# tree, from the rusage of the reaped children: the fair figure on a
# loaded machine), the peak PSS of the tree (sampled every 50 ms, shared
# copy-on-write pages counted once) and the load average around it (the
# machine is shared: the load says how far the figures compare).  Then
# the ratios (goal, issue 35: batch j2 <= 0.5x runs 2x on an idle
# machine, and never slower than runs 1x1 on a loaded one), whether the
# warm-off batch's result.mesh equal the separate runs' byte for byte,
# and the warm starts' effect: total iterations and each target's
# two-sided RMS distances against the cold batch's.  BATCH_ROUNDS (default
# 1) repeats the five in rotated order and reports the medians.  Then the
# model's build time for N targets (from the batch) and, synthetic, for N
# = 1000 shapes (BATCH_SYNTH_POINTS points, default 10000) and for N = 16
# shapes of 1M points (through the core's sm_shape_model_build, ctypes).
# Figures, not verdicts.
set -euo pipefail
cd "$(dirname "$0")/.."
BIN=$PWD/build/release/shapematch
LIB=$PWD/build/release/libshapematch.so
PY=/usr/bin/python3
[ -x "$PY" ] || PY=python3
W=$PWD/build/bench-batch
NT=${BATCH_TARGETS:-16}
ITER=${BATCH_MAX_ITER:-500}
ROUNDS=${BATCH_ROUNDS:-1}
SYNTH=${BATCH_SYNTH_POINTS:-10000}
rm -rf "$W" && mkdir -p "$W"
CLAMP=$(tr -d ' \n' <examples/3d/clamp)

"$PY" - "$W" "$NT" <<'PY'
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
    for k in range(int(sys.argv[2])):
        s1, s2 = rng.uniform(0.85, 1.15, 2)
        a = 0.3 * np.array([s1, s2, 1.0])
        d = (np.sqrt(((v / a) ** 2).sum(1)) - 1) * a.min()
        with open("%s/t%02d.sol" % (w, k), "w") as f:
            f.write("MeshVersionFormatted 2\nDimension 3\nSolAtVertices\n%d\n1 1\n" % n)
            f.write("\n".join("%.17g" % x for x in d))
            f.write("\nEnd\n")
        lst.write("t%02d,%s/examples/3d/background.mesh.gz,t%02d.sol\n" % (k, __import__("os").getcwd(), k))
PY

# tree.py CMD...: runs CMD, prints "WALL CPU PEAK_PSS_MB LOAD_BEFORE
# LOAD_AFTER" (CPU: user + sys of every process of the tree, reaped by
# CMD or its children; PSS of the tree sampled every 50 ms)
cat >"$W/tree.py" <<'PY'
import os, resource, subprocess, sys, time
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
load = lambda: float(open("/proc/loadavg").read().split()[0])
l0 = load()
r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
t0 = time.time()
proc = subprocess.Popen(sys.argv[1:], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
peak = 0
while proc.poll() is None:
    peak = max(peak, sum(pss(p) for p in tree(proc.pid)))
    time.sleep(0.05)
wall = time.time() - t0
r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
cpu = (r1.ru_utime - r0.ru_utime) + (r1.ru_stime - r0.ru_stime)
print("%.2f %.2f %.1f %.2f %.2f" % (wall, cpu, peak / 1024.0, l0, load()))
sys.exit(proc.returncode)
PY
cd "$W"
T=$OLDPWD/examples/3d/template.mesh
BG=$OLDPWD/examples/3d/background.mesh.gz
export BIN T BG CLAMP ITER
# one separate run: run1 K OUTDIR
cat >run1.sh <<'SH'
#!/usr/bin/env bash
exec "$BIN" run --template "$T" --target-mesh "$BG" --target-sol "t$1.sol" \
    --clamp-ball "$CLAMP" --max-iter "$ITER" -q -o "$2/t$1" >/dev/null 2>&1
SH
chmod +x run1.sh
names=$(seq -f %02g 0 $((NT - 1)))
export names
configs=(seq par b1 b2 b2w)
cmd_of() { # the command line of a configuration in round $2
    case $1 in
    seq) echo "bash -c 'for k in \$names; do ./run1.sh \$k seq$2 || true; done'" ;;
    par) echo "bash -c 'printf \"%s\\n\" \$names | xargs -P 2 -I{} ./run1.sh {} par$2 || true'" ;;
    b1) echo "$BIN batch --template $T --targets list.csv --clamp-ball $CLAMP --max-iter $ITER -q --jobs 1 --warm-start 0 -o b1$2" ;;
    b2) echo "$BIN batch --template $T --targets list.csv --clamp-ball $CLAMP --max-iter $ITER -q --jobs 2 --warm-start 0 -o b2$2" ;;
    b2w) echo "$BIN batch --template $T --targets list.csv --clamp-ball $CLAMP --max-iter $ITER -q --jobs 2 --warm-start 1 -o b2w$2" ;;
    esac
}
: >times.txt
for r in $(seq 1 "$ROUNDS"); do
    for k in $(seq 0 4); do # rotated: each configuration early and late
        c=${configs[$(((k + r - 1) % 5))]}
        fig=$(eval "nice $PY tree.py $(cmd_of "$c" "$r")" || true)
        echo "$c $r $fig" >>times.txt
    done
done
# bit for bit: the warm-off batches against separate runs on one thread
# (a batch's children get one when two run at once; the 3D example's
# results differ in the last bits between one and two threads, and a
# separate run takes two when a core is idle), for the first two targets
same=yes
for k in $(echo $names | cut -d' ' -f1-2); do
    OMP_NUM_THREADS=1 ./run1.sh "$k" one
    cmp -s "one/t$k/result.mesh" "b21/targets/t$k/result.mesh" || same=no
    cmp -s "one/t$k/result.mesh" "b11/targets/t$k/result.mesh" || same=no
done

"$PY" - "$same" "$ITER" "$NT" <<'PY'
import json, os, statistics, sys
same, it, nt = sys.argv[1], sys.argv[2], int(sys.argv[3])
rows = {}
for line in open("times.txt"):
    f = line.split()
    if len(f) == 7:
        rows.setdefault(f[0], []).append(list(map(float, f[2:])))
def med(c, k):
    return statistics.median(r[k] for r in rows[c]) if c in rows else float("nan")
loads = [x for v in rows.values() for r in v for x in r[3:5]]
print("batch: %d targets on examples/3d's template (to the stop rules, --max-iter %s), "
      "load %.1f-%.1f (1-min average, 2 cores, during the five)" % (nt, it, min(loads), max(loads)))
label = {"seq": "runs one after another", "par": "runs two at a time",
         "b1": "batch --jobs 1", "b2": "batch --jobs 2", "b2w": "batch --jobs 2 --warm-start 1"}
for c in ("seq", "par", "b1", "b2", "b2w"):
    print("  %-32s %7.2f s wall %7.2f s CPU  peak PSS %5.0f MB  load %.1f" %
          (label[c], med(c, 0), med(c, 1), med(c, 2), med(c, 3)))
def ratio(a, b):
    return "%.2fx wall, %.2fx CPU" % (med(a, 0) / med(b, 0), med(a, 1) / med(b, 1))
print("  batch --jobs 2 / runs two at a time:          %s (goal <= 0.5x idle)" % ratio("b2", "par"))
print("  batch --jobs 2 / runs one after another:      %s (goal <= 1x loaded)" % ratio("b2", "seq"))
print("  batch --jobs 1 / runs one after another:      %s" % ratio("b1", "seq"))
print("  warm on / off (batch --jobs 2):               %s" % ratio("b2w", "b2"))
print("  warm on / runs two at a time:                 %s" % ratio("b2w", "par"))
print("  result.mesh of the warm-off batches identical to separate runs on one thread: %s" % same)
def per_target(d):
    out = {}
    for t in json.load(open(d + "/summary.json"))["targets"]:
        p = "%s/targets/%s/summary.json" % (d, t["name"])
        if os.path.exists(p):
            r = json.load(open(p))
            out[t["name"]] = (r["iterations"], r["distance"]["result_to_target"]["rms"],
                              r["distance"]["target_to_result"]["rms"], t.get("start") or {})
    return out
cold, warm = per_target("b21"), per_target("b2w1")
common = sorted(set(cold) & set(warm))
if common:
    ic = sum(cold[n][0] for n in common)
    iw = sum(warm[n][0] for n in common)
    worst = max(max(warm[n][1] / cold[n][1], warm[n][2] / cold[n][2]) for n in common)
    started = sum(1 for n in common if warm[n][3].get("from"))
    print("  warm starts: %d of %d targets started from another's map; iterations %d warm, "
          "%d cold (%.2fx); two-sided RMS warm / cold at most %.3f" %
          (started, len(common), iw, ic, iw / ic, worst))
s = json.load(open("b21/summary.json"))
print("  template set-up once in the batch: %.2f s; shared backgrounds read once: %d; "
      "cores %d, threads per target %d" % (s["template_setup"]["seconds"],
      s.get("shared_backgrounds", 0), s.get("cores", 0), s.get("threads_per_target", 0)))
m = json.load(open("b21/model/summary.json"))
t = m["timings"]
print("  model N=%d (%d vertices): read %.3f s, build %.3f s, write %.3f s" %
      (nt, m["vertices"], t["read"], t["build"], t["write"]))
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
