#!/usr/bin/env bash
# Warnings, not silent success: each warning of summary.json (and of
# shapematch run's stderr) triggered by a crafted input, and a distance
# whose sign is unambiguously inverted refused.  Their absence on the
# clean examples is checked by stall.sh (2D) and examples.sh (both).
source "$(dirname "$0")/../lib/cli.sh"
EX=$ROOT/examples/2d
T=$EX/template.mesh
CLAMP=(--clamp-ball 0.5,0.5,0.04)
python3 "$ROOT/tests/cli/warnings_inputs.py" "$WORK" || { echo "not ok - crafted inputs"; exit 0; }

# has_warning NAME CODE: the summary lists CODE (with a figure) and stderr says it
has_warning() {
    local out=$WORK/$1 code=$2 fig
    fig=$(jq -r --arg c "$code" '[.warnings[] | select(.code == $c) | .figure] | first // empty' \
        "$out/summary.json" 2>/dev/null)
    [ -n "$fig" ] && grep -q "^shapematch: warning: $code: " "$WORK/$1.err" && echo "$fig"
}
run() { local name=$1; shift; "$BIN" run "$@" --quiet -o "$WORK/$name" >"$WORK/$name.out" 2>"$WORK/$name.err"; }

run part --template "$T" --target-mesh "$WORK/part.mesh" --target-sol "$WORK/part.sol" "${CLAMP[@]}" --max-iter 60
if f=$(has_warning part outside-background) && awk -v f="$f" 'BEGIN { exit !(f > 0.2 && f < 0.6) }'; then
    echo "ok - a background covering part of the shape: outside-background (fraction $f)"
else
    echo "not ok - outside-background"; sed 's/^/# /' "$WORK/part.err"
fi

run inv --template "$T" --target-mesh "$WORK/full.mesh" --target-sol "$WORK/inverted.sol" "${CLAMP[@]}"
rc=$?
if [ $rc -ne 0 ] && grep -q "target_sol: the signed distance looks inverted" "$WORK/inv.err" &&
    [ ! -e "$WORK/inv/summary.json" ]; then
    echo "ok - an inverted distance (positive inside) is refused (exit $rc)"
else
    echo "not ok - inverted distance refused (exit $rc)"; sed 's/^/# /' "$WORK/inv.err"
fi

# a target elsewhere, the far field positive: the template lies outside
# the target (not an inverted sign), and so does its clamp
run away --template "$T" --target-mesh "$WORK/full2.mesh" --target-sol "$WORK/elsewhere.sol" "${CLAMP[@]}" --max-iter 5
if f=$(has_warning away misaligned) && [ "$f" = 1 ] && g=$(has_warning away clamp-outside) &&
    awk -v g="$g" 'BEGIN { exit !(g > 0.3 && g < 0.5) }' && ! grep -q sign-inverted "$WORK/away.err"; then
    echo "ok - a target beside the template: misaligned ($f), clamp-outside (d >= $g), no sign-inverted"
else
    echo "not ok - misaligned / clamp-outside"; sed 's/^/# /' "$WORK/away.err"
fi

run invsmall --template "$T" --target-mesh "$WORK/full3.mesh" --target-sol "$WORK/inverted_small.sol" --clamp-ball 0.5,0.35,0.04 --max-iter 2
if f=$(has_warning invsmall sign-inverted) && awk -v f="$f" 'BEGIN { exit !(f > 0.05 && f < 0.5) }'; then
    echo "ok - negative at the far field: sign-inverted (fraction positive $f)"
else
    echo "not ok - sign-inverted warning"; sed 's/^/# /' "$WORK/invsmall.err"
fi

run big --template "$T" --target-mesh "$WORK/big.mesh" --target-sol "$WORK/big.sol" "${CLAMP[@]}" --max-iter 2
if f=$(has_warning big units) && awk -v f="$f" 'BEGIN { exit !(f > 900 && f < 1500) }' &&
    grep -q "units: the target is [0-9.]* times larger than the template .* about 1000 times" "$WORK/big.err"; then
    echo "ok - a target 1000 times larger: units (ratio $f)"
else
    echo "not ok - units"; sed 's/^/# /' "$WORK/big.err"
fi

