#!/usr/bin/env bash
# Label-map targets through the daemon: a job with the part target_image
# (the NIfTI sphere of tests/cli/image_shapes.py, made at test time) and
# params label/image_space gives the result of `shapematch run
# --target-image` (one job runner: the same iterations and boundary RMS),
# by curl and by `shapematch submit --target-image --wait` (the OGC
# process description lists the input); summary.json carries target_image; bad images are
# problem+json answers with the right status: a truncated NIfTI (422
# naming target_image and the byte), a label that selects nothing (422,
# label-empty), a detached NRRD header (422: one file over HTTP), an
# image beside target_sol (422), an image over --max-inflated (413 naming
# it), a 2D template (422).
source "$(dirname "$0")/lib.sh"
PY=/usr/bin/python3
[ -x "$PY" ] || PY=python3

if ! "$PY" "$ROOT/tests/cli/image_shapes.py" write "$WORK" sphere >/dev/null; then
    not_ok "image_shapes.py wrote the sphere"
    exit 1
fi
cat >"$WORK/ball.geo" <<'GEO'
SetFactory("OpenCASCADE");
Sphere(1) = {4, 39, 9, 8.5};
Mesh.MeshSizeFromPoints = 0;
GEO
gmsh "$WORK/ball.geo" -3 -format msh41 -clmax 3 -nt 1 -v 1 -o "$WORK/ball.msh" >/dev/null 2>&1
# a 200^3 label map (8 MB of voxels, a few kB gzip-compressed) for the
# --max-inflated bound
"$PY" - "$WORK/big.nii.gz" <<'PY'
import gzip, struct, sys
h = bytearray(352)
struct.pack_into('<i', h, 0, 348)
struct.pack_into('<8h', h, 40, 3, 200, 200, 200, 1, 1, 1, 1)
struct.pack_into('<hh', h, 70, 2, 8)
struct.pack_into('<8f', h, 76, 1, 1, 1, 1, 0, 0, 0, 0)
struct.pack_into('<f', h, 108, 352)
h[344:348] = b'n+1\0'
v = bytearray(200 ** 3)
v[100 + 200 * (100 + 200 * 100)] = 1
open(sys.argv[1], 'wb').write(gzip.compress(bytes(h) + bytes(v)))
PY
if ! start_daemon image --workers 1 --max-inflated 4000000; then
    not_ok "the daemon starts"
    exit 1
fi
ok "the daemon starts"

P='{"clamp": {"kind": "ball", "center": [4, 39, 9], "radius": 4.5}, "max_iter": 10, "label": 1}'
OMP_NUM_THREADS=1 "$BIN/shapematch" run --template "$WORK/ball.msh" --target-image "$WORK/s1.nii" \
    --label 1 --clamp-ball 4,39,9,4.5 --max-iter 10 --quiet -o "$WORK/cli" >/dev/null 2>"$WORK/cli.err"
rc=$?
if [ "$rc" = 0 ] || [ "$rc" = 10 ]; then
    ok "run --target-image (the reference)"
else
    not_ok "run --target-image (the reference), exit $rc" "$(head -c 400 "$WORK/cli.err")"
fi
# same_as_run SUMMARY: the CLI's iterations and boundary RMS (1e-9
# relative) and the label's figures
same_as_run() {
    jq -en --slurpfile a "$1" --slurpfile b "$WORK/cli/summary.json" '
        $a[0] as $x | $b[0] as $y |
        def near(p; q): ((p - q) | fabs) <= 1e-9 * ((q | fabs) + 1e-12);
        near($x.boundary_rms; $y.boundary_rms) and $x.iterations == $y.iterations and
        $x.target_image.voxels == 1921 and $x.target_image.label == 1 and
        $x.target_image.background_vertices == $y.target_image.background_vertices' >/dev/null
}
# post CURL-ARGS...: a job by curl; the code in $WORK/post.code
post() {
    hcurl "${AUTH[@]}" -o "$WORK/post.out" -D "$WORK/post.head" -w '%{http_code}' \
        -F "template=@$WORK/ball.msh" "$@" "$BASE/v1/jobs" >"$WORK/post.code" 2>/dev/null
    jq -r '.jobID // empty' "$WORK/post.out" 2>/dev/null
}
id=$(post -F "target_image=@$WORK/s1.nii" -F "params=$P")
if [ -n "$id" ] && wait_final "$id" 120 && state_is "$id" successful &&
    hcurl "${AUTH[@]}" "$BASE/v1/jobs/$id/results" >"$WORK/curl.json" &&
    same_as_run "$WORK/curl.json"; then
    ok "a target_image job (curl): the result of run --target-image"
