#!/usr/bin/env bash
# Targets from a surface through the daemon (issue 9): the multipart part
# target_surface of POST /v1/jobs, with a generated background or with
# target_mesh, against a real daemon and surfaces made by the real gmsh:
#   - template + target_surface ends successful, its summary.json carries
#     the surface's health report, and its boundary error is the one
#     `shapematch run --target-surface` reaches on the same inputs;
#   - template + target_surface + target_mesh: the background is the one
#     given (not generated);
#   - target_surface with target_sol is a 422 naming the conflict; a
#     malformed STL a 422 naming the part; no target at all a 400 naming
#     the missing part;
#   - the generated background and distance the check built are kept
#     (inputs/checked, job.json's "checked") and reused by the worker;
#     the results are byte-identical to the worker's own build (none
#     kept, a stale key, a damaged file); none kept with target_mesh;
#   - `shapematch submit --target-surface S --wait` end to end;
#   - the process description lists target_surface;
#   - params background_size / background_padding size the generated
#     background: the summary reports them (and the defaults otherwise),
#     a smaller size gives more vertices, the same as `run` with the
#     flags; with target_mesh (or no target_surface) a 422 naming the
#     param and the conflict, a bad value (0, negative, string) the params
#     error, also through POST /v1/processes/match/execution; a background
#     beyond --max-vertices a 413; `submit --background-size` sends it;
#   - a target surface in millimetres against a template in metres: a 422
#     naming target_surface, the ratio, the likely units and
#     params.background_size, before any background is generated (not a
#     413 for a background sized in the wrong unit); with
#     params.background_size given, accepted (201).
source "$(dirname "$0")/lib.sh"

d=$WORK/case
mkdir -p "$d"
cp "$ROOT/tests/lib/case/ball.geo" "$d/"
cp "$ROOT/tests/lib/case/small_ball.geo" "$d/small.geo"
(cd "$d" && gmsh ball.geo -2 -format stl -clmax 0.15 -nt 1 -v 1 -o sphere.stl &&
    gmsh ball.geo -3 -format msh41 -clmax 0.3 -nt 1 -v 1 -o ball.msh &&
    gmsh small.geo -3 -format msh41 -clmax 0.3 -nt 1 -v 1 -o small.msh &&
    printf 'Dilate {{0, 0, 0}, {1000, 1000, 1000}} { Volume{1}; }\n' | cat ball.geo - >mm.geo &&
    gmsh mm.geo -2 -format stl -clmax 150 -nt 1 -v 1 -o mm.stl) >"$d/gmsh.log" 2>&1
if [ -s "$d/sphere.stl" ] && [ -s "$d/ball.msh" ] && [ -s "$d/small.msh" ] && [ -s "$d/mm.stl" ]; then
    ok "gmsh made the sphere STL and the .msh balls"
else
    not_ok "gmsh made the sphere STL and the .msh balls" "$(tail -5 "$d/gmsh.log")"
    exit 1
fi
STL=$d/sphere.stl
TPL=$d/small.msh
BG=$d/ball.msh
PARAMS='{"clamp": {"kind": "ball", "center": [0, 0, 0], "radius": 0.5}, "max_iter": 30}'

# --max-vertices 50000: far above every input here, below a background
# of size 0.05 (73k vertices)
if ! start_daemon surface --workers 1 --worker-threads 1 --max-vertices 50000; then
    not_ok "the daemon starts"
    exit 1
fi
ok "the daemon starts"

# post NAME CURL-ARGS...: POST /v1/jobs, the answer in $WORK/NAME.json,
# the status code printed
post() {
    local name=$1
    shift
    hcurl "${AUTH[@]}" -o "$WORK/$name.json" -w '%{http_code}' "$@" "$BASE/v1/jobs" 2>"$WORK/$name.err"
}

# the reference: the same job run locally, one thread as the worker
OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 "$BIN/shapematch" run --template "$TPL" \
    --target-surface "$STL" --clamp-ball 0,0,0,0.5 --max-iter 30 --quiet -o "$WORK/run" \
    >/dev/null 2>"$WORK/run.err"
check "shapematch run --target-surface gives the reference" test -f "$WORK/run/summary.json"

