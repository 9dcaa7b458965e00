#!/usr/bin/env bash
# The web app's routes with curl (issue 11; the browser half is web_app):
# GET / gives a browser the page and any other client the JSON landing;
# /app/{file} serves web/ and the npm libraries embedded at build time
# (three's module rewritten to import ./three-core.js), public even with
# tokens, while the JSON landing keeps requiring one; the page says
# whether the daemon wants a token; /v1/jobs/{id}/inputs/{part} serves a
# job's stored uploads (the target overlay's source) and nothing else.
source "$(dirname "$0")/lib.sh"

HTML='text/html,application/xhtml+xml,application/xml;q=0.9,*/*;q=0.8'
ctype() { tr -d '\r' <"$WORK/h" | awk 'tolower($1) == "content-type:" { print $2 }' | tr -d ';'; }
get() { # URL [CURL ARGS]: the status; headers $WORK/h, body $WORK/b
    local u=$1
    shift
    curl -sS --max-time $((10 * SLOW)) -D "$WORK/h" -o "$WORK/b" -w '%{http_code}' "$@" "$u"
}

start_daemon open --workers 1 || { not_ok "the daemon starts"; exit 1; }
ok "the daemon starts"
c=$(get "$BASE/" -H "Accept: $HTML")
check "GET / from a browser: the web app (text/html, data-tokens=\"0\")" \
    [ "$c" = 200 ] && [ "$(ctype)" = text/html ] && grep -q 'src="app/app.js"' "$WORK/b" &&
    grep -q 'data-tokens="0"' "$WORK/b" && cmp -s "$WORK/b" "$ROOT/web/index.html"
c=$(get "$BASE/")
check "GET / from an API client: the JSON landing page" \
    [ "$c" = 200 ] && [ "$(ctype)" = application/json ] && jq -e '.links | length > 0' "$WORK/b" >/dev/null
for f in app.js view.js target.js align.js warp.js app.css favicon.svg; do
    c=$(get "$BASE/app/$f")
    check "/app/$f is web/$f" [ "$c" = 200 ] && cmp -s "$WORK/b" "$ROOT/web/$f"
done
declare -A npm=([three-core.js]=three/build/three.core.min.js [orbit.js]=three/examples/jsm/controls/OrbitControls.js
    [uplot.js]=uplot/dist/uPlot.esm.js [uplot.css]=uplot/dist/uPlot.min.css)
for f in "${!npm[@]}"; do
    c=$(get "$BASE/app/$f")
    check "/app/$f is node_modules/${npm[$f]}" [ "$c" = 200 ] && cmp -s "$WORK/b" "$ROOT/node_modules/${npm[$f]}"
done
c=$(get "$BASE/app/three.js")
check "/app/three.js is three's module importing ./three-core.js (text/javascript)" \
    [ "$c" = 200 ] && [ "$(ctype)" = text/javascript ] && grep -q 'from"./three-core.js"' "$WORK/b" &&
    ! grep -q 'three.core.min.js' "$WORK/b"
c=$(get "$BASE/app/three.js" -H 'Accept-Encoding: gzip')
check "the libraries go out gzip-compressed when asked" \
    [ "$c" = 200 ] && tr -d '\r' <"$WORK/h" | grep -qi '^content-encoding: gzip' &&
    [ "$(stat -c %s "$WORK/b")" -lt 200000 ]
c=$(get "$BASE/app/nothing.js")
check "an unknown app file: 404 problem+json" [ "$c" = 404 ] && [ "$(ctype)" = application/problem+json ]
c=$(get "$BASE/app/a-name-longer-than-sixteen.js")
check "a long app file name: 404" [ "$c" = 404 ]
c=$(get "$BASE/app/app.js" -X POST)
check "POST on an app file: 405" [ "$c" = 405 ]
stop_daemon

