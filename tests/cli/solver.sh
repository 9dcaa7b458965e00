#!/usr/bin/env bash
# --solver of `shapematch run`: amg and cholmod both match the 2D example
# (amg reaches cholmod's boundary error within 5% in at most 30% more
# iterations, as tests/unit/test_solver.c states), the choice is recorded in
# summary.json's parameters, and an unknown name is a usage error (exit 1)
# that names the choices.
source "$(dirname "$0")/../lib/cli.sh"
EX=$ROOT/examples/2d
ARGS="--template $EX/template.mesh --target-mesh $EX/background.mesh.gz --target-sol $EX/background.sol.gz --clamp-ball $(tr -d ' \n' <"$EX/clamp") --max-iter 40 --quiet --format mesh"
# shellcheck disable=SC2086
"$BIN" run $ARGS --solver cholmod -o "$WORK/cholmod" >"$WORK/cholmod.out" 2>&1
rc_c=$?
l2=$(jq -r '.. | objects | select(has("boundary_l2")) | .boundary_l2' "$WORK/cholmod/summary.json" 2>/dev/null | head -1)
tol=$(awk -v x="${l2:-0}" 'BEGIN { printf "%.6g", 1.05 * x }')
# shellcheck disable=SC2086
"$BIN" run $ARGS --solver amg --max-iter 52 --tol-boundary "$tol" -o "$WORK/amg" >"$WORK/amg.out" 2>&1
rc_a=$?
if [ $rc_c = 0 ] && [ $rc_a = 0 ]; then
    echo "ok - --solver cholmod and --solver amg both run the 2D example"
else
    echo "not ok - runs with both solvers (exit $rc_c / $rc_a)"
    sed 's/^/# /' "$WORK/cholmod.out" "$WORK/amg.out"
fi
stop=$(jq -r '.. | objects | select(has("stop_reason")) | .stop_reason' "$WORK/amg/summary.json" 2>/dev/null | head -1)
if [ -n "$l2" ] && [ "$stop" = boundary_tolerance ]; then
    echo "ok - amg reaches cholmod's boundary error after 40 iterations within 5% ($tol) in at most 52"
else
    echo "not ok - amg to cholmod's boundary error $l2 (+5%): stop '$stop'"
fi
if jq -e '.. | objects | select(has("solver")) | .solver == "amg"' "$WORK/amg/summary.json" >/dev/null 2>&1; then
    echo "ok - summary.json records solver amg"
else
    echo "not ok - summary.json records the solver"; head -c 600 "$WORK/amg/summary.json" | sed 's/^/# /'
fi
# shellcheck disable=SC2086
"$BIN" run $ARGS --solver lu -o "$WORK/bad" >"$WORK/bad.out" 2>&1
rc=$?
if [ $rc -eq 1 ] && grep -q "auto, cholmod or amg" "$WORK/bad.out"; then
    echo "ok - --solver lu: usage error naming the choices"
else
    echo "not ok - --solver lu (exit $rc)"; sed 's/^/# /' "$WORK/bad.out"
fi
