#!/usr/bin/env bash
# run.sh: weight 0.5 seconds 45 asan 150
# A template meshed from a surface through the daemon (issue 34): the
# multipart part template_surface of POST /v1/jobs through real curl (a
# closed 2D curve, tests/cli/template_mesh_check.py's star), meshed in the
# upload's check child, which keeps the mesh for the worker:
#   - 201 without a clamp or a template; the job ends successful, its
#     summary's template.meshed names nglib, 0 inverted, the default clamp
#     in its warnings; GET results/template serves the mesh, byte for byte
#     the template.mesh `shapematch run --template-surface` writes on the
#     same file;
#   - an open curve: 422 naming template_surface and the defect; template
#     with template_surface: 422; neither: 400 naming template;
#   - params template_size reaches the mesher (fewer triangles);
#   - `shapematch submit --template-surface --wait -o DIR` downloads
#     template.mesh with the results;
#   - a label map's label as the template (part template_image, params
#     template_label; tests/cli/template_mesh_check.py's label map, two
#     labels): 201, successful, summary template.meshed from "image" with
#     label 3, results/template byte for byte `run --template-image
#     --template-label 3`'s template.mesh; a label the image lacks: 422
#     naming template_image and the label; template_label without
#     template_image, template_image with template: 422; a detached NRRD
#     header 422 and a header over the voxel bound 413, the target
#     image's bounds; OGC: the process lists template_image, execute
#     takes it inline (the same template.mesh); `submit
#     --template-image --template-label 3 --wait -o DIR` the same mesh.
source "$(dirname "$0")/lib.sh"
CHECK=$ROOT/tests/cli/template_mesh_check.py
PY=/usr/bin/python3
cd "$WORK" || exit 1
"$PY" "$CHECK" star star.mesh 1 0 0 && "$PY" "$CHECK" star moved.mesh 1.12 0.1 -0.05
# an open curve: the star without its last segment
"$PY" - <<'PYEOF'
lines = open('star.mesh').read().split('\n')
i = lines.index('Edges')
n = int(lines[i + 1])
out = lines[:i + 1] + [str(n - 1)] + lines[i + 2:i + 2 + n - 1] + lines[i + 2 + n:]
open('open.mesh', 'w').write('\n'.join(out))
PYEOF

# --max-vertices 100000: a template image may declare 25.6M voxels
start_daemon tpl --workers 1 --max-vertices 100000 || { not_ok "daemon starts"; exit 1; }
P='{"max_iter": 30}'
code=$(hcurl -o sub.json -w '%{http_code}' -F template_surface=@star.mesh -F target_surface=@moved.mesh \
    -F "params=$P" "$BASE/v1/jobs")
check "POST template_surface + target_surface, no clamp: 201 ($code)" test "$code" = 201
J=$(jq -r .jobID sub.json)
wait_state "$J" successful 60
check "the job ends successful" state_is "$J" successful
hcurl -o res.json "$BASE/v1/jobs/$J/results"
jq -e '.template.meshed.mesher == "nglib" and .template.meshed.from == "surface"
    and .inverted_elements == 0 and (.warnings | map(.code) | index("clamp-default")) != null' \
    res.json >/dev/null
check "summary: template.meshed by nglib, 0 inverted, the default clamp reported" test $? = 0
code=$(hcurl -o tpl.mesh -w '%{http_code}' "$BASE/v1/jobs/$J/results/template")
"$BIN/shapematch" run --template-surface star.mesh --target-surface moved.mesh --max-iter 1 -q \
    -o local 2>/dev/null >/dev/null
