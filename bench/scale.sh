#!/usr/bin/env bash
# Scaling benchmark (issue 13): the 3D example's ball template meshed by
# Gmsh at growing sizes, matched for SCALE_ITERS iterations onto the 3D
# example's target (its 345k-tetrahedron background), with each solver.
# Prints per size and solver: set-up (reading, background field and
# everything before the first iteration), s/iteration, peak RSS, bytes
# per tetrahedron, PCG iterations per solve (amg); then the fitted growth exponents (least squares on
# log-log) and where each solver's peak RSS would reach 24 GiB.  The
# times are wall clock (as a user sees them) and process CPU seconds (all
# threads; on a shared machine the wall clock includes waiting for a core).
#
#   bench/scale.sh                       # sizes 30k 100k 300k 1M, both solvers
#   SCALE_SIZES="30k 4M" SCALE_SOLVERS=amg bench/scale.sh
#   SCALE_REUSE=1 bench/scale.sh         # the table again from the last runs' logs
#   SCALE_SKIP="1M:cholmod" bench/scale.sh   # leave out size:solver pairs
#                                        # (the 1M window needs amg at 1M and
#                                        # cholmod at 30k only)
#
# Templates are cached under build/scale/ (Gmsh takes ~1 min per 1M
# tetrahedra).  Figures only, no pass/fail.  Sizes: NNk or NM tetrahedra
# (approximate: uniform mesh size h = (0.51 / N)^(1/3) in the ball of
# radius 0.3).
set -euo pipefail
cd "$(dirname "$0")/.."
BIN=build/release
SIZES=${SCALE_SIZES:-"30k 100k 300k 1M"}
SOLVERS=${SCALE_SOLVERS:-"cholmod amg"}
ITERS=${SCALE_ITERS:-10}
DIR=build/scale
CLAMP="$(cat examples/3d/clamp)"
mkdir -p "$DIR"
[ -x $BIN/match_bench ] || { echo "scale: build first (make release)" >&2; exit 1; }

count() {
    case "$1" in
        *k) echo $(( ${1%k} * 1000 )) ;;
        *M) echo $(( ${1%M} * 1000000 )) ;;
        *) echo "$1" ;;
    esac
}

# The example's template geometry with one uniform mesh size.
template() {
    local label=$1 n h out
    n=$(count "$label")
    out="$DIR/t$label"
    if [ ! -s "$out/template.mesh" ]; then
        mkdir -p "$out"
        h=$(awk -v n="$n" 'BEGIN { printf "%.6f", exp(log(0.51 / n) / 3) }')
        sed -e "s/^h_boundary = [0-9.]*;/h_boundary = $h;/" \
            -e "s/^h_interior = [0-9.]*;/h_interior = $h;/" \
            -e "s/^h_clamp = [0-9.]*;/h_clamp = $h;/" examples/3d/template.geo >"$out/template.geo"
        echo "scale: meshing $label (h = $h) with Gmsh ..." >&2
        gmsh "$out/template.geo" -3 -format mesh -v 1 -o "$out/template.mesh.tmp" >/dev/null
        mv "$out/template.mesh.tmp" "$out/template.mesh"
    fi
    ln -sf ../../../examples/3d/background.mesh.gz "$out/background.mesh.gz"
    ln -sf ../../../examples/3d/background.sol.gz "$out/background.sol.gz"
    echo "$out"
}