printf 'routes-token-5e1d\n' >"$WORK/tokens"
SPOOL=
start_daemon token --workers 1 --tokens-file "$WORK/tokens" || { not_ok "the token daemon starts"; exit 1; }
c=$(get "$BASE/" -H "Accept: $HTML")
check "with tokens, the page loads without one and says data-tokens=\"1\"" \
    [ "$c" = 200 ] && grep -q 'data-tokens="1"' "$WORK/b"
c=$(get "$BASE/app/app.js")
check "with tokens, the app's files are public" [ "$c" = 200 ]
c=$(get "$BASE/")
check "with tokens, the JSON landing page still wants one (401)" [ "$c" = 401 ]
c=$(get "$BASE/" -H 'Authorization: Bearer wrong')
check "with tokens, a wrong one is refused at / (401)" [ "$c" = 401 ] && grep -q "not valid" "$WORK/b"
c=$(get "$BASE/" -H 'Authorization: Bearer routes-token-5e1d')
check "with tokens, the JSON landing page with the token (200)" [ "$c" = 200 ] && [ "$(ctype)" = application/json ]
# the job's stored inputs (the web app's target overlay), with the token
AUTH=(-H 'Authorization: Bearer routes-token-5e1d')
if make_case; then
    gzip -c "$BOXSOL" >"$WORK/box.sol.gz"
    id=$(submit "$DISK" "$BOX" "$WORK/box.sol.gz" "$(quick_params 5)")
    c=$(get "$BASE/v1/jobs/$id/inputs" "${AUTH[@]}")
    check "GET /v1/jobs/{id}/inputs lists the three parts sent, with their stored names and sizes" \
        [ "$c" = 200 ] && [ "$(jq -c '[.inputs[] | [.part, .file, .bytes]]' "$WORK/b")" = \
        "[[\"template\",\"template.mesh\",$(stat -c %s "$DISK")],[\"target_mesh\",\"target_mesh.mesh\",$(stat -c %s "$BOX")],[\"target_sol\",\"target_sol.sol.gz\",$(stat -c %s "$WORK/box.sol.gz")]]" ]
    c=$(get "$BASE/v1/jobs/$id/inputs/target_sol" "${AUTH[@]}")
    check "GET /v1/jobs/{id}/inputs/target_sol: the uploaded file as it was sent (gzip), named by its content" \
        [ -n "$id" ] && [ "$c" = 200 ] && [ "$(ctype)" = application/octet-stream ] && cmp -s "$WORK/b" "$WORK/box.sol.gz" &&
        tr -d '\r' <"$WORK/h" | grep -qi '^content-disposition: attachment; filename="target_sol.sol.gz"'
    c=$(get "$BASE/v1/jobs/$id/inputs/template" "${AUTH[@]}")
    check "GET /v1/jobs/{id}/inputs/template: the template" [ "$c" = 200 ] && cmp -s "$WORK/b" "$DISK"
    c=$(get "$BASE/v1/jobs/$id/inputs/target_surface" "${AUTH[@]}")
    check "an input the job was not sent: 404 problem+json" [ "$c" = 404 ] && [ "$(ctype)" = application/problem+json ]
    codes=
    for p in params job.json ..%2Fjob.json nothing; do codes="$codes $(get "$BASE/v1/jobs/$id/inputs/$p" "${AUTH[@]}")"; done
    check "anything but the four file parts is 404 (params, job.json, ../job.json, nothing)" [ "$codes" = " 404 404 404 404" ]
    c=$(get "$BASE/v1/jobs/$id/inputs/template")
    check "the inputs want the token (401)" [ "$c" = 401 ]
    c=$(get "$BASE/v1/jobs/0123456789abcdef0123456789abcdef/inputs/template" "${AUTH[@]}")
    check "the inputs of no job: 404" [ "$c" = 404 ]
    wait_final "$id" 60 >/dev/null
else
    not_ok "gmsh builds the test meshes" "$(tail -5 "$WORK/case/gmsh.log")"
fi
check "no sanitizer reports" reports_clean
echo "1..$n"
