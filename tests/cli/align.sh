#!/usr/bin/env bash
# Pre-alignment through `shapematch run` (params align, --landmarks): on
# examples/2d moved by a known rigid motion (30 degrees, 100 diameters),
# and with its target in millimetres: the alignment puts the template's
# centre where it belongs (the disk's rotation is free: the landmarks
# case checks the whole matrix against the inverse motion), the matched
# result is as good as the example's own (hand-aligned) run, within 1.5x,
# and displacement.sol is the whole map; --align none is the run without
# the parameter byte for byte; misaligned fires on the moved template and
# not on the examples; bad landmarks are refused with a message.
source "$(dirname "$0")/../lib/cli.sh"
EX=$ROOT/examples/2d
python3 "$ROOT/tests/cli/align_inputs.py" "$EX" "$WORK" || { echo "not ok - align inputs"; exit 0; }
TARGET=(--target-mesh "$EX/background.mesh.gz" --target-sol "$EX/background.sol.gz")
run() { local name=$1; shift; "$BIN" run "$@" -o "$WORK/$name" >"$WORK/$name.out" 2>"$WORK/$name.err"; }
# the moved clamp centre: (0.5, 0.5) through the motion of align_inputs.py
MC=$(python3 -c 'import math; a=math.radians(30); print("%.17g,%.17g" % (math.cos(a)*.5-math.sin(a)*.5+40, math.sin(a)*.5+math.cos(a)*.5-30))')

run hand --template "$EX/template.mesh" "${TARGET[@]}" --clamp-ball 0.5,0.5,0.04
run none --template "$EX/template.mesh" "${TARGET[@]}" --clamp-ball 0.5,0.5,0.04 --align none
if cmp -s "$WORK/hand/result.mesh" "$WORK/none/result.mesh" &&
    cmp -s "$WORK/hand/displacement.sol" "$WORK/none/displacement.sol" &&
    [ "$(jq 'has("alignment")' "$WORK/none/summary.json")" = false ] &&
    [ "$(jq -r .parameters.align "$WORK/none/summary.json")" = none ] &&
    ! grep -q misaligned "$WORK/hand.err"; then
    echo "ok - --align none: the same result.mesh and displacement.sol byte for byte, no alignment, no misaligned"
else
    echo "not ok - --align none unchanged"; sed 's/^/# /' "$WORK/none.err"
fi
HAND=$(jq .boundary_rms "$WORK/hand/summary.json")

run off --template "$WORK/moved.mesh" "${TARGET[@]}" --clamp-ball "$MC,0.04" --max-iter 1
if grep -q "^shapematch: warning: misaligned: .*--align" "$WORK/off.err" &&
    [ "$(jq '[.warnings[] | select(.code == "misaligned")] | length' "$WORK/off/summary.json")" = 1 ]; then
    echo "ok - the moved template without --align: misaligned, naming --align"
else
    echo "not ok - misaligned on the moved template"; sed 's/^/# /' "$WORK/off.err"
fi

# centre_error DIR X Y: |A (X,Y) + b - (0.5, 0.5)| from summary.json's matrix
centre_error() {
    jq -r --argjson x "$2" --argjson y "$3" '.alignment.matrix as $m |
        ((($m[0]*$x + $m[1]*$y + $m[2] - 0.5) | fabs) + (($m[3]*$x + $m[4]*$y + $m[5] - 0.5) | fabs))' \
        "$WORK/$1/summary.json"
}
run rigid --template "$WORK/moved.mesh" "${TARGET[@]}" --clamp-ball "$MC,0.04" --align rigid
rc=$?
E=$(centre_error rigid "${MC%,*}" "${MC#*,}")
RMS=$(jq .boundary_rms "$WORK/rigid/summary.json")
# the whole map: result = moved template + displacement, at one vertex
MAP=$(python3 - "$WORK" <<'PY'
import sys
w = sys.argv[1]
def verts(path):
    lines = open(path).read().split("\n")
    i = [k for k, l in enumerate(lines) if l.strip() == "Vertices"][0]
    n = int(lines[i + 1])
    return [tuple(map(float, lines[i + 2 + k].split()[:2])) for k in range(n)]
t, r = verts(w + "/moved.mesh"), verts(w + "/rigid/result.mesh")
lines = open(w + "/rigid/displacement.sol").read().split("\n")
i = [k for k, l in enumerate(lines) if l.strip() == "SolAtVertices"][0]
d = [tuple(map(float, l.split())) for l in lines[i + 3:] if l.strip() and l.strip() != "End"][:len(t)]
print(max(abs(t[k][c] + d[k][c] - r[k][c]) for k in range(len(t)) for c in range(2)))
PY
)
if [ $rc -eq 0 ] && [ -n "$MAP" ] && awk -v e="$E" -v r="$RMS" -v h="$HAND" -v m="$MAP" \
    'BEGIN { exit !(e < 5e-4 && r <= 1.5 * h && m < 1e-9) }' &&
    grep -q "^shapematch: aligned (rigid, from moments)" "$WORK/rigid.err"; then
    echo "ok - 30 degrees and 100 diameters away, --align rigid: centre within $E, RMS $RMS (hand-aligned $HAND), displacement the whole map ($MAP)"