# ------------------------------------------ template + target_surface
code=$(post gen -F "template=@$TPL" -F "target_surface=@$STL" -F "params=$PARAMS")
ID=$(jq -r '.jobID // empty' "$WORK/gen.json" 2>/dev/null)
if [ "$code" = 201 ] && [ -n "$ID" ] && wait_final "$ID" 120 && state_is "$ID" successful; then
    ok "template + target_surface (generated background): the job ends successful"
else
    not_ok "template + target_surface ends successful" "code $code, id '$ID', state $(job_state "$ID")" \
        "$(cat "$WORK/gen.json")"
fi
JOB=$SPOOL/jobs/$ID
jq -e '.target_surface == "inputs/target_surface.surface" and (has("target_sol") | not) and
       (has("target_mesh") | not)' "$JOB/job.json" >/dev/null
check "job.json names the stored target_surface, no target_mesh nor target_sol" test $? = 0
msg=$(python3 - "$JOB/results/summary.json" "$WORK/run/summary.json" <<'PY'
import json, sys
d, r = (json.load(open(p)) for p in sys.argv[1:3])
h = d.get("target_surface", {})
ok = (d["inputs"].get("target_surface") == "inputs/target_surface.surface" and h.get("open_edges") == 0
      and h.get("components") == 1 and h.get("background_generated") is True
      and h.get("background_vertices") == r["target_surface"]["background_vertices"])
ed, er = d["boundary_l2"], r["boundary_l2"]
print("boundary L2 %.6e (daemon) vs %.6e (run), %d iterations vs %d"
      % (ed, er, d["iterations"], r["iterations"]))
sys.exit(0 if ok and abs(ed - er) <= 1e-9 * er and d["iterations"] == r["iterations"] else 1)
PY
)
check "the summary has the health report; $msg" test $? = 0

# ------------------ the check's background and distance, reused (issue 35)
# the upload's check built the background and the distance: kept in the
# job's inputs/ and named in job.json with the key of the inputs, and the
# worker read them instead of building them again
if jq -e '.checked.background == "inputs/checked/background.meshb" and
          .checked.distance == "inputs/checked/distance.solb" and (.checked.key | length) == 16' \
    "$JOB/job.json" >/dev/null && [ -s "$JOB/inputs/checked/background.meshb" ] &&
    [ -s "$JOB/inputs/checked/distance.solb" ] &&
    grep -q "are reused (inputs/checked/background.meshb)" "$JOB/worker.log"; then
    ok "the check's background and distance are kept in inputs/checked and reused by the worker"
else
    not_ok "the check's background and distance are kept and reused" \
        "$(jq -c .checked "$JOB/job.json" 2>&1; ls "$JOB/inputs" "$JOB/inputs/checked" 2>&1; tail -3 "$JOB/worker.log")"
fi
# the same job run again by the worker program on copies of its folder:
# with the kept files (reused), without them (built) and with a key that
# is not the job's (built): the result files are the same to the byte,
# and the daemon's too
same=1
worker_again "$JOB" result.meshb displacement.solb result.mesh displacement.sol || same=0
if [ "$same" = 1 ] && grep -q 'are reused' "$WORK/again-kept/worker.log" &&
    ! grep -q 'are reused' "$WORK/again-none/worker.log" &&
    ! grep -q 'are reused' "$WORK/again-stale/worker.log"; then
    ok "results with the reused background and distance are byte-identical to those built again (none kept, a stale key)"
else
    not_ok "results with and without the reused distance are byte-identical" \
        "same $same; $(tail -2 "$WORK"/again-*/worker.log)"
fi
# a damaged kept file: the worker builds them instead (same results)
worker_copy "$JOB" damaged '' >/dev/null 2>&1
printf 'damaged' >"$WORK/again-damaged/inputs/checked/distance.solb"
rm -rf "$WORK/again-damaged/results"
OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 "$BIN/shapematch-worker" "$WORK/again-damaged" 3>/dev/null \
    2>"$WORK/again-damaged/worker.log"
if cmp -s "$JOB/results/result.meshb" "$WORK/again-damaged/results/result.meshb" &&
    grep -q 'is not used' "$WORK/again-damaged/worker.log"; then
    ok "a damaged kept distance is not used: built again, the same results"