else
    not_ok "target_image job (curl)" "$(cat "$WORK/post.code") $(head -c 400 "$WORK/post.out")" \
        "$(jq -c '{boundary_rms, iterations, target_image}' "$WORK/curl.json" 2>&1 | head -c 400)"
fi
hcurl "${AUTH[@]}" -o "$WORK/back.img" "$BASE/v1/jobs/$id/inputs/target_image"
if cmp -s "$WORK/back.img" "$WORK/s1.nii"; then
    ok "GET .../inputs/target_image serves the image as sent"
else
    not_ok "target_image served back"
fi

timeout $((120 * SLOW)) "$BIN/shapematch" submit --server "$BASE" --template "$WORK/ball.msh" \
    --target-image "$WORK/gz.nrrd" --label 1 --clamp-ball 4,39,9,4.5 --max-iter 10 --wait --quiet \
    -o "$WORK/sub" >/dev/null 2>"$WORK/sub.err"
rc=$?
if { [ "$rc" = 0 ] || [ "$rc" = 10 ]; } && same_as_run "$WORK/sub/summary.json"; then
    ok "submit --target-image (NRRD, sent gzip-compressed) --wait: the result of run"
else
    not_ok "submit --target-image --wait (exit $rc)" "$(head -c 600 "$WORK/sub.err")"
fi

hcurl "${AUTH[@]}" "$BASE/v1/processes/match" >"$WORK/process.json"
if jq -e '.inputs.target_image.title == "Target image"' "$WORK/process.json" >/dev/null; then
    ok "the process description lists target_image"
else
    not_ok "process description" "$(head -c 300 "$WORK/process.json")"
fi

# refused CODE NAME PATTERN CURL-ARGS...: a problem+json of that status
refused() {
    local code=$1 name=$2 pattern=$3
    shift 3
    post "$@" >/dev/null
    if [ "$(cat "$WORK/post.code")" = "$code" ] &&
        grep -qi '^content-type: application/problem+json' "$WORK/post.head" &&
        grep -q -- "$pattern" "$WORK/post.out"; then
        ok "$name: $code problem+json naming $pattern"
    else
        not_ok "$name" "$(cat "$WORK/post.code") $(head -c 400 "$WORK/post.out")"
    fi
}
head -c 400 "$WORK/s1.nii" >"$WORK/cut.nii"
refused 422 "a truncated NIfTI" 'target_image: byte' -F "target_image=@$WORK/cut.nii" -F "params=$P"
refused 422 "a label that selects nothing" 'label-empty' -F "target_image=@$WORK/s1.nii" \
    -F "params=${P/\"label\": 1/\"label\": 9}"
refused 422 "a detached NRRD header" 'detached data file' -F "target_image=@$WORK/det.nhdr" \
    -F "params=$P"
refused 422 "target_image with target_sol" 'target_image excludes target_sol' \
    -F "target_image=@$WORK/s1.nii" -F "target_sol=@$ROOT/examples/3d/background.sol.gz" \
    -F "params=$P"
refused 413 "an image over --max-inflated" 'max-inflated' -F "target_image=@$WORK/big.nii.gz" \
    -F "params=$P"
refused 422 "image_space xyz" 'params.image_space' -F "target_image=@$WORK/s1.nii" \
    -F "params=${P/\"label\": 1/\"image_space\": \"xyz\"}"
echo "1..$n"
[ "$failed" -eq 0 ]