else
    echo "not ok - --align rigid on the moved example (exit $rc, centre $E, RMS $RMS, hand $HAND, map $MAP)"
    sed 's/^/# /' "$WORK/rigid.err"
fi

# the disk's rotation is free (its misfit hardly changes with it), so the
# landmarks case checks the start was taken and the centre; the exact
# Kabsch/Umeyama matrices are test_align's
run lm --template "$WORK/moved.mesh" "${TARGET[@]}" --clamp-ball "$MC,0.04" --align rigid \
    --landmarks "$WORK/lm_template.csv,$WORK/lm_target.csv" --max-iter 3
E=$(centre_error lm "${MC%,*}" "${MC#*,}")
if [ "$(jq .alignment.landmarks "$WORK/lm/summary.json")" = 4 ] &&
    awk -v e="$E" 'BEGIN { exit !(e < 5e-4) }' &&
    grep -q "aligned (rigid, from 4 landmarks)" "$WORK/lm.err"; then
    echo "ok - --landmarks: the start from 4 pairs, centre within $E"
else
    echo "not ok - landmarks (centre $E)"; sed 's/^/# /' "$WORK/lm.err"
fi

run mm --template "$EX/template.mesh" --target-mesh "$WORK/mm.mesh" --target-sol "$WORK/mm.sol" \
    --clamp-ball 0.5,0.5,0.04 --align similarity
S=$(jq .alignment.scale "$WORK/mm/summary.json")
RMSMM=$(jq .boundary_rms "$WORK/mm/summary.json")
# the scale follows the target's extent (two-sided): the star r = 0.25 (1
# + 0.2 cos 5t) encloses 1.02 times the disk's area, so the disk's scale
# is 1000 sqrt(1.02) = 1009.95 by the area ratio, within 0.5%
if awk -v s="$S" -v r="$RMSMM" -v h="$HAND" 'BEGIN { e = 1000 * sqrt(1.02); exit !((s - e) / e < 0.005 && (e - s) / e < 0.005 && r <= 1.5 * 1000 * h) }' &&
    ! grep -q "warning: units" "$WORK/mm.err"; then
    echo "ok - a target in millimetres, --align similarity: scale $S (the area ratio's 1009.95), RMS $RMSMM (hand-aligned x1000: $HAND)"
else
    echo "not ok - millimetres (scale $S, RMS $RMSMM)"; sed 's/^/# /' "$WORK/mm.err"
fi

# refusals: landmarks without an alignment, malformed, unequal, degenerate
bad() { # NAME EXPECTED-EXIT PATTERN ARGS...
    local name=$1 want=$2 pattern=$3; shift 3
    run "$name" --template "$WORK/moved.mesh" "${TARGET[@]}" --clamp-ball "$MC,0.04" "$@"
    local rc=$?
    if [ $rc -eq "$want" ] && grep -q -- "$pattern" "$WORK/$name.err"; then
        echo "ok - refused ($rc): $pattern"
    else
        echo "not ok - $name: exit $rc, expected $want and '$pattern'"; sed 's/^/# /' "$WORK/$name.err"
    fi
}
LM="$WORK/lm_template.csv"
bad lm_none 1 "--landmarks needs an alignment: add --align" --landmarks "$LM,$WORK/lm_target.csv"
bad lm_one 1 "--landmarks: give TEMPLATE.csv,TARGET.csv" --align rigid --landmarks "$LM"
bad lm_bad 2 "lm_bad.csv: line 2, field 2: 'zero' is not a finite decimal number" --align rigid --landmarks "$LM,$WORK/lm_bad.csv"
bad lm_count 2 "4 template point(s) and 3 target point(s)" --align rigid --landmarks "$LM,$WORK/lm_three.csv"
bad lm_same 2 "the target points are all at one place" --align rigid --landmarks "$LM,$WORK/lm_same.csv"
bad align_bad 1 "--align: 'shear' is not none, rigid, similarity or affine" --align shear
