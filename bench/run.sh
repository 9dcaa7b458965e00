#!/usr/bin/env bash
# `make bench`: figures and ratios, not pass/fail.  Runs the matching
# benchmark on the bundled 2D and 3D examples (release build), then the
# daemon benchmark when it exists.
set -euo pipefail
cd "$(dirname "$0")/.."
BIN=build/release

# Reference figures for the authors' own C code, measured on this machine
# class on a 3D case of the paper's size (issue 2): 0.37 s per iteration,
# best boundary error 2.9e-4 reached after ~50 iterations (~20 s).
REF_PER_ITER=0.37
REF_T3E4=20

echo "== matching: examples/2d (goal: <= 3e-4 in <= 0.5 s) =="
$BIN/match_bench examples/2d "$(cat examples/2d/clamp)" 400 | tee build/bench-2d.txt
echo
echo "== matching: examples/3d (goal: <= 3e-4 in <= 3 s, then <= 1.5e-4) =="
$BIN/match_bench examples/3d "$(cat examples/3d/clamp)" 300 | tee build/bench-3d.txt
echo
awk -v ref_it="$REF_PER_ITER" -v ref_t="$REF_T3E4" '
  /^RESULT/ {
    for (i = 2; i <= NF; i++) { split($i, kv, "="); v[kv[1]] = kv[2] }
    if (v["dim"] == 3) {
      printf "3D vs the authors'"'"' code: %.1fx faster per iteration (%.3f s vs %.2f s)", ref_it / v["per_iter"], v["per_iter"], ref_it
      if (v["t3e4"] >= 0) printf ", %.1fx faster to 3e-4 (%.2f s vs ~%d s)", ref_t / v["t3e4"], v["t3e4"], ref_t
      printf ", best error %.3g vs 2.9e-4\n", v["best"]
    }
  }' build/bench-3d.txt

echo
echo "== the paper's size end to end: shapematch run on examples/3d to 2.9e-4 (goal: <= 0.5 s wall, <= 100 MB) =="
# the whole command: process start, reading, the run, the result files;
# several runs, as the machine's speed varies from one to the next
# (and its CPU time, user + sys of all threads: on a shared machine the
# wall time also counts waiting for a core; the load is printed with it)
RUNS=${BENCH_RUNS:-9}
echo "load before: $(cut -d' ' -f1-3 /proc/loadavg) (1, 5, 15 min) on $(nproc) cores"
for i in $(seq "$RUNS"); do
    /usr/bin/time -f "%e %M %U %S" $BIN/shapematch run --template examples/3d/template.mesh \
        --target-mesh examples/3d/background.mesh.gz --target-sol examples/3d/background.sol.gz \
        --clamp-ball "$(cat examples/3d/clamp)" --tol-boundary 2.9e-4 --quiet -o build/bench-run 2>&1 | tail -1
done >build/bench-paper.txt
cpu_median=$(awk '{ print $3 + $4 }' build/bench-paper.txt | sort -n | awk '{ c[NR] = $1 } END { printf "%.3f", c[int((NR + 1) / 2)] }')
sort -n build/bench-paper.txt | awk -v cpu="$cpu_median" '
  { w[NR] = $1; r = $2 / 1024; lo = NR == 1 || r < lo ? r : lo; hi = NR == 1 || r > hi ? r : hi }
  END { printf("wall: best %.3f s, median %.3f s, worst %.3f s over %d runs (median / goal of 0.5 s: %.2f); CPU (user+sys) median %.3f s; peak RSS %.1f to %.1f MiB\n",
               w[1], w[int((NR + 1) / 2)], w[NR], NR, w[int((NR + 1) / 2)] / 0.5, cpu, lo, hi) }'
echo "load after: $(cut -d' ' -f1-3 /proc/loadavg)"
python3 -c "import json; d = json.load(open('build/bench-run/summary.json')); t = d['timings'];
print('last run: %d iterations, boundary error %.3g; read %.3f s (the target, its field (%.3f s) and the measure\'s set-up, beside the elastic set-up), set-up %.3f s, solve %.3f s, step search %.3f s, sampling %.3f s'
      % (d['iterations'], d['boundary_l2'], t['read'], t['field_build'], t['setup'], t['solve'], t['step'], t['sample']))"

echo
echo "== auto against each solver (goal: auto's cost within 1.2x the faster solver's at each size) =="
# the examples' template and Gmsh balls of 100k and 300k tetrahedra
# (bench/solvers.sh alone for the other shapes and 1M)
SOLVERS_CASES=${BENCH_SOLVERS_CASES:-"example ball:100k ball:300k"} bench/solvers.sh

echo
echo "== warp: 1M points through that run's map (goal: >= 1M/s forward, >= 300k/s inverse, 2 cores) =="
# (the last run's result.mesh and displacement.sol; docs/warp.md)
$BIN/warp_bench build/bench-run 1000000
echo "-- the same map from the command line (CSV, .npy) against the Python package --"
bench/warp_cli.sh build/bench-run 1000000
echo
echo "== distance to a surface (goal: 57k points in <= 0.3 s, exact) =="
SD=build/bench-sdf
mkdir -p "$SD"
# 3D: a sphere of ~20k triangles where the 3D example's target is; the
# query points are the vertices of the example's background (57k), then
# 1M random points; 2D: a circle of ~2k segments, the 2D background
printf 'SetFactory("OpenCASCADE");\nSphere(1) = {0.5, 0.5, 0.5, 0.3};\nMesh.MeshSizeFromPoints = 0;\n' >"$SD/sphere.geo"
printf 'SetFactory("OpenCASCADE");\nCircle(1) = {0.5, 0.5, 0, 0.3};\nMesh.MeshSizeFromPoints = 0;\n' >"$SD/circle.geo"
gmsh "$SD/sphere.geo" -2 -format stl -clmax 0.0115 -nt 1 -v 1 -o "$SD/sphere.stl" >/dev/null
gmsh "$SD/circle.geo" -2 -format mesh -clmax 0.00094 -nt 1 -v 1 -o "$SD/circle.mesh" >/dev/null
# the 3D example's own target ("blob3d", examples/3d/background.geo): the
# sphere's vertices moved radially onto r = R(u), written as OBJ
python3 - "$SD/sphere.stl" "$SD/blob.obj" <<'PY'
import math, struct, sys
text = open(sys.argv[1], "rb").read()
tris = []
if text[:5] == b"solid" and b"facet" in text[:400]:
    vs = [tuple(map(float, l.split()[1:4])) for l in text.decode().splitlines() if l.strip().startswith("vertex")]
    tris = [vs[i:i + 3] for i in range(0, len(vs), 3)]