[ "$code" = 200 ] && cmp -s tpl.mesh local/template.mesh
check "GET results/template (200) is the template.mesh of shapematch run, byte for byte" test $? = 0
# the check's mesh kept with the job and read by the worker (issue 35
# item 5's reuse, for the template): job.json names it with its figures,
# the worker says so, and the job run again by the worker program without
# it (meshed again) or with a stale key makes the same result files
JOB=$SPOOL/jobs/$J
if jq -e '.checked.template == "inputs/checked/template.meshb" and
          .checked.template_meshed.source == "surface"' \
    "$JOB/job.json" >/dev/null && [ -s "$JOB/inputs/checked/template.meshb" ] &&
    grep -q "the template meshed by the upload's check is reused (inputs/checked/template.meshb)" \
        "$JOB/worker.log"; then
    ok "the check's meshed template is kept in inputs/checked and reused by the worker"
else
    not_ok "the check's meshed template is kept and reused" \
        "$(jq -c .checked "$JOB/job.json" 2>&1; ls "$JOB/inputs/checked" 2>&1; tail -3 "$JOB/worker.log")"
fi
same=1
worker_again "$JOB" template.mesh result.mesh displacement.sol || same=0
if [ "$same" = 1 ] && grep -q 'template meshed by the upload.s check is reused' "$WORK/again-kept/worker.log" &&
    ! grep -q 'is reused' "$WORK/again-none/worker.log" &&
    ! grep -q 'is reused' "$WORK/again-stale/worker.log" &&
    jq -e --slurpfile k "$WORK/again-kept/results/summary.json" \
        '.template.meshed == $k[0].template.meshed' "$JOB/results/summary.json" >/dev/null; then
    ok "results with the reused template are byte-identical to those of a template meshed again (none kept, a stale key); template.meshed the check's"
else
    not_ok "results with and without the reused template are byte-identical" \
        "same $same; $(tail -2 "$WORK"/again-*/worker.log)"
fi
# a damaged kept mesh: the worker meshes again (the same template)
worker_copy "$JOB" damaged-tpl '' >/dev/null 2>&1
printf 'damaged' >"$WORK/again-damaged-tpl/inputs/checked/template.meshb"
rm -rf "$WORK/again-damaged-tpl/results"
OMP_NUM_THREADS=1 "$BIN/shapematch-worker" "$WORK/again-damaged-tpl" 3>/dev/null 2>"$WORK/again-damaged-tpl/worker.log"
if cmp -s "$JOB/results/template.mesh" "$WORK/again-damaged-tpl/results/template.mesh" &&
    grep -q "what the upload's check built is not used" "$WORK/again-damaged-tpl/worker.log"; then
    ok "a damaged kept template: meshed again by the worker, the same template.mesh"
else
    not_ok "a damaged kept template is meshed again" "$(tail -3 "$WORK/again-damaged-tpl/worker.log")"
fi

code=$(hcurl -o bad.json -w '%{http_code}' -F template_surface=@open.mesh -F target_surface=@moved.mesh \
    -F "params=$P" "$BASE/v1/jobs")
[ "$code" = 422 ] && jq -e '.detail | startswith("template_surface: open: ")' bad.json >/dev/null
check "an open curve: 422 naming template_surface and the defect ($code)" test $? = 0 || cat bad.json
code=$(hcurl -o bad.json -w '%{http_code}' -F template=@local/template.mesh -F template_surface=@star.mesh \
    -F target_surface=@moved.mesh -F "params=$P" "$BASE/v1/jobs")
[ "$code" = 422 ] && jq -e '.detail | contains("excludes template")' bad.json >/dev/null
check "template with template_surface: 422 ($code)" test $? = 0
code=$(hcurl -o bad.json -w '%{http_code}' -F target_surface=@moved.mesh -F "params=$P" "$BASE/v1/jobs")
[ "$code" = 400 ] && jq -e '.detail | contains("missing part \"template\"")' bad.json >/dev/null
check "no template at all: 400 naming template ($code)" test $? = 0

code=$(hcurl -o sub2.json -w '%{http_code}' -F template_surface=@star.mesh -F target_surface=@moved.mesh \
    -F 'params={"max_iter": 1, "template_size": 0.15}' "$BASE/v1/jobs")