else
    not_ok "a damaged kept distance is built again" "$(tail -3 "$WORK/again-damaged/worker.log")"
fi

# ----------------------------- template + target_surface + target_mesh
code=$(post bg -F "template=@$TPL" -F "target_surface=@$STL" -F "target_mesh=@$BG" -F "params=$PARAMS")
ID2=$(jq -r '.jobID // empty' "$WORK/bg.json" 2>/dev/null)
if [ "$code" = 201 ] && [ -n "$ID2" ] && wait_final "$ID2" 120 && state_is "$ID2" successful &&
    jq -e --argjson n "$(grep -A2 '^\$Nodes' "$BG" | sed -n 2p | cut -d' ' -f2)" \
        '.target_surface.background_generated == false and .target_surface.background_vertices == $n
         and (.inputs.target_mesh | startswith("inputs/target_mesh."))' \
        "$SPOOL/jobs/$ID2/results/summary.json" >/dev/null; then
    ok "template + target_surface + target_mesh: successful, the distance on the given background"
    jq -e 'has("checked") | not' "$SPOOL/jobs/$ID2/job.json" >/dev/null
    check "with target_mesh the check keeps no background (nothing generated)" test $? = 0
else
    not_ok "template + target_surface + target_mesh" "code $code, state $(job_state "$ID2")" \
        "$(cat "$WORK/bg.json" "$SPOOL/jobs/$ID2/results/summary.json" 2>/dev/null | head -c 800)"
fi

# ------------------------- params background_size / background_padding
# the default job above reports what sized its background
jq -e '.target_surface.background_size > 0 and .target_surface.background_padding == 0.1' \
    "$JOB/results/summary.json" >/dev/null
check "the summary reports the default background size ($(jq .target_surface.background_size \
    "$JOB/results/summary.json")) and padding 0.1" test $? = 0
FINE=0.08
code=$(post fine -F "template=@$TPL" -F "target_surface=@$STL" \
    -F "params=${PARAMS%\}}, \"background_size\": $FINE, \"background_padding\": 0.2}")
ID3=$(jq -r '.jobID // empty' "$WORK/fine.json" 2>/dev/null)
if [ "$code" = 201 ] && [ -n "$ID3" ] && wait_final "$ID3" 120 && state_is "$ID3" successful; then
    ok "background_size $FINE, background_padding 0.2: the job ends successful"
else
    not_ok "background_size $FINE ends successful" "code $code, state $(job_state "$ID3")" \
        "$(head -c 600 "$WORK/fine.json")"
fi
jq -e --argjson h "$FINE" '.params.background_size == $h and .params.background_padding == 0.2' \
    "$SPOOL/jobs/$ID3/job.json" >/dev/null
check "job.json keeps background_size and background_padding for the worker" test $? = 0
OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 "$BIN/shapematch" run --template "$TPL" \
    --target-surface "$STL" --clamp-ball 0,0,0,0.5 --max-iter 30 --background-size "$FINE" \
    --background-padding 0.2 --quiet -o "$WORK/run-fine" >/dev/null 2>"$WORK/run-fine.err"
msg=$(python3 - "$SPOOL/jobs/$ID3/results/summary.json" "$JOB/results/summary.json" \
    "$WORK/run-fine/summary.json" "$FINE" 2>&1 <<'PY'
import json, sys
fine, dflt, run = (json.load(open(p)) for p in sys.argv[1:4])
h = float(sys.argv[4])
f, d, r = fine["target_surface"], dflt["target_surface"], run["target_surface"]
print("%d background vertices with size %g (padding %g) vs %d with the default %.4g; run: %d"
      % (f["background_vertices"], f["background_size"], f["background_padding"],
         d["background_vertices"], d["background_size"], r["background_vertices"]))
ok = (f["background_generated"] and f["background_size"] == h and f["background_padding"] == 0.2
      and h < d["background_size"] and f["background_vertices"] > 1.5 * d["background_vertices"]
      and f["background_vertices"] == r["background_vertices"]
      and abs(fine["boundary_l2"] - run["boundary_l2"]) <= 1e-9 * run["boundary_l2"])
sys.exit(0 if ok else 1)
PY
)
check "the summary shows the size and padding used; $msg" test $? = 0