else:
    n = struct.unpack("<I", text[80:84])[0]
    for k in range(n):
        f = struct.unpack("<12f", text[84 + 50 * k: 84 + 50 * k + 48])
        tris.append([f[3:6], f[6:9], f[9:12]])
def blob(p):
    u = [p[i] - 0.5 for i in range(3)]
    r = math.sqrt(sum(x * x for x in u)); u = [x / r for x in u]
    R = (1 + 0.12 * (u[0]**3 - 3 * u[0] * u[1]**2) + 0.08 * (5 * u[2]**3 - 3 * u[2]) / 2) \
        / math.sqrt((u[0] / 0.34)**2 + (u[1] / 0.26)**2 + (u[2] / 0.22)**2)
    return [0.5 + R * x for x in u]
index, out = {}, open(sys.argv[2], "w")
for t in tris:
    ids = []
    for v in t:
        if v not in index:
            index[v] = len(index) + 1
            out.write("v %.17g %.17g %.17g\n" % tuple(blob(v)))
        ids.append(index[v])
    out.write("f %d %d %d\n" % tuple(ids))
PY
$BIN/sdf_bench "$SD/blob.obj" examples/3d/background.mesh.gz 2000
$BIN/sdf_bench "$SD/blob.obj" random:1000000:0:1 500
$BIN/sdf_bench "$SD/sphere.stl" examples/3d/background.mesh.gz 500
$BIN/sdf_bench "$SD/circle.mesh" examples/2d/background.mesh.gz 2000
# the generated (graded) background against the examples' hand-made ones:
# P1 error of the exact distance near the surface, vertex counts; 2D: the
# 2D example's target (star2d) as a 4000-segment polyline
python3 - "$SD/star.mesh" <<'PY'
import math, sys
n = 4000
with open(sys.argv[1], "w") as f:
    f.write("MeshVersionFormatted 2\nDimension 2\nVertices\n%d\n" % n)
    for i in range(n):
        t = 2 * math.pi * i / n
        r = 0.25 * (1 + 0.2 * math.cos(5 * t))
        f.write("%.17g %.17g 0\n" % (0.5 + r * math.cos(t), 0.5 + r * math.sin(t)))
    f.write("Edges\n%d\n" % n)
    for i in range(n):
        f.write("%d %d 1\n" % (i + 1, (i + 1) % n + 1))
    f.write("End\n")
PY
for band in 1 3; do
    $BIN/bg_bench "$SD/star.mesh" examples/2d/background.mesh.gz 0.0015 20000 $band
    $BIN/bg_bench "$SD/blob.obj" examples/3d/background.mesh.gz 0.009 20000 $band
done
start=$(date +%s.%N)
$BIN/shapematch sdf --surface "$SD/blob.obj" -o "$SD/out" 2>/dev/null
echo "shapematch sdf --surface blob.obj -o DIR (generated background included): $(echo "$(date +%s.%N) - $start" | bc) s"

echo
echo "== mesh readers: parse rates (goal: .meshb >= 200 MB/s) =="
mkdir -p build/bench-io
$BIN/io_bench build/bench-io 64
echo "== reading the inputs of examples/3d, the paper's size (goal: <= 0.07 s) =="
$BIN/read_bench examples/3d 9
echo "== writing the ASCII results of examples/3d (result.mesh, result.vtu, displacement.sol) =="
$BIN/write_bench examples/3d/template.mesh build/bench-io 9

echo "== the map against the solver (issue 21) and --no-clamp with AMG on 210k tetrahedra (issue 20) =="
bench/solver_maps.sh maps noclamp

echo "== stop rules: the stall rule on the examples and on Gmsh-made cases (bench/stall_cases.py) =="
# a case out of its bounds is a figure to read, not a reason to skip the
# benchmarks after it
python3 bench/stall_cases.py "$BIN" --examples ||
    echo "stall cases: a stop fell outside [needed, 2 needed] (the line marked OUT OF BOUNDS above)"

echo
bench/robust.sh

echo
bench/python.sh

echo
echo "== alignment: examples/3d moved 40 degrees and ~10 diameters, and mixed units (goal: <= 10% of the match; mixed / same ~1) =="
bench/align.sh

if [ -x bench/server_bench.sh ] && [ -x "$BIN/shapematchd" ]; then
    echo
    echo "== daemon =="
    bench/server_bench.sh
fi

if [ -x bench/cluster_bench.sh ] && [ -x "$BIN/shapematchd" ] && [ -x /usr/lib/postgresql/15/bin/initdb ]; then
    echo
    echo "== several machines on PostgreSQL =="
    bench/cluster_bench.sh
fi