RESULTS="$DIR/results.txt"
: >"$RESULTS"
printf '%-6s %-8s %9s %8s %9s %8s %9s %9s %9s %8s %7s %s\n' size solver tets setup_s setup_cpu s/iter cpu/iter solve_s pcg/solve rss_MiB B/tet stop
for label in $SIZES; do
    d=$(template "$label")
    for solver in $SOLVERS; do
        case " ${SCALE_SKIP:-} " in *" $label:$solver "*) continue ;; esac
        log="$d/run-$solver.txt"
        if [ "${SCALE_REUSE:-0}" = 1 ]; then
            # print the figures of the last run again
            [ -s "$log" ] || { printf '%-6s %-8s not run\n' "$label" "$solver"; continue; }
        elif ! /usr/bin/time -v $BIN/match_bench "$d" "$CLAMP" "$ITERS" 100 "$solver" >"$log" 2>&1; then
            printf '%-6s %-8s failed: %s\n' "$label" "$solver" "$(grep -v '^\s' "$log" | tail -1)"
            continue
        fi
        awk -v label="$label" -v solver="$solver" '
          /^case / { for (i = 1; i <= NF; i++) if ($i == "elements,") tets = $(i - 1) }
          /^  iterations/ { iters = $2; stop = $4; sub(/,$/, "", stop) }
          /^  PCG iterations/ { pcg = $4; sub(/^\(/, "", pcg) }
          /^  per iteration/ { per = $3 / 1000; for (i = 1; i <= NF; i++) if ($i == "solve") solve = $(i + 1) / 1000 }
          /^  total wall/ { wall = $3 }
          /Maximum resident set size/ { rss = $NF / 1024 }
          /^  cpu time/ { setup_cpu = $8; iter_cpu = $12 }
          END {
            setup = wall - iters * per
            printf "%-6s %-8s %9d %8.2f %9.2f %8.3f %9.3f %8.3f %9s %9.0f %7.0f %s\n", label, solver, tets, setup, setup_cpu, per, iter_cpu, solve, (pcg == "" ? "-" : pcg), rss, rss * 1048576 / tets, stop
            printf "%s %s %d %.4f %.5f %.1f %.4f %.5f\n", label, solver, tets, setup, per, rss, setup_cpu, iter_cpu >> "'"$RESULTS"'"
          }' "$log"
    done
done

echo
echo "growth exponents (cost ~ tets^p, least squares over the sizes above; wall, then CPU):"
for solver in $SOLVERS; do
    awk -v solver="$solver" '
      $2 == solver { n++; x = log($3); sx += x; sxx += x * x
                     for (k = 0; k < 5; k++) { y = log($(4 + k) > 0 ? $(4 + k) : 1e-9); sy[k] += y; sxy[k] += x * y }
                     last_n = $3; last_rss = $6 }
      END {
        if (n < 2) { printf "  %-8s (fewer than 2 sizes)\n", solver; exit }
        split("set-up s/iteration peak-RSS set-up(cpu) s/iteration(cpu)", name, " ")
        d = n * sxx - sx * sx
        line = sprintf("  %-8s", solver)
        for (k = 0; k < 5; k++) { p[k] = (n * sxy[k] - sx * sy[k]) / d; line = line sprintf(" %s %.2f", name[k + 1], p[k]) }
        print line
        if (p[2] > 0)
          printf "  %-8s peak RSS would reach 24 GiB at ~%.1fM tetrahedra (extrapolated)\n", solver,
                 last_n * exp(log(24 * 1024 / last_rss) / p[2]) / 1e6
      }' "$RESULTS"
done
first=$(echo "$SIZES" | awk '{ print $1 }')
for solver in $SOLVERS; do
    awk -v first="$first" -v solver="$solver" '
      $2 == solver && $1 == first { s0 = $4; i0 = $5; n0 = $3; c0 = $7; k0 = $8 }
      $2 == solver && $1 != first && s0 > 0 {
        printf "  %-8s %s vs %s: %.1fx the elements, set-up %.1fx (cpu %.1fx), time/iteration %.1fx (cpu %.1fx)\n",
               solver, $1, first, $3 / n0, $4 / s0, (c0 > 0 ? $7 / c0 : 0), $5 / i0, (k0 > 0 ? $8 / k0 : 0) }
    ' "$RESULTS"
done
# issue 13's goal compares with the 30k template's fastest path (CHOLMOD)
awk -v first="$first" '
  $1 == first && $2 == "cholmod" { s0 = $4; i0 = $5; n0 = $3; c0 = $7; k0 = $8 }
  $1 != first && $2 == "amg" { a[++na] = $0 }
  END {
    if (!(s0 > 0)) exit
    for (j = 1; j <= na; j++) {
      split(a[j], f, " ")
      printf "  amg %s vs cholmod %s: %.1fx the elements, set-up %.1fx (cpu %.1fx), time/iteration %.1fx (cpu %.1fx)%s\n",
             f[1], first, f[3] / n0, f[4] / s0, (c0 > 0 ? f[7] / c0 : 0), f[5] / i0, (k0 > 0 ? f[8] / k0 : 0),
             (f[1] == "1M" ? " (the 1M window; goal <= 45x)" : "")
    }
  }' "$RESULTS"
