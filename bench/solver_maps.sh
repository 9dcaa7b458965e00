#!/usr/bin/env bash
# The map as a property of the inputs (issue 21), and --no-clamp with AMG
# on a large template (issue 20), for `make bench` (bench/run.sh) or alone:
#   bench/solver_maps.sh [maps|refactor|noclamp ...]   (default: maps noclamp)
# maps:     final displacement maps of --solver amg and --solver cholmod
#           (same other options, defaults otherwise) on examples/2d,
#           examples/3d and the asymmetric pull of issue 21 (a Gmsh
#           ellipsoid of 31k tetrahedra, a target with three asymmetric
#           bumps, clamp ball of radius 0.04): mean |u_amg - u_chol| over
#           the mean |u_chol| (goal <= 10%), and max over max.
# refactor: the operator on the reference (--refactor-every 100, the
#           default) or the current mesh (1, the paper's): the maps of the
#           two, and how much each moves with the solver and with
#           --step-max halved, on examples/3d and the asymmetric case.
# noclamp:  --no-clamp --solver amg on a Gmsh unit ball of ~210k
#           tetrahedra (112k unknowns) matched onto an ellipsoid: exit
#           code, iterations, boundary RMS, wall time.
set -uo pipefail
cd "$(dirname "$0")/.." || exit 1
BIN=${SM_BIN:-build/release}/shapematch
W=build/bench-maps
mkdir -p "$W"
SECTIONS=${*:-maps noclamp}

# mean and max of |a - b| over the mean and max of |b - t|, vertices of
# three Medit meshes (template t, results a and b)
cmp_maps() {
    python3 - "$1" "$2" "$3" <<'PY'
import math, sys
def read(p):
    tok = open(p).read().split()
    dim = int(tok[tok.index("Dimension") + 1])
    i = tok.index("Vertices"); n = int(tok[i + 1]); v = tok[i + 2:i + 2 + n * (dim + 1)]
    return [[float(v[k * (dim + 1) + c]) for c in range(dim)] for k in range(n)]
t, a, b = (read(p) for p in sys.argv[1:4])
sd = sm = md = mm = 0.0
for p, q, r in zip(t, a, b):
    d = math.dist(q, r); m = math.dist(r, p)
    sd += d; sm += m; md = max(md, d); mm = max(mm, m)
print("%.1f%% of the mean displacement (max %.1f%% of the max)" % (100 * sd / sm, 100 * md / mm))
PY
}

# run NAME ARGS...: shapematch run into $W/NAME, prints iterations and time
run() {
    local name=$1
    shift
    local t0 t1
    t0=$(date +%s.%N)
    "$BIN" run "$@" --quiet --format mesh -o "$W/$name" >"$W/$name.log" 2>&1
    local rc=$?
    t1=$(date +%s.%N)
    python3 -c "import json,sys; d=json.load(open('$W/$name/summary.json'));
print('  %-22s exit $rc, %4d iterations, %-18s boundary L2 %.3g, %.1f s' % ('$name', d['iterations'], d['stop_reason'], d['boundary_l2'], $t1 - $t0))" 2>/dev/null ||
        { echo "  $name: exit $rc"; tail -2 "$W/$name.log"; }
}

make_asymmetric_case() {
    [ -f "$W/asym/background.sol" ] && return
    mkdir -p "$W/asym"
    printf 'SetFactory("OpenCASCADE");\nSphere(1) = {0, 0, 0, 1};\nDilate {{0, 0, 0}, {0.3, 0.25, 0.2}} { Volume{1}; }\nTranslate {0.5, 0.5, 0.5} { Volume{1}; }\nMesh.MeshSizeFromPoints = 0;\n' >"$W/asym/template.geo"
    printf 'SetFactory("OpenCASCADE");\nSphere(1) = {0, 0, 0, 1};\nMesh.MeshSizeFromPoints = 0;\n' >"$W/asym/sphere.geo"
    gmsh "$W/asym/template.geo" -3 -format mesh -clmax 0.021 -nt 1 -v 1 -o "$W/asym/template.mesh" >/dev/null
    gmsh "$W/asym/sphere.geo" -2 -format stl -clmax 0.04 -nt 1 -v 1 -o "$W/asym/sphere.stl" >/dev/null
    # the target: the unit sphere's vertices moved radially onto an
    # ellipsoid 0.32 x 0.26 x 0.21 with three bumps in asymmetric
    # directions (the same shape as tests/unit/test_solver_accuracy.c)
    python3 - "$W/asym/sphere.stl" "$W/asym/bumps.obj" <<'PY'
import math, sys
vs = [tuple(map(float, l.split()[1:4])) for l in open(sys.argv[1]) if l.strip().startswith("vertex")]
dirs = [(1, 0.4, 0.3), (-0.2, 1, -0.5), (0.3, -0.5, 1)]
amp, width = (0.10, 0.07, 0.06), (0.5, 0.45, 0.4)
def unit(d):
    r = math.sqrt(sum(x * x for x in d)); return [x / r for x in d]
dirs = [unit(d) for d in dirs]
def moved(p):
    u = unit(p)
    r = 1 / math.sqrt((u[0] / 0.32) ** 2 + (u[1] / 0.26) ** 2 + (u[2] / 0.21) ** 2)
    for d, a, w in zip(dirs, amp, width):
        r += a * math.exp(-2 * (1 - sum(x * y for x, y in zip(u, d))) / (w * w))
    return [0.5 + r * x for x in u]
index, out = {}, open(sys.argv[2], "w")
for k in range(0, len(vs), 3):
    ids = []
    for v in vs[k:k + 3]:
        if v not in index:
            index[v] = len(index) + 1
            out.write("v %.17g %.17g %.17g\n" % tuple(moved(v)))
        ids.append(index[v])
    out.write("f %d %d %d\n" % tuple(ids))
PY
    "$BIN" sdf --surface "$W/asym/bumps.obj" -o "$W/asym" >/dev/null 2>&1
}

