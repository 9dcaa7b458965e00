#!/usr/bin/env bash
# run.sh: weight 1 seconds 25 asan 1
# The web app's batch view (web/batch.js) in real Chromium (web_batch.mjs:
# the checks): a daemon, the disk template matched onto 4 circles of
# radius 0.60, 0.70, 0.80, 0.85 (4 ordinary jobs grouped by POST
# /v1/batches), opened in the app by #batch=ID while it runs, then from
# the jobs list (the model job offers its batch view).  Release
# variant only (the page is the same in both; the daemon side is
# daemon_batches.sh's in every variant).  Screenshot in build/test-logs/.
source "$(dirname "$0")/lib.sh"

browser_only "daemon_batches covers the daemon in every variant"
if ! make_case; then
    not_ok "gmsh builds the test meshes" "$(tail -5 "$WORK/case/gmsh.log")"
    exit 1
fi
start_daemon web-batch --workers 2 || { not_ok "daemon starts"; exit 1; }
# two endless jobs hold both workers, so the batch is still queued when
# the page opens it (its view then follows the event stream)
blockers=()
for k in 1 2; do blockers+=("$(submit "$DISK" "$BOX" "$BOXSOL" "$(endless_params)")"); done
RADII="0.60 0.70 0.80 0.85"
ids=()
for R in $RADII; do
    awk -v R="$R" -f "$WORK/case/sdf.awk" "$BOX" >"$WORK/case/box-$R.sol"
    id=$(submit "$DISK" "$BOX" "$WORK/case/box-$R.sol" "$(quick_params 30)")
    [ -n "$id" ] && ids+=("$id")
done
body=$(k=0; for id in "${ids[@]}"; do k=$((k + 1)); echo "{\"job\": \"$id\", \"name\": \"r$k\"}"; done | jq -s '{targets: .}')
B=$(hcurl -H 'Content-Type: application/json' --data-binary "$body" "$BASE/v1/batches" | jq -r '.batchID // empty')
check "a batch of 4 targets submitted" [ -n "$B" ] && [ "${#ids[@]}" = 4 ]
mkdir -p "$ROOT/build/test-logs"
# the blockers go once the page asked for the batch (the daemon's request
# log), at most a minute later
(for _ in $(seq 600); do grep -q "\"path\":\"/v1/batches/$B\"" "$DLOG" && break; sleep 0.1; done
 for b in "${blockers[@]}"; do hcurl -X DELETE "$BASE/v1/jobs/$b" >/dev/null; done) &
node_checks "the browser driver runs" "$ROOT/tests/integration/web_batch.mjs" "$BASE" "$B" "$RADII" "$ROOT/build/test-logs" \
   
stop_daemon
echo "1..$n"
