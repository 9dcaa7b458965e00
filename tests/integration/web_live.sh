#!/usr/bin/env bash
# The live mesh (issue 11): GET /v1/jobs/{id}/mesh/latest answers 404
# result-not-ready while a job is queued, then the shape the worker
# publishes as the job runs (binary payload by default, Medit with
# ?format=mesh), replaced as it moves (by time, ~0.5 s, and every
# live_every iterations); the last one stays after the end; a bad format
# is 400, an unknown job 404 no-such-job.
source "$(dirname "$0")/lib.sh"

if ! make_case; then
    not_ok "gmsh builds the test meshes" "$(tail -5 "$WORK/case/gmsh.log")"
    exit 1
fi
ok "gmsh builds the test meshes"
start_daemon live --workers 1 --kill-grace 1 || { not_ok "the daemon starts"; exit 1; }
ok "the daemon starts"

# get ID [QUERY]: the status; the body in $WORK/live.out
get() {
    curl -sS --max-time $((10 * SLOW)) -D "$WORK/live.h" -o "$WORK/live.out" -w '%{http_code}' \
        "$BASE/v1/jobs/$1/mesh/latest${2:-}"
}
published() { [ "$(get "$1")" = 200 ]; }

A=$(submit "$FINE" "$BOX" "$BOXSOL" "$(endless_params)")
B=$(submit "$DISK" "$BOX" "$BOXSOL" "$BALL_PARAMS, \"max_iter\": 30, \"live_every\": 1}")
[ -n "$A" ] && [ -n "$B" ] || { not_ok "two jobs are accepted" "$(cat "$WORK/submit.out")"; exit 1; }
wait_state "$A" running 30
c=$(get "$B")
if [ "$c" = 404 ] && state_is "$B" accepted &&
    jq -e '.type | endswith("result-not-ready")' "$WORK/live.out" >/dev/null; then
    ok "a queued job: 404 result-not-ready"
else
    not_ok "mesh/latest of a queued job" "code $c $(job_state "$B")" "$(cat "$WORK/live.out")"
fi

if poll 30 published "$A" && [ "$(head -c 6 "$WORK/live.out")" = SMMESH ] &&
    tr -d '\r' <"$WORK/live.h" | grep -qi '^content-type: application/vnd.shapematch.mesh' &&
    tr -d '\r' <"$WORK/live.h" | grep -qi '^cache-control: no-store'; then
    ok "a running job publishes its shape: the binary payload by default, no-store"
else
    not_ok "the live payload" "$(cat "$WORK/live.h")"
fi
cp "$WORK/live.out" "$WORK/first.smmesh"
changed() { get "$A" >/dev/null && ! cmp -s "$WORK/live.out" "$WORK/first.smmesh"; }
if poll 10 changed; then
    ok "the shape is replaced as the job runs (about every 0.5 s)"
else
    not_ok "the live shape changes"
fi
c=$(get "$A" '?format=mesh')
if [ "$c" = 200 ] && grep -q '^MeshVersionFormatted' "$WORK/live.out" && grep -q '^Triangles' "$WORK/live.out"; then
    ok "?format=mesh: the Medit file"
else
    not_ok "?format=mesh" "code $c" "$(head -c 300 "$WORK/live.out")"
fi
c=$(get "$A" '?format=vtu')
check "?format=vtu: 400" [ "$c" = 400 ]
c=$(get 0123456789abcdef0123456789abcdef)
check "an unknown job: 404" [ "$c" = 404 ]
curl -sS -o /dev/null -X DELETE "$BASE/v1/jobs/$A"

if wait_final "$B" 60 && state_is "$B" successful && [ "$(get "$B")" = 200 ] &&
    [ "$(head -c 6 "$WORK/live.out")" = SMMESH ]; then
    ok "with live_every: 1, a finished job keeps its last shape"
else
    not_ok "the last shape" "$(job_state "$B")"
fi
# the worker logged no failed publication
if ! grep -q "live mesh not published" "$SPOOL"/jobs/*/worker.log 2>/dev/null; then
    ok "no failed publication in the workers' logs"
else
    not_ok "publications failed" "$(grep -h "live mesh" "$SPOOL"/jobs/*/worker.log)"
fi
check "metrics count the route under its own label" \
    grep -q 'route="/v1/jobs/{id}/mesh/latest"' <(hcurl "$BASE/metrics")
check "no sanitizer reports" reports_clean
echo "1..$n"
