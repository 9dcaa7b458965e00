#!/usr/bin/env bash
# OGC API - Processes Part 1 execution (issue 11), with curl against a real
# daemon: POST /v1/processes/match/execution with a JSON execute request
# whose file inputs are inline base64 values is decoded into the same
# upload path as the multipart POST /v1/jobs: 201 + Location + status
# document (Preference-Applied: respond-async when asked; async also
# without Prefer, and with Prefer: wait, unapplied); the job runs to
# successful; bad requests get 400/413/415/422 problem+json (href, bad
# base64, unknown inputs or members, params as for multipart, a missing
# part); an image target inline (target_image: the job runs on its
# label; an empty label and a second target are 422s); /v1/conformance
# lists core.
source "$(dirname "$0")/lib.sh"

if ! make_case; then
    not_ok "gmsh builds the test meshes" "$(tail -5 "$WORK/case/gmsh.log")"
    exit 1
fi
ok "gmsh builds the test meshes"
start_daemon exec --workers 1 || { not_ok "the daemon starts"; exit 1; }
ok "the daemon starts"
EXEC=$BASE/v1/processes/match/execution
hdr() { tr -d '\r' <"$WORK/h" | awk -v n="$1" 'BEGIN { n = tolower(n) } { i = index($0, ":"); if (tolower(substr($0, 1, i - 1)) == n) v = substr($0, i + 2) } END { print v }'; }
# post FILE [CURL ARGS]: the status; headers in $WORK/h, body in $WORK/b
post() {
    local f=$1
    shift
    curl -sS --max-time $((30 * SLOW)) -D "$WORK/h" -o "$WORK/b" -w '%{http_code}' \
        -H 'Content-Type: application/json' --data-binary "@$f" "$@" "$EXEC"
}
# request PARAMS_JSON [EXTRA_INPUTS_JSON]: an execute request into $WORK/req.json
request() {
    jq -n --rawfile t <(base64 -w0 "$DISK") --rawfile m <(base64 -w0 "$BOX") \
        --rawfile s <(base64 -w0 "$BOXSOL") --argjson p "$1" --argjson x "${2:-{\}}" \
        '{inputs: ({template: {value: $t, mediaType: "application/x-medit-mesh"},
                    target_mesh: {value: $m}, target_sol: {value: $s, encoding: "base64"},
                    params: $p} + $x), response: "document"}' >"$WORK/req.json"
}
detail() { jq -r .detail "$WORK/b" 2>/dev/null; }
is_problem() { # STATUS
    tr -d '\r' <"$WORK/h" | grep -qi '^content-type: application/problem+json' &&
        [ "$(jq -r .status "$WORK/b")" = "$1" ]
}

request "$(quick_params 20)"
c=$(post "$WORK/req.json" -H 'Prefer: respond-async')
id=$(jq -r '.jobID // empty' "$WORK/b" 2>/dev/null)
if [ "$c" = 201 ] && [ -n "$id" ] && [ "$(hdr Location)" = "/v1/jobs/$id" ] &&
    [ "$(hdr Preference-Applied)" = respond-async ] && [ "$(jq -r .type "$WORK/b")" = process ]; then
    ok "execute with Prefer: respond-async: 201, Location, status document, Preference-Applied"
else
    not_ok "execute, respond-async" "code $c" "$(cat "$WORK/h" "$WORK/b")"
fi
if [ -n "$id" ] && wait_final "$id" $((60 * SLOW)) && state_is "$id" successful; then
    ok "the executed job runs to successful"
else
    not_ok "the executed job" "$(hcurl "$BASE/v1/jobs/$id")"
fi
code=$(hcurl -o "$WORK/in.mesh" -w '%{http_code}' "$BASE/v1/jobs/$id/results/mesh?format=mesh")
check "its result mesh is served" [ "$code" = 200 ] && grep -q Vertices "$WORK/in.mesh"

