#!/usr/bin/env bash
# The web app's batch view (web/batch.js) in real Chromium (web_batch.mjs:
# the checks): a daemon, the disk template matched onto 4 circles of
# radius 0.60, 0.70, 0.80, 0.85 (4 ordinary jobs grouped by POST
# /v1/batches), opened in the app by #batch=ID while it runs, then from
# the jobs list (the model job offers its batch view).  Release
# variant only (the page is the same in both; the daemon side is
# daemon_batches.sh's in every variant).  Screenshot in build/test-logs/.
source "$(dirname "$0")/lib.sh"

if [ "$VARIANT" != release ]; then
    skip "browser tests run in the release variant only (daemon_batches covers the daemon in every variant)"
    echo "1..$n"
    exit 0
fi
if [ ! -x /usr/bin/chromium ] || [ ! -d "$ROOT/node_modules/playwright-core" ]; then
    not_ok "chromium and playwright-core are installed (make deps)" "$(ls -l /usr/bin/chromium 2>&1)"
    echo "1..$n"
    exit 1
fi
if ! make_case; then
    not_ok "gmsh builds the test meshes" "$(tail -5 "$WORK/case/gmsh.log")"
    exit 1
fi
start_daemon web-batch --workers 2 || { not_ok "daemon starts"; exit 1; }
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
node "$ROOT/tests/integration/web_batch.mjs" "$BASE" "$B" "$RADII" "$ROOT/build/test-logs" \
    >"$WORK/node.out" 2>"$WORK/node.err"
rc=$?
while IFS= read -r line; do
    desc=$(jq -r .desc <<<"$line" 2>/dev/null) || continue
    if [ "$(jq -r .ok <<<"$line")" = true ]; then
        ok "$desc"
    else
        not_ok "$desc" "$(jq -r .detail <<<"$line")"
    fi
done <"$WORK/node.out"
[ "$rc" = 0 ] || not_ok "the browser driver runs" "exit $rc" "$(tail -20 "$WORK/node.err")"
stop_daemon
echo "1..$n"
