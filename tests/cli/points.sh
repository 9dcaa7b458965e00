#!/usr/bin/env bash
# Point lists as users have them, through `shapematch warp` and
# --landmarks (proto/sm_points_csv.h): a CSV with '#' comments and a
# header naming x, y, z among an id, a quoted label with a comma and a
# note (what Slicer and landmark tools write) warps to the plain CSV's
# coordinates bit for bit with every other column kept; the output read
# back as input (its inside column replaced) warps back to the points;
# Slicer's .fcsv (LPS) and .mrk.json (RAS, x and y negated) give the
# plain CSV's points; the same landmarks as .fcsv and .mrk.json give
# --align rigid the plain CSVs' matrix.  Checked by
# tests/cli/points_check.py (Python's csv and json modules).
source "$(dirname "$0")/../lib/cli.sh"
check_rc() { if [ "$1" = 0 ]; then ok "$2"; else not_ok "$2" "${3:-}"; fi; }
WARP="python3 $ROOT/tests/cli/warp_check.py"
PTS="python3 $ROOT/tests/cli/points_check.py"
T3=$ROOT/examples/3d/template.mesh
cd "$WORK" || exit 1

mkdir -p map && $WARP make "$T3" map affine && $WARP points "$T3" p.csv 20 7 && $PTS write p.csv .
check_rc $? "a 3D map under a known affine map, the points in four files"
"$BIN" warp --result map --points p.csv -o plain.out -q
check_rc $? "warp the plain CSV"
for f in labelled.csv slicer.fcsv slicer.mrk.json; do
    "$BIN" warp --result map --points "$f" -o "$f.out" -q 2>"$f.err" &&
        $PTS same plain.out "$f.out" >"$f.same" 2>&1 && $PTS labels "$f.out" >>"$f.same" 2>&1
    check_rc $? "$f: the plain CSV's images bit for bit, its other columns kept" \
        "$(cat "$f.err" "$f.same")"
done
# the output is an input: back through the inverse, the labels still there
"$BIN" warp --result map --inverse --points labelled.csv.out -o back.out -q 2>back.err &&
    $PTS same labelled.csv back.out 1e-9 >back.same 2>&1 && $PTS labels back.out >>back.same 2>&1
check_rc $? "a warp's output warps back (--inverse) to the points, labels kept" \
    "$(cat back.err back.same)"
head -1 back.out | grep -qx "id,label,x,y,z,note,inside"
check_rc $? "one inside column, at the end" "$(head -1 back.out)"
# a line that is not a point names its line, comments counted
printf '# one\nlabel,x,y,z\n"a",0.5,0.5,0.5\n# two\n"b",0.5,zero,0.5\n' >bad.csv
"$BIN" warp --result map --points bad.csv -o bad.out 2>bad.err
rc=$?
[ $rc = 2 ] && grep -q "bad.csv: line 5, field 3 (y): 'zero' is not a finite decimal number" bad.err
check_rc $? "a bad field named by line and column (exit 2)" "rc $rc: $(cat bad.err)"

# --landmarks: the target's points are the template's moved by the affine
# map; plain CSVs, then the same points as .fcsv (template) and .mrk.json
# (target, RAS) give the same alignment
$WARP points "$T3" lt.csv 6 11 && "$BIN" warp --result map --points lt.csv -o lt.out -q &&
    cut -d, -f1-3 lt.out >ltarget.csv && $PTS write lt.csv . && cp slicer.fcsv lt.fcsv &&
    $PTS write ltarget.csv . && cp slicer.mrk.json ltarget.mrk.json
check_rc $? "landmark pairs under the known map"
# a coarse ball for the runs: the alignment's refinement costs by its
# boundary points
printf 'SetFactory("OpenCASCADE");\nSphere(1) = {0.5, 0.5, 0.5, 0.3};\n' >ball.geo
gmsh -3 ball.geo -clmax 0.08 -format msh41 -o ball.msh -v 0 >/dev/null 2>&1
check_rc $? "gmsh makes a coarse ball"
run_lm() { # NAME TEMPLATE.csv TARGET.csv
    "$BIN" run --template ball.msh --target-mesh "$ROOT/examples/3d/background.mesh.gz" \
        --target-sol "$ROOT/examples/3d/background.sol.gz" --clamp-ball 0.5,0.5,0.5,0.12 \
        --align similarity --landmarks "$2,$3" --max-iter 1 -q -o "$1" >/dev/null 2>"$1.err"
    local rc=$?
    [ $rc = 0 ] || [ $rc = 10 ]
}
run_lm lm-csv lt.csv ltarget.csv && run_lm lm-slicer lt.fcsv ltarget.mrk.json &&
    jq -e --slurpfile b lm-slicer/summary.json '.alignment.matrix == $b[0].alignment.matrix and
        .alignment.landmarks == $b[0].alignment.landmarks and .alignment.landmarks >= 6' lm-csv/summary.json >/dev/null
check_rc $? "--landmarks T.fcsv,S.mrk.json: the plain CSVs' alignment matrix" \
    "$(cat lm-csv.err lm-slicer.err; jq -c .alignment lm-csv/summary.json lm-slicer/summary.json 2>&1)"
# --image-space ras: the template's frame is RAS, Slicer's points go there
# (the LPS .fcsv negated in x and y, the RAS .mrk.json as written): the
# plain CSVs of those RAS points give the same matrix
neg() { awk -F, 'NR == 1 { print; next } { printf "%.17g,%.17g,%s\n", -$1, -$2, $3 }' "$1"; }
neg lt.csv >lt-ras.csv && neg ltarget.csv >ltarget-ras.csv
RAS=(--image-space ras)
run_lm_ras() { # NAME TEMPLATE TARGET
    "$BIN" run --template ball.msh --target-mesh "$ROOT/examples/3d/background.mesh.gz" \
        --target-sol "$ROOT/examples/3d/background.sol.gz" --clamp-ball 0.5,0.5,0.5,0.12 \
        --align similarity --landmarks "$2,$3" "${RAS[@]}" --max-iter 1 -q -o "$1" \
        >/dev/null 2>"$1.err"
    local rc=$?
    [ $rc = 0 ] || [ $rc = 10 ]
}
run_lm_ras ras-csv lt-ras.csv ltarget-ras.csv && run_lm_ras ras-slicer lt.fcsv ltarget.mrk.json &&
    jq -e --slurpfile b ras-slicer/summary.json '.alignment.matrix == $b[0].alignment.matrix' \
        ras-csv/summary.json >/dev/null
check_rc $? "--image-space ras: Slicer's markups in the RAS frame (the RAS CSVs' matrix)" \
    "$(cat ras-csv.err ras-slicer.err; jq -c .alignment.matrix ras-csv/summary.json ras-slicer/summary.json 2>&1)"
echo "1..$n"
exit $((failed > 0))
