#!/usr/bin/env bash
# `auto` against each solver (issue 35): on templates of several shapes
# and sizes (a ball, a flat plate, a rod, meshed by Gmsh at a uniform
# size, cached in build/solvers/; the graded 30k example), each solver
# alone (bench/solver_bench.c, one thread, one process per solver):
# set-up (pattern, analysis, factorization or hierarchy) and a solve, as
# CPU seconds, and the peak memory it adds.  The cost of a solver is its
# set-up plus HORIZON solves (the horizon `auto`'s model uses,
# SM_SOLVER_AUTO_HORIZON); the table gives both, what auto chose, what
# its model predicted, and auto's cost over the faster solver's (goal:
# <= 1.2).  Figures only, no pass/fail.
#
#   bench/solvers.sh                          # 30k 100k 300k of each shape
#   SOLVERS_CASES="ball:1M flat:1M" bench/solvers.sh
#   SOLVERS_SKIP_CHOLMOD_ABOVE=400000 (default) runs no CHOLMOD above it
#   (the 1M ball's factor takes ~150 s and 10 GiB; the table then says so)
set -euo pipefail
cd "$(dirname "$0")/.."
BIN=build/release
CASES=${SOLVERS_CASES:-"example ball:30k flat:30k rod:30k ball:100k flat:100k rod:100k ball:300k flat:300k rod:300k"}
SOLVES=${SOLVERS_SOLVES:-20}
HORIZON=$(awk '/#define SM_SOLVER_AUTO_HORIZON/ { print $3 }' core/sm_elasticity.h)
SKIP_ABOVE=${SOLVERS_SKIP_CHOLMOD_ABOVE:-400000}
DIR=build/solvers
CLAMP="$(cat examples/3d/clamp)"
mkdir -p "$DIR"
[ -x $BIN/solver_bench ] || { echo "solvers: build first (make release)" >&2; exit 1; }

# shape:size -> a template meshed at one uniform size h, the tetrahedra
# about 4.5 V / h^3; every shape holds the clamp ball of examples/3d
template() {
    local shape=${1%%:*} label=${1##*:} n v body h out
    case "$label" in *k) n=$(( ${label%k} * 1000 )) ;; *M) n=$(( ${label%M} * 1000000 )) ;; esac
    case "$shape" in
        ball) v=0.1131; body='Sphere(1) = {0.5, 0.5, 0.5, 0.3};' ;;
        flat) v=0.0294; body='Box(1) = {0.15, 0.15, 0.47, 0.7, 0.7, 0.06};' ;;
        rod)  v=0.0123; body='Cylinder(1) = {0.1, 0.5, 0.5, 0.8, 0, 0, 0.07};' ;;
        *) echo "solvers: unknown shape $shape" >&2; exit 1 ;;
    esac
    out="$DIR/$shape-$label"
    if [ ! -s "$out/template.mesh" ]; then
        mkdir -p "$out"
        h=$(awk -v v="$v" -v n="$n" 'BEGIN { printf "%.6f", exp(log(4.5 * v / n) / 3) }')
        printf 'SetFactory("OpenCASCADE");\n%s\nMesh.MeshSizeMin = %s;\nMesh.MeshSizeMax = %s;\nMesh.MeshSizeFromPoints = 0;\nMesh.MeshSizeExtendFromBoundary = 0;\n' \
            "$body" "$h" "$h" >"$out/template.geo"
        echo "solvers: meshing $shape $label (h = $h) with Gmsh ..." >&2
        gmsh "$out/template.geo" -3 -format mesh -v 1 -o "$out/template.mesh.tmp" >/dev/null
        mv "$out/template.mesh.tmp" "$out/template.mesh"
    fi
    echo "$out/template.mesh"
}

field() { tr ' ' '\n' <<<"$1" | awk -F= -v k="$2" '$1 == k { print $2 }'; }

echo "load: $(cut -d' ' -f1-3 /proc/loadavg) (1, 5, 15 min); CPU seconds of one thread; horizon $HORIZON solves"
printf '%-11s %8s %8s %9s | %7s %8s %6s | %7s %8s %4s %6s | %8s %8s | %-7s %8s %8s %6s\n' case tets unknowns lnz \
    chol_set chol_sol chol_M amg_set amg_sol pcg amg_M cost_ch cost_amg auto pred_ch pred_amg ratio
for c in $CASES; do
    if [ "$c" = example ]; then t=examples/3d/template.mesh; else t=$(template "$c"); fi
    name=${c/:/-}
    amg=$(OMP_NUM_THREADS=1 $BIN/solver_bench "$t" "$CLAMP" amg "$SOLVES" | grep '^SOLVER')
    auto=$(OMP_NUM_THREADS=1 $BIN/solver_bench "$t" "$CLAMP" auto 0 | grep '^SOLVER')
    tets=$(field "$amg" tets)
    if [ "$tets" -le "$SKIP_ABOVE" ]; then
        chol=$(OMP_NUM_THREADS=1 $BIN/solver_bench "$t" "$CLAMP" cholmod "$SOLVES" | grep '^SOLVER')
    else
        chol=""
    fi
    echo "$name $chol" >>"$DIR/raw.txt"
    echo "$name $amg" >>"$DIR/raw.txt"
    awk -v name="$name" -v h="$HORIZON" -v chol="$chol" -v amg="$amg" -v auto="$auto" '
      function get(line, key,   n, i, kv, a) { n = split(line, a, " ")
        for (i = 1; i <= n; i++) { split(a[i], kv, "="); if (kv[1] == key) return kv[2] } return "" }
      BEGIN {
        cs = get(chol, "cpu_setup"); cv = get(chol, "cpu_solve"); cm = get(chol, "rss_mib")
        as = get(amg, "cpu_setup"); av = get(amg, "cpu_solve"); am = get(amg, "rss_mib")
        choice = get(auto, "solver")
        amg_cost = as + h * av
        if (chol != "") {
          chol_cost = cs + h * cv
          best = chol_cost < amg_cost ? chol_cost : amg_cost
          ratio = sprintf("%.2f", (choice == "cholmod" ? chol_cost : amg_cost) / best)
          chol_cost = sprintf("%.2f", chol_cost)
        } else { cs = "-"; cv = "-"; cm = "-"; ratio = "-"; chol_cost = "-" }
        printf "%-11s %8d %8d %9.3g | %7s %8s %6s | %7.3f %8.5f %4.1f %6.0f | %8s %8.2f | %-7s %8.2f %8.2f %6s\n",
          name, get(amg, "tets"), get(amg, "unknowns"), get(auto, "lnz"), cs, cv, cm,
          as, av, get(amg, "pcg"), am, chol_cost, amg_cost, choice, get(auto, "est_chol_s"),
          get(auto, "est_amg_s"), ratio
      }'
done
echo "(chol_set, amg_set: set-up s; chol_sol, amg_sol: s a solve; _M: MiB the solver adds; cost_: set-up + horizon x solve, measured; pred_: auto's model of it; ratio: auto's cost / the faster solver's)"