EX2="--template examples/2d/template.mesh --target-mesh examples/2d/background.mesh.gz --target-sol examples/2d/background.sol.gz --clamp-ball $(tr -d ' \n' <examples/2d/clamp)"
EX3="--template examples/3d/template.mesh --target-mesh examples/3d/background.mesh.gz --target-sol examples/3d/background.sol.gz --clamp-ball $(tr -d ' \n' <examples/3d/clamp)"
ASYM="--template $W/asym/template.mesh --target-mesh $W/asym/background.mesh --target-sol $W/asym/background.sol --clamp-ball 0.5,0.5,0.5,0.04"

for section in $SECTIONS; do
    case $section in
    maps)
        echo "== the map against the solver: --solver amg vs cholmod, final maps (goal <= 10%) =="
        make_asymmetric_case
        for c in ex2 ex3 asym; do
            case $c in ex2) args=$EX2; tmpl=examples/2d/template.mesh ;;
                       ex3) args=$EX3; tmpl=examples/3d/template.mesh ;;
                       asym) args=$ASYM; tmpl=$W/asym/template.mesh ;; esac
            # shellcheck disable=SC2086
            run "$c-amg" $args --solver amg
            # shellcheck disable=SC2086
            run "$c-cholmod" $args --solver cholmod
            echo "  $c: amg vs cholmod maps differ by $(cmp_maps "$tmpl" "$W/$c-amg/result.mesh" "$W/$c-cholmod/result.mesh")"
        done
        ;;
    refactor)
        echo "== the operator: reference (--refactor-every 100) vs current mesh (1) =="
        make_asymmetric_case
        for c in ex3 asym; do
            case $c in ex3) args=$EX3; tmpl=examples/3d/template.mesh ;;
                       asym) args=$ASYM; tmpl=$W/asym/template.mesh ;; esac
            for k in 100 1; do
                for s in cholmod amg; do
                    # shellcheck disable=SC2086
                    run "$c-r$k-$s" $args --solver $s --refactor-every $k
                done
                # shellcheck disable=SC2086
                run "$c-r$k-half" $args --solver cholmod --refactor-every $k --step-max 0.05
                echo "  $c, --refactor-every $k: amg vs cholmod $(cmp_maps "$tmpl" "$W/$c-r$k-amg/result.mesh" "$W/$c-r$k-cholmod/result.mesh")"
                echo "  $c, --refactor-every $k: --step-max 0.05 vs 0.1 $(cmp_maps "$tmpl" "$W/$c-r$k-half/result.mesh" "$W/$c-r$k-cholmod/result.mesh")"
            done
            echo "  $c: --refactor-every 1 vs 100 (cholmod) $(cmp_maps "$tmpl" "$W/$c-r1-cholmod/result.mesh" "$W/$c-r100-cholmod/result.mesh")"
        done
        ;;
    noclamp)
        echo "== --no-clamp --solver amg on a 210k-tetrahedron ball (112k unknowns) =="
        if [ ! -f "$W/ball/background.sol" ]; then
            mkdir -p "$W/ball"
            printf 'SetFactory("OpenCASCADE");\nSphere(1) = {0, 0, 0, 1};\nMesh.MeshSizeFromPoints = 0;\n' >"$W/ball/ball.geo"
            printf 'SetFactory("OpenCASCADE");\nSphere(1) = {0, 0, 0, 1};\nDilate {{0, 0, 0}, {1.3, 0.9, 0.8}} { Volume{1}; }\nMesh.MeshSizeFromPoints = 0;\n' >"$W/ball/ell.geo"
            gmsh "$W/ball/ball.geo" -3 -format mesh -clmax 0.045 -nt 1 -v 1 -o "$W/ball/ball.mesh" >/dev/null
            gmsh "$W/ball/ell.geo" -2 -format stl -clmax 0.05 -nt 1 -v 1 -o "$W/ball/ell.stl" >/dev/null
            "$BIN" sdf --surface "$W/ball/ell.stl" -o "$W/ball" >/dev/null 2>&1
        fi
        echo "  template: $(awk '$1 == "Tetrahedra" { getline; print $1; exit }' "$W/ball/ball.mesh") tetrahedra"
        run noclamp-amg --template "$W/ball/ball.mesh" --target-mesh "$W/ball/background.mesh" \
            --target-sol "$W/ball/background.sol" --no-clamp --solver amg
        ;;
    *)
        echo "unknown section $section (maps, refactor, noclamp)" >&2
        exit 1
        ;;
    esac
done