c=$(post "$WORK/req.json")
if [ "$c" = 201 ] && ! tr -d '\r' <"$WORK/h" | grep -qi '^preference-applied:'; then
    ok "execute without Prefer: asynchronous (the process is async-execute only), no Preference-Applied"
else
    not_ok "execute without Prefer" "code $c" "$(cat "$WORK/h")"
fi
c=$(post "$WORK/req.json" -H 'Prefer: wait=10')
if [ "$c" = 201 ] && ! tr -d '\r' <"$WORK/h" | grep -qi '^preference-applied:'; then
    ok "Prefer: wait is not applied: 201 all the same, no Preference-Applied"
else
    not_ok "execute with Prefer: wait" "code $c" "$(cat "$WORK/h")"
fi
c=$(post "$WORK/req.json" -H 'Idempotency-Key: exec-1')
id1=$(jq -r '.jobID // empty' "$WORK/b")
c2=$(post "$WORK/req.json" -H 'Idempotency-Key: exec-1')
check "an Idempotency-Key replays the same job (201 then 200, one id)" \
    [ "$c" = 201 ] && [ "$c2" = 200 ] && [ "$(jq -r .jobID "$WORK/b")" = "$id1" ]

# ---------------------------------------------------------- refusals
refused() { # DESC STATUS PATTERN FILE [CURL ARGS]
    local desc=$1 want=$2 pat=$3 f=$4
    shift 4
    local c
    c=$(post "$f" "$@")
    if [ "$c" = "$want" ] && is_problem "$want" && detail | grep -q -- "$pat"; then
        ok "$desc: $want problem+json"
    else
        not_ok "$desc" "code $c" "$(cat "$WORK/b")"
    fi
}
request '{"clamp": {"kind": "ball", "center": [0, 0], "radius": 0.1}, "max_iter": -3}'
refused "a bad parameter is judged as for multipart" 422 "max_iter" "$WORK/req.json"
jq -r '.["invalid-params"][0].name // empty' "$WORK/b" | grep -q max_iter &&
    ok "the 422 names the parameter in invalid-params" || not_ok "invalid-params" "$(cat "$WORK/b")"
request "$(quick_params 5)" '{"template": {"href": "http://127.0.0.1:1/disk.mesh"}}'
refused "an input by reference (href)" 400 "href" "$WORK/req.json"
request "$(quick_params 5)" '{"target_sol": {"value": "not*base64"}}'
refused "a value that is not base64" 400 "not base64" "$WORK/req.json"
request "$(quick_params 5)" '{"target_sol": {"value": "AAAA", "encoding": "utf8"}}'
refused "an encoding other than base64" 400 "encoding" "$WORK/req.json"
request "$(quick_params 5)" '{"colour": 3}'
refused "an unknown input" 400 "unknown input" "$WORK/req.json"
request "$(quick_params 5)" '{"target_surface": {"value": "AAAA"}}'
refused "target_surface with target_sol" 422 "excludes target_sol" "$WORK/req.json"
request "$(quick_params 5)"
jq 'del(.inputs.target_sol)' "$WORK/req.json" >"$WORK/nosol.json"
refused "a missing input" 400 "target_sol" "$WORK/nosol.json"
jq '.subscriber = {successUri: "http://127.0.0.1:1/"}' "$WORK/req.json" >"$WORK/sub.json"
refused "a subscriber (callbacks are not implemented)" 400 "subscriber" "$WORK/sub.json"
printf '{"inputs": ' >"$WORK/trunc.json"
refused "a body that is not JSON" 400 "not JSON" "$WORK/trunc.json"
request "$(quick_params 5)"
c=$(curl -sS -D "$WORK/h" -o "$WORK/b" -w '%{http_code}' -H 'Content-Type: text/plain' \
    --data-binary "@$WORK/req.json" "$EXEC")
check "a body that is not application/json: 415 problem+json" \
    [ "$c" = 415 ] && is_problem 415 && detail | grep -q application/json
c=$(curl -sS -o "$WORK/b" -w '%{http_code}' -H 'Content-Type: application/json' \
    --data-binary "@$WORK/req.json" "$BASE/v1/processes/other/execution")