run clampout --template "$T" --target-mesh "$WORK/full4.mesh" --target-sol "$WORK/left.sol" --clamp-ball 0.7,0.5,0.04 --max-iter 2
if g=$(has_warning clampout clamp-outside) && awk -v g="$g" 'BEGIN { exit !(g > 0.15 && g < 0.22) }' &&
    ! grep -q misaligned "$WORK/clampout.err"; then
    echo "ok - the clamp outside an overlapping target: clamp-outside only (d >= $g)"
else
    echo "not ok - clamp-outside alone"; sed 's/^/# /' "$WORK/clampout.err"
fi

run holed --template "$T" --target-surface "$WORK/holed.mesh" "${CLAMP[@]}" --max-iter 2
if f=$(has_warning holed surface-open) && [ "$f" = 2 ] && ! grep -q surface-components "$WORK/holed.err"; then
    echo "ok - a curve with a gap: surface-open ($f open ends)"
else
    echo "not ok - surface-open"; sed 's/^/# /' "$WORK/holed.err"
fi

run two --template "$T" --target-surface "$WORK/two.mesh" "${CLAMP[@]}" --max-iter 2
if f=$(has_warning two surface-components) && [ "$f" = 3 ] && ! grep -q surface-open "$WORK/two.err"; then
    echo "ok - a surface in three pieces: surface-components ($f)"
else
    echo "not ok - surface-components"; sed 's/^/# /' "$WORK/two.err"
fi

IN=(--template "$T" --target-mesh "$EX/background.mesh.gz" --target-sol "$EX/background.sol.gz")
run short "${IN[@]}" "${CLAMP[@]}" --max-iter 2
if f=$(has_warning short above-resolution) && awk -v f="$f" 'BEGIN { exit !(f > 1) }'; then
    echo "ok - stopped far from the target: above-resolution (rms / h = $f)"
else
    echo "not ok - above-resolution"; sed 's/^/# /' "$WORK/short.err"
fi

run alpha "${IN[@]}" --no-clamp --alpha 0.01 --max-iter 3
if f=$(has_warning alpha alpha-small) && awk -v f="$f" 'BEGIN { exit !(f > 0.004 && f < 0.006) }'; then
    echo "ok - --no-clamp --alpha 0.01: alpha-small (alpha L^2/E = $f)"
else
    echo "not ok - alpha-small"; sed 's/^/# /' "$WORK/alpha.err"
fi

# the default alpha (from the scale) converges and warns of nothing
run auto "${IN[@]}" --no-clamp --tol-boundary-rel 1e-3 --max-iter 100
if [ "$(jq -r '.stop_reason + " " + (.warnings | length | tostring)' "$WORK/auto/summary.json")" = "boundary_tolerance 0" ] &&
    ! grep -q warning "$WORK/auto.err"; then
    echo "ok - --no-clamp with the default alpha converges ($(jq .iterations "$WORK/auto/summary.json") iterations), no warning"
else
    echo "not ok - default alpha"; sed 's/^/# /' "$WORK/auto.err"
fi

# a target surface with holes and a match that ends far above the
# resolution: surface-holes names the holes as a possible cause and says
# how to check the sign; the closed surface cut as short gets only
# above-resolution
STAR=$ROOT/tests/cli/star_curve.py
python3 "$STAR" write "$WORK/star.mesh" 0 0 1 && python3 "$STAR" write "$WORK/star-gaps.mesh" 0.01 0 1
run holes --template "$T" --target-surface "$WORK/star-gaps.mesh" "${CLAMP[@]}" --max-iter 2
if f=$(has_warning holes surface-holes) && [ "$f" = 40 ] && has_warning holes above-resolution >/dev/null &&
    grep -q "surface-holes: the target surface has 40 open edges (holes) in 20 open piece(s): .*shapematch sdf --surface" "$WORK/holes.err"; then
    echo "ok - a surface with holes, stopped far from it: surface-holes ($f open edges) names the check"
else
    echo "not ok - surface-holes"; sed 's/^/# /' "$WORK/holes.err"
fi
run closed --template "$T" --target-surface "$WORK/star.mesh" "${CLAMP[@]}" --max-iter 2
if has_warning closed above-resolution >/dev/null && ! grep -q surface-holes "$WORK/closed.err"; then
    echo "ok - a closed surface stopped as short: above-resolution only"
else
    echo "not ok - closed surface: no surface-holes"; sed 's/^/# /' "$WORK/closed.err"
fi