J2=$(jq -r .jobID sub2.json)
wait_state "$J2" successful 60
hcurl -o res2.json "$BASE/v1/jobs/$J2/results"
jq -e --slurpfile a res.json '.template.meshed.size == 0.15
    and .template.meshed.elements < $a[0].template.meshed.elements' res2.json >/dev/null
check "params template_size 0.15 reaches the mesher (fewer triangles)" test $? = 0

"$BIN/shapematch" submit --server "$BASE" --template-surface star.mesh --target-surface moved.mesh \
    --max-iter 5 --wait -q -o out-sub >sub.out 2>sub.err
rc=$?
{ [ $rc = 0 ] || [ $rc = 10 ]; } && cmp -s out-sub/template.mesh local/template.mesh && [ -s out-sub/summary.json ]
check "submit --template-surface --wait -o: template.mesh downloaded with the results (exit $rc)" test $? = 0
# ---- a label map's label as the template
"$PY" "$CHECK" label lab.nii.gz && "$PY" "$CHECK" label moved.nii.gz 3
PI='{"max_iter": 3, "template_label": 3, "label": 3}'
code=$(hcurl -o subi.json -w '%{http_code}' -F template_image=@lab.nii.gz -F target_image=@moved.nii.gz \
    -F "params=$PI" "$BASE/v1/jobs")
check "POST template_image + params template_label 3 + target_image: 201 ($code)" test "$code" = 201 ||
    cat subi.json
JI=$(jq -r .jobID subi.json)
wait_state "$JI" successful 120
check "the label-map job ends successful" state_is "$JI" successful
hcurl -o resi.json "$BASE/v1/jobs/$JI/results"
jq -e '.template.meshed.from == "image" and .template.meshed.label == 3
    and .template.meshed.mesher == "nglib" and .inverted_elements == 0' resi.json >/dev/null
check "summary: template.meshed from the image's label 3 by nglib, 0 inverted" test $? = 0 ||
    jq -c .template resi.json
code=$(hcurl -o tpli.mesh -w '%{http_code}' "$BASE/v1/jobs/$JI/results/template")
"$BIN/shapematch" run --template-image lab.nii.gz --template-label 3 --target-image moved.nii.gz \
    --label 3 --max-iter 1 -q -o locali 2>/dev/null >/dev/null
[ "$code" = 200 ] && [ -s locali/template.mesh ] && cmp -s tpli.mesh locali/template.mesh
check "GET results/template (200) is run --template-image's template.mesh, byte for byte" test $? = 0
code=$(hcurl -o bad.json -D bad.hdr -w '%{http_code}' -F template_image=@lab.nii.gz \
    -F target_image=@moved.nii.gz -F 'params={"template_label": 9, "label": 3}' "$BASE/v1/jobs")
grep -qi '^content-type: application/problem+json' bad.hdr &&
[ "$code" = 422 ] && jq -e '(.detail | startswith("template_image: label-empty: no voxel of the image has label 9"))
    and .status == 422 and .["invalid-params"][0].name == "template_image"' bad.json >/dev/null
check "a label the image lacks: 422 problem+json naming template_image and label 9 ($code)" test $? = 0 || cat bad.json
# OGC: the process lists template_image (optional); the execute request
# takes it inline and makes the same template
hcurl -o proc.json "$BASE/v1/processes/match"
jq -e '.inputs.template_image.minOccurs == 0 and .inputs.template.minOccurs == 0' proc.json >/dev/null
check "the OGC process description lists template_image (optional) beside template" test $? = 0
jq -n --rawfile t <(base64 -w0 lab.nii.gz) --rawfile g <(base64 -w0 moved.nii.gz) --argjson p "$PI" \
    '{inputs: {template_image: {value: $t}, target_image: {value: $g}, params: $p}}' >exec.json
