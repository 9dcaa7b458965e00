#!/usr/bin/env bash
# Every target and clamp option through every entry point: `run`,
# `submit --wait`, `batch`, `batch --server`, Python's match and
# Client.submit, and curl against the daemon each take a target surface,
# a target mesh + distance, a target image (with smooth, the label map's
# smoothing row), a ball clamp, a clamp by physical name ("core"), by
# number and no clamp, and each job's summary.json says the same
# parameters (the name resolved to its number, the smoothing used).
# The template is a ball in a shell made by gmsh (physical volumes "core"
# 1 and "shell" 2); the targets a sphere of radius 0.9 as a surface, as
# its distance on a background (`shapematch sdf`), and as a label map
# (nibabel).
source "$(dirname "$0")/lib.sh"
PY=/usr/bin/python3
[ -x "$PY" ] || PY=python3
SM=$BIN/shapematch
cd "$WORK" || exit 1
cp "$ROOT/tests/lib/case/ball_shell.geo" t.geo
cat >s.geo <<'GEO'
SetFactory("OpenCASCADE");
Sphere(1) = {0, 0, 0, 0.9};
Mesh.MeshSizeMax = 0.3;
GEO
if ! gmsh -3 t.geo -format msh41 -o t.msh -v 1 >gmsh.log 2>&1 ||
    ! gmsh -2 s.geo -format stl -o s.stl -v 1 >>gmsh.log 2>&1 ||
    ! "$SM" sdf --surface s.stl -o sdf >sdf.log 2>&1; then
    not_ok "gmsh and shapematch sdf make the inputs" "$(tail -5 gmsh.log sdf.log)"
    exit 1
fi
"$PY" - s.nii.gz <<'PYEOF'
import sys
import nibabel, numpy as np
h = 0.1
i = np.arange(-14, 15) * h
x, y, z = np.meshgrid(i, i, i, indexing='ij')
mask = (np.sqrt(x * x + y * y + z * z) <= 0.9).astype(np.uint8)
# RAS affine of an LPS grid centred at 0 (a sphere: the frame does not matter)
nibabel.Nifti1Image(mask, np.diag([h, h, h, 1.0]) @ np.array(
    [[1, 0, 0, -14], [0, 1, 0, -14], [0, 0, 1, -14], [0, 0, 0, 1.0]])).to_filename(sys.argv[1])
PYEOF
[ -s s.nii.gz ] || { not_ok "nibabel writes the label map"; exit 1; }
if ! start_daemon walk --workers 2; then
    not_ok "the daemon starts"
    exit 1
fi
ok "inputs made, the daemon starts"

# The four cases of every entry point: target, clamp, and what
# summary.json must say (a jq test on the summary)
CASES=(
    "surface|ball|.parameters.clamp == {kind: \"ball\", center: [0, 0, 0], radius: 0.35}"
    "field|name|.parameters.clamp == {kind: \"elements\", refs: [1]}"
    "image|number|.parameters.clamp == {kind: \"elements\", refs: [1]} and .parameters.smooth == 0.5 and .target_image.smooth == 0.5"
    "surface|none|.parameters.clamp.kind == \"none\""
)
target_flags() { # surface|field|image
    case $1 in
    surface) echo "--target-surface s.stl" ;;
    field) echo "--target-mesh sdf/background.mesh --target-sol sdf/background.sol" ;;
    image) echo "--target-image s.nii.gz --smooth 0.5" ;;
    esac
}
clamp_flags() { # ball|name|number|none
    case $1 in
    ball) echo "--clamp-ball 0,0,0,0.35" ;;
    name) echo "--clamp-elements core" ;;
    number) echo "--clamp-elements 1" ;;
    none) echo "--no-clamp" ;;
    esac
}
# check_summary ENTRY TARGET CLAMP SUMMARY EXPR
check_summary() {
    if [ -s "$4" ] && jq -e "$5" "$4" >/dev/null 2>&1; then
        ok "$1: target $2, clamp $3"
    else
        not_ok "$1: target $2, clamp $3" "$(cat "$1-$2-$3.err" 2>/dev/null | tail -5)" \
            "$(jq -c '{parameters, target_image: .target_image.smooth}' "$4" 2>&1 | head -c 600)"
    fi
}
COMMON="--template t.msh --max-iter 2 --quiet"
k=0
for c in "${CASES[@]}"; do
    IFS='|' read -r target clamp expr <<<"$c"
    k=$((k + 1))
    # shellcheck disable=SC2046 # the flags are words
    "$SM" run $COMMON $(target_flags "$target") $(clamp_flags "$clamp") -o "run-$k" \
        >"run-$target-$clamp.err" 2>&1
    check_summary run "$target" "$clamp" "run-$k/summary.json" "$expr"
    # shellcheck disable=SC2046
    "$SM" submit --server "$BASE" $COMMON $(target_flags "$target") $(clamp_flags "$clamp") \
        --wait -o "submit-$k" >"submit-$target-$clamp.err" 2>&1
    check_summary submit "$target" "$clamp" "submit-$k/summary.json" "$expr"
    # shellcheck disable=SC2046
    "$SM" batch $COMMON $(target_flags "$target") $(clamp_flags "$clamp") --no-model --jobs 1 \
        -o "batch-$k" >"batch-$target-$clamp.err" 2>&1
    check_summary batch "$target" "$clamp" "$(ls batch-$k/targets/*/summary.json 2>/dev/null | head -1)" "$expr"
    # the daemon's batch wants two targets for a model: --no-model is local only
    # shellcheck disable=SC2046
    "$SM" batch --server "$BASE" $COMMON $(target_flags "$target") $(target_flags "$target") \
        $(clamp_flags "$clamp") -o "rbatch-$k" >"batch--server-$target-$clamp.err" 2>&1
    check_summary "batch --server" "$target" "$clamp" \
        "$(ls rbatch-$k/targets/*/summary.json 2>/dev/null | head -1)" "$expr"