# refusals: the param named in invalid-params, the conflict in the detail
bad_background() { # NAME EXPECTED-PARAM ERE CURL-ARGS...
    local name=$1 param=$2 re=$3
    shift 3
    local code
    code=$(post "$name" "$@")
    if [ "$code" = 422 ] &&
        jq -e --arg p "$param" --arg re "$re" '.status == 422 and (.detail | test($re)) and
            .["invalid-params"][0].name == $p' "$WORK/$name.json" >/dev/null; then
        ok "$name: 422 \"$(jq -r .detail "$WORK/$name.json" | head -c 160)\""
    else
        not_ok "$name: 422 naming $param" "got $code" "$(head -c 600 "$WORK/$name.json")"
    fi
}
bad_background bg_with_mesh params.background_size \
    '^params.background_size: .*generated background \(target_surface without target_mesh\): target_mesh is given' \
    -F "template=@$TPL" -F "target_surface=@$STL" -F "target_mesh=@$BG" \
    -F "params=${PARAMS%\}}, \"background_size\": 0.1}"
printf 'MeshVersionFormatted 2\nDimension 3\nSolAtVertices\n1\n1 1\n0\nEnd\n' >"$d/zero.sol"
bad_background padding_with_sol params.background_padding 'target_surface is not given' \
    -F "template=@$TPL" -F "target_mesh=@$BG" -F "target_sol=@$d/zero.sol" \
    -F "params=${PARAMS%\}}, \"background_padding\": 0.3}"
bad_background size_zero params.background_size '^params.background_size: must be > 0 \(got 0\)' \
    -F "template=@$TPL" -F "target_surface=@$STL" -F "params=${PARAMS%\}}, \"background_size\": 0}"
bad_background size_negative params.background_size '^params.background_size: must be > 0 \(got -0.5\)' \
    -F "template=@$TPL" -F "target_surface=@$STL" -F "params=${PARAMS%\}}, \"background_size\": -0.5}"
bad_background size_string params.background_size '^params.background_size: must be a number \(got string\)' \
    -F "template=@$TPL" -F "target_surface=@$STL" -F "params=${PARAMS%\}}, \"background_size\": \"0.1\"}"
bad_background padding_huge params.background_padding '^params.background_padding: must be <= 100' \
    -F "template=@$TPL" -F "target_surface=@$STL" -F "params=${PARAMS%\}}, \"background_padding\": 1e9}"
bad_background size_too_fine params.background_size \
    '^params.background_size: .*give a larger params.background_size' \
    -F "template=@$TPL" -F "target_surface=@$STL" -F "params=${PARAMS%\}}, \"background_size\": 1e-9}"
# a generated background is held to the daemon's bounds, like an uploaded one
code=$(post too_many -F "template=@$TPL" -F "target_surface=@$STL" \
    -F "params=${PARAMS%\}}, \"background_size\": 0.05}")
if [ "$code" = 413 ] && jq -e '.detail | test("^params.background_size: the generated background has [0-9]+ vertices, beyond the limit of 50000: give a larger params.background_size.*--max-vertices")' \
        "$WORK/too_many.json" >/dev/null; then
    ok "a background beyond --max-vertices: 413 \"$(jq -r .detail "$WORK/too_many.json" | head -c 200)\""
else
    not_ok "a background beyond --max-vertices: 413" "got $code" "$(head -c 600 "$WORK/too_many.json")"
fi
# the same rules through the OGC execute request (the same upload path)
for f in TPL STL BG; do base64 -w0 "${!f}" >"$WORK/$f.b64"; done # files: beyond ARG_MAX as --arg
jq -n --rawfile t "$WORK/TPL.b64" --rawfile s "$WORK/STL.b64" --rawfile m "$WORK/BG.b64" \
    '{inputs: {template: {value: $t}, target_surface: {value: $s}, target_mesh: {value: $m},
      params: {clamp: {kind: "ball", center: [0, 0, 0], radius: 0.5}, background_size: 0.1}}}' \
    >"$WORK/execute-conflict.json"