JX=$(hcurl -H 'Content-Type: application/json' --data-binary @exec.json \
    "$BASE/v1/processes/match/execution" | jq -r '.jobID // empty')
[ -n "$JX" ] && wait_state "$JX" successful 120
code=$(hcurl -o tplx.mesh -w '%{http_code}' "$BASE/v1/jobs/$JX/results/template")
[ -n "$JX" ] && [ "$code" = 200 ] && cmp -s tplx.mesh locali/template.mesh
check "OGC execute with template_image inline: successful, the same template.mesh ($code)" test $? = 0

# the target image's bounds: one file (a detached header would read a
# file of the daemon's machine), the voxels under 256 x --max-vertices
printf 'NRRD0004\ntype: uint8\ndimension: 3\nsizes: 2 2 2\nencoding: raw\ndata file: /etc/hostname\n\n' >det.nhdr
code=$(hcurl -o bad.json -w '%{http_code}' -F template_image=@det.nhdr -F target_image=@moved.nii.gz \
    -F "params=$PI" "$BASE/v1/jobs")
[ "$code" = 422 ] && jq -e '(.detail | startswith("template_image: ")) and (.detail | contains("detached data file"))' \
    bad.json >/dev/null
check "a detached NRRD header as template_image: 422 (one file), as for target_image ($code)" test $? = 0 ||
    cat bad.json
printf 'NRRD0004\ntype: uint8\ndimension: 3\nsizes: 512 512 512\nencoding: raw\n\n\001' >huge.nrrd
code=$(hcurl -o bad.json -w '%{http_code}' -F template_image=@huge.nrrd -F target_image=@moved.nii.gz \
    -F "params=$PI" "$BASE/v1/jobs")
[ "$code" = 413 ] && jq -e '.detail | startswith("template_image: ")' bad.json >/dev/null
check "a template_image declaring 512^3 voxels over 256 x --max-vertices: 413 ($code)" test $? = 0 ||
    cat bad.json
code=$(hcurl -o bad.json -w '%{http_code}' -F template_surface=@star.mesh -F target_surface=@moved.mesh \
    -F 'params={"template_label": 3}' "$BASE/v1/jobs")
[ "$code" = 422 ] && jq -e '.detail | startswith("params.template_label: ")' bad.json >/dev/null
check "template_label without template_image: 422 naming params.template_label ($code)" test $? = 0 ||
    cat bad.json
code=$(hcurl -o bad.json -w '%{http_code}' -F 'params={"template_label": -1}' \
    -F template_image=@lab.nii.gz -F target_image=@moved.nii.gz "$BASE/v1/jobs")
[ "$code" = 422 ] && jq -e '.detail | startswith("params.template_label: ")' bad.json >/dev/null
check "template_label -1: 422 naming params.template_label ($code)" test $? = 0 || cat bad.json
code=$(hcurl -o bad.json -w '%{http_code}' -F template=@local/template.mesh -F template_image=@lab.nii.gz \
    -F target_image=@moved.nii.gz -F "params=$PI" "$BASE/v1/jobs")
[ "$code" = 422 ] && jq -e '.detail | startswith("template_image excludes template")' bad.json >/dev/null
check "template with template_image: 422 ($code)" test $? = 0 || cat bad.json
"$BIN/shapematch" submit --server "$BASE" --template-image lab.nii.gz --template-label 3 \
    --target-image moved.nii.gz --label 3 --max-iter 2 --wait -q -o out-subi >subi.out 2>subi.err
rc=$?
{ [ $rc = 0 ] || [ $rc = 10 ]; } && cmp -s out-subi/template.mesh locali/template.mesh
check "submit --template-image --template-label 3 --wait -o: the same template.mesh (exit $rc)" \
    test $? = 0 || cat subi.err

reports_clean && ok "no sanitizer report" || not_ok "no sanitizer report"
stop_daemon
echo "1..$n"
[ "$failed" -eq 0 ]