done

# curl: the daemon's params document, the same cases (names in refs)
PARAMS=(
    '{"clamp": {"kind": "ball", "center": [0, 0, 0], "radius": 0.35}, "max_iter": 2}'
    '{"clamp": {"kind": "elements", "refs": ["core"]}, "max_iter": 2}'
    '{"clamp": {"kind": "elements", "refs": [1]}, "max_iter": 2, "smooth": 0.5}'
    '{"clamp": {"kind": "none"}, "max_iter": 2}'
)
PARTS=("-F target_surface=@s.stl" "-F target_mesh=@sdf/background.mesh -F target_sol=@sdf/background.sol"
    "-F target_image=@s.nii.gz" "-F target_surface=@s.stl")
k=0
for c in "${CASES[@]}"; do
    IFS='|' read -r target clamp expr <<<"$c"
    # shellcheck disable=SC2086 # the parts are words
    id=$(hcurl -F template=@t.msh ${PARTS[$k]} -F "params=${PARAMS[$k]}" "$BASE/v1/jobs" |
        jq -r '.jobID // empty')
    if [ -n "$id" ] && wait_final "$id" 60; then
        hcurl -o "curl-$k.json" "$BASE/v1/jobs/$id/results"
    fi
    check_summary curl "$target" "$clamp" "curl-$k.json" "$expr"
    k=$((k + 1))
done
# Python: match (local) and Client.submit (the daemon), the same cases
# as keywords; in the release variant (an uninstrumented python3 loads
# the sanitized libraries only with their runtimes preloaded: python.sh
# covers that)
if [ "$VARIANT" != release ]; then
    skip "python match and Client.submit: release variant only (python.sh runs them under ASan)"
    echo "1..$n"
    exit $((failed > 0))
fi
SHAPEMATCH_LIBDIR=$BIN PYTHONPATH=$ROOT/python "$PY" - "$BASE" >py.out 2>py.err <<'PYEOF'
import json, sys
import shapematch
base = sys.argv[1]
targets = {"surface": {"target_surface": "s.stl"},
           "field": {"target_mesh": "sdf/background.mesh", "target_sol": "sdf/background.sol"},
           "image": {"target_image": "s.nii.gz", "smooth": 0.5}}
clamps = {"ball": {"clamp_ball": (0, 0, 0, 0.35)}, "name": {"clamp_elements": "core"},
          "number": {"clamp_elements": [1]}, "none": {"no_clamp": True}}
client = shapematch.Client(base)
for k, (t, c) in enumerate((("surface", "ball"), ("field", "name"), ("image", "number"),
                            ("surface", "none"))):
    kw = dict(targets[t], **clamps[c], max_iter=2)
    try:
        r = shapematch.match("t.msh", **kw)
        json.dump(r.summary, open("py-match-%d.json" % k, "w"))
    except Exception as e:  # noqa: BLE001 - reported by the suite
        print("match", t, c, e, file=sys.stderr)
    try:
        job = client.submit("t.msh", **kw)
        job.wait()
        job.results("py-client-%d" % k)
    except Exception as e:  # noqa: BLE001
        print("client", t, c, e, file=sys.stderr)
PYEOF
k=0
for c in "${CASES[@]}"; do
    IFS='|' read -r target clamp expr <<<"$c"
    cp py.err "python-match-$target-$clamp.err" 2>/dev/null
    check_summary "python match" "$target" "$clamp" "py-match-$k.json" "$expr"
    cp py.err "python-client-$target-$clamp.err" 2>/dev/null
    check_summary "python Client.submit" "$target" "$clamp" "py-client-$k/summary.json" "$expr"
    k=$((k + 1))
done

echo "1..$n"
exit $((failed > 0))
