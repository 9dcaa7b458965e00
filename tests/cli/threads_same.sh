#!/usr/bin/env bash
# The thread count does not change a result below the policy's
# SM_JOB_THREADS_MIN_ELEMENTS (proto/job/sm_job_threads.h): the 3D
# example (30k tetrahedra, a 22k-unknown CHOLMOD factor) for 5 iterations
# with one thread, with two, and with OpenBLAS asked for two as well
# gives the same displacement and the same summary figures bit for bit
# (the factor is taken with one BLAS thread; two made its last bits, and
# so the result files, differ from one thread's).
# run.sh: seconds 16 asan 30
source "$(dirname "$0")/../lib/cli.sh"
EX=$ROOT/examples/3d
ARGS=(run --template "$EX/template.mesh" --target-mesh "$EX/background.mesh.gz"
      --target-sol "$EX/background.sol.gz" --clamp-ball "$(tr -d ' \n' <"$EX/clamp")"
      --max-iter 5 --quiet)
run() { # NAME ENV...: the run's exit code in NAME.rc
    local name=$1
    shift
    env "$@" "$BIN" "${ARGS[@]}" -o "$WORK/$name" >"$WORK/$name.out" 2>&1
    echo $? >"$WORK/$name.rc"
}
run one OMP_NUM_THREADS=1
run two OMP_NUM_THREADS=2
run blas2 OMP_NUM_THREADS=2 OPENBLAS_NUM_THREADS=2
# 5 iterations stop on max_iter: exit 10 (not converged), the files written
for r in one two blas2; do
    if [ "$(cat "$WORK/$r.rc")" = 10 ] && [ -s "$WORK/$r/displacement.sol" ]; then
        ok "the 3D example runs 5 iterations ($r)"
    else
        not_ok "the 3D example runs 5 iterations ($r): exit $(cat "$WORK/$r.rc")" "$(cat "$WORK/$r.out")"
    fi
done
figures() { jq -c '[.iterations, .boundary_rms, .J_final, .distance]' "$WORK/$1/summary.json" 2>/dev/null; }
for r in two blas2; do
    if cmp -s "$WORK/one/displacement.sol" "$WORK/$r/displacement.sol"; then
        ok "the displacement with $r threads is the one-thread displacement bit for bit"
    else
        not_ok "the displacement with $r threads is the one-thread displacement bit for bit"
    fi
    a=$(figures one)
    b=$(figures "$r")
    if [ -n "$a" ] && [ "$a" = "$b" ]; then
        ok "summary.json's figures with $r threads are the one-thread figures"
    else
        not_ok "summary.json's figures with $r threads are the one-thread figures" "one: $a" "$r: $b"
    fi
done
echo "1..$n"
exit 0