code=$(hcurl "${AUTH[@]}" -o "$WORK/exec_conflict.json" -w '%{http_code}' -H 'Content-Type: application/json' \
    -H 'Prefer: respond-async' --data-binary "@$WORK/execute-conflict.json" \
    "$BASE/v1/processes/match/execution")
if [ "$code" = 422 ] && jq -e '.["invalid-params"][0].name == "params.background_size" and
        (.detail | test("target_mesh is given"))' "$WORK/exec_conflict.json" >/dev/null; then
    ok "execute: background_size with target_mesh is a 422 naming it"
else
    not_ok "execute: background_size with target_mesh is a 422" "got $code" "$(head -c 600 "$WORK/exec_conflict.json")"
fi
hcurl "${AUTH[@]}" "$BASE/v1/processes/match" >"$WORK/process-bg.json"
jq -e '.inputs.params.schema.properties | (.background_size.exclusiveMinimum == 0) and
       (.background_padding.default == 0.1) and (.background_size.description | test("target_surface without target_mesh"))' \
    "$WORK/process-bg.json" >/dev/null
check "the process description's params list background_size and background_padding" test $? = 0

# ------------------------------------------------------------ refusals
# expect_refusal NAME STATUS ERE PART: the answer of `post NAME` is
# STATUS problem+json whose detail matches ERE (and whose invalid-params
# entry names PART, when given)
expect_refusal() {
    local name=$1 want=$2 re=$3 part=${4:-} code=$5
    if [ "$code" = "$want" ] &&
        jq -e --argjson s "$want" --arg re "$re" --arg part "$part" \
            '.status == $s and (.detail | test($re)) and
             ($part == "" or (.["invalid-params"][0].name == $part))' "$WORK/$name.json" >/dev/null; then
        ok "$name: $want \"$(jq -r .detail "$WORK/$name.json" | head -c 160)\""
    else
        not_ok "$name: $want" "got $code" "$(head -c 600 "$WORK/$name.json")"
    fi
}
SOL=$d/zero.sol
printf 'MeshVersionFormatted 2\nDimension 3\nSolAtVertices\n1\n1 1\n0\nEnd\n' >"$SOL"
code=$(post conflict -F "template=@$TPL" -F "target_surface=@$STL" -F "target_mesh=@$BG" \
    -F "target_sol=@$SOL" -F "params=$PARAMS")
expect_refusal conflict 422 'target_surface excludes target_sol' "" "$code"
printf 'solid broken\nfacet normal 0 0 1\n outer loop\n  vertex 0 0 0\n  vertex 1 0\n' >"$d/broken.stl"
code=$(post malformed -F "template=@$TPL" -F "target_surface=@$d/broken.stl" -F "params=$PARAMS")
expect_refusal malformed 422 '^target_surface: ' target_surface "$code"
grep -qF "$WORK" "$WORK/malformed.json"
check "the refusal does not show the spool's path" test $? != 0
code=$(post notarget -F "template=@$TPL" -F "params=$PARAMS")
expect_refusal notarget 400 'missing part "target_mesh".*target_surface' "" "$code"
code=$(post nosol -F "template=@$TPL" -F "target_mesh=@$BG" -F "params=$PARAMS")
expect_refusal nosol 400 'missing part "target_sol"' "" "$code"
left=$(find "$SPOOL/tmp" -mindepth 1 -maxdepth 1 2>/dev/null | wc -l)
check "refused uploads leave nothing in the spool ($left entries)" test "$left" = 0

# ------------------------------------------------ the process description
hcurl "${AUTH[@]}" "$BASE/v1/processes/match" >"$WORK/process.json"
jq -e '.inputs.target_surface.minOccurs == 0 and .inputs.target_sol.minOccurs == 0 and
       .inputs.template.minOccurs == 0 and .inputs.template_surface.minOccurs == 0 and
       (.inputs.target_surface.description | test("excludes target_sol"; "i"))' \
    "$WORK/process.json" >/dev/null
check "the process description lists target_surface (optional, excludes target_sol); template or template_surface (each optional)" test $? = 0

# ------------------------------------------- shapematch submit --target-surface
timeout $((120 * SLOW)) "$BIN/shapematch" submit --server "$BASE" --template "$TPL" \
    --target-surface "$STL" --clamp-ball 0,0,0,0.5 --max-iter 30 --wait --quiet -o "$WORK/sub" \
    >"$WORK/sub.out" 2>"$WORK/sub.err"