check "an unknown process: 404" [ "$c" = 404 ] && grep -q no-such-process "$WORK/b"
c=$(curl -sS -o /dev/null -w '%{http_code}' "$EXEC")
check "GET on the execution route: 405" [ "$c" = 405 ]

# ---------------------------------------------------------- an image target
# the sphere label map of tests/cli/image_shapes.py (NIfTI-1), a gmsh ball
# inside it as the template: target_image inline is the image part of the
# multipart upload (its label read, its refusals, the job's summary)
PY=/usr/bin/python3
[ -x "$PY" ] || PY=python3
mkdir -p "$WORK/img" && "$PY" "$ROOT/tests/cli/image_shapes.py" write "$WORK/img" sphere >/dev/null &&
    printf 'SetFactory("OpenCASCADE");\nSphere(1) = {4, 39, 9, 8.5};\nMesh.MeshSizeFromPoints = 0;\n' \
        >"$WORK/img/ball.geo" &&
    gmsh "$WORK/img/ball.geo" -3 -format msh41 -clmax 4 -nt 1 -v 1 -o "$WORK/img/ball.msh" \
        >/dev/null 2>&1
check "the sphere image and the ball template are made" [ -s "$WORK/img/ball.msh" ]
# image_request PARAMS_JSON [EXTRA_INPUTS_JSON]
image_request() {
    jq -n --rawfile t <(base64 -w0 "$WORK/img/ball.msh") --rawfile i <(base64 -w0 "$WORK/img/s1.nii") \
        --argjson p "$1" --argjson x "${2:-{\}}" \
        '{inputs: ({template: {value: $t}, target_image: {value: $i}, params: $p} + $x)}' \
        >"$WORK/img.json"
}
IMG_CLAMP='"clamp": {"kind": "ball", "center": [4, 39, 9], "radius": 4.5}, "max_iter": 1'
image_request "{$IMG_CLAMP, \"label\": 1}"
c=$(post "$WORK/img.json")
id=$(jq -r '.jobID // empty' "$WORK/b" 2>/dev/null)
if [ "$c" = 201 ] && [ -n "$id" ] && wait_final "$id" $((60 * SLOW)) && state_is "$id" successful &&
    hcurl "$BASE/v1/jobs/$id/results" >"$WORK/img_summary.json" &&
    jq -e '.target_image.voxels == 1921 and .target_image.label == 1 and
           .inputs.target_image == "inputs/target_image.image"' "$WORK/img_summary.json" >/dev/null; then
    ok "execute with target_image: the job runs on the image's label (1921 voxels in the summary)"
else
    not_ok "execute with target_image" "code $c" "$(head -c 600 "$WORK/b")" \
        "$(head -c 600 "$WORK/img_summary.json" 2>/dev/null)"
fi
image_request "{$IMG_CLAMP, \"label\": 2}"
refused "target_image with a label that selects nothing" 422 "label-empty" "$WORK/img.json"
image_request "{$IMG_CLAMP}" "{\"target_sol\": {\"value\": \"$(base64 -w0 "$BOXSOL")\"}}"
refused "target_image with target_sol" 422 "excludes target_sol" "$WORK/img.json"
stop_daemon
SPOOL=
start_daemon small --workers 1 --max-upload 4096 || { not_ok "the small daemon starts"; exit 1; }
EXEC=$BASE/v1/processes/match/execution
refused "a request over --max-upload" 413 "max-upload" "$WORK/req.json"
c=$(curl -sS "$BASE/v1/conformance" | jq -r '.conformsTo | index("http://www.opengis.net/spec/ogcapi-processes-1/1.0/conf/core") != null')
check "/v1/conformance lists core" [ "$c" = true ]
check "nothing is left in the spool's tmp" [ -z "$(ls -A "$SPOOL/tmp" 2>/dev/null)" ]
check "no sanitizer reports" reports_clean
echo "1..$n"