rc=$?
msg=$(python3 - "$WORK/sub/summary.json" "$WORK/run/summary.json" 2>&1 <<'PY'
import json, sys
d, r = (json.load(open(p)) for p in sys.argv[1:3])
print("boundary L2 %.6e vs %.6e" % (d["boundary_l2"], r["boundary_l2"]))
sys.exit(0 if abs(d["boundary_l2"] - r["boundary_l2"]) <= 1e-9 * r["boundary_l2"]
         and d["target_surface"]["background_generated"] else 1)
PY
)
same=$?
if [ "$rc" = 0 ] && [ "$same" = 0 ]; then
    ok "submit --target-surface --wait: results fetched, $msg"
else
    not_ok "submit --target-surface --wait" "exit $rc: $msg" "$(head -c 600 "$WORK/sub.err")"
fi
timeout 30 "$BIN/shapematch" submit --server "$BASE" --template "$TPL" --target-surface "$STL" \
    --target-sol "$SOL" --clamp-ball 0,0,0,0.5 >/dev/null 2>"$WORK/sub2.err"
rc=$?
[ "$rc" = 1 ] && grep -q "excludes --target-sol" "$WORK/sub2.err"
check "submit: --target-surface excludes --target-sol (exit $rc, before any request)" test $? = 0

# submit --background-size: sent as params.background_size
timeout $((120 * SLOW)) "$BIN/shapematch" submit --server "$BASE" --template "$TPL" \
    --target-surface "$STL" --clamp-ball 0,0,0,0.5 --max-iter 30 --background-size "$FINE" \
    --background-padding 0.2 --wait --quiet -o "$WORK/sub-fine" >"$WORK/sub-fine.out" 2>"$WORK/sub-fine.err"
rc=$?
if [ "$rc" = 0 ] && jq -e --argjson h "$FINE" --slurpfile r "$WORK/run-fine/summary.json" \
        '.target_surface.background_size == $h and .target_surface.background_padding == 0.2 and
         .target_surface.background_vertices == $r[0].target_surface.background_vertices' \
        "$WORK/sub-fine/summary.json" >/dev/null; then
    ok "submit --background-size $FINE --background-padding 0.2: the job's background is run's"
else
    not_ok "submit --background-size" "exit $rc" "$(head -c 600 "$WORK/sub-fine.err")"
fi
timeout 30 "$BIN/shapematch" submit --server "$BASE" --template "$TPL" --target-surface "$STL" \
    --target-mesh "$BG" --background-size 0.1 --clamp-ball 0,0,0,0.5 >/dev/null 2>"$WORK/sub3.err"
rc=$?
[ "$rc" = 1 ] && grep -q "are for a generated background (--target-surface without --target-mesh): --target-mesh is given" "$WORK/sub3.err"
check "submit: --background-size with --target-mesh is a usage error (exit $rc, before any request)" test $? = 0

# units: a sphere of radius 1000 (millimetres) against the small ball
MMP='{"clamp": {"kind": "ball", "center": [0, 0, 0], "radius": 0.5}, "max_iter": 1'
t0=$EPOCHREALTIME
bad_background units_mm target_surface \
    '^target_surface: the target is [0-9.]+ times larger than the template .*about 1000 times: are they in different units .*set params[.]background_size to generate it anyway$' \
    -F "template=@$TPL" -F "target_surface=@$d/mm.stl" -F "params=$MMP}"
echo "# refused in $(awk -v a="${t0/,/.}" -v b="${EPOCHREALTIME/,/.}" 'BEGIN { printf "%.2f", b - a }') s"
code=$(post units_sized -F "template=@$TPL" -F "target_surface=@$d/mm.stl" \
    -F "params=$MMP, \"background_size\": 200}")
sized=$(jq -r '.jobID // empty' "$WORK/units_sized.json" 2>/dev/null)
check "the same with params.background_size 200: accepted (201, got $code)" test "$code" = 201
[ -n "$sized" ] && wait_final "$sized" 60

reports_clean && ok "no sanitizer report" || not_ok "no sanitizer report"
stop_daemon
echo "1..$n"
