#!/usr/bin/env bash
# Batches on the spool (server/api/smd_batches.h, docs/api.md "Batches"):
# a template (the disk of radius 0.5) matched onto 6 targets, the circles
# of radius R = 0.60 .. 0.85 (box background, analytic signed distance),
# submitted as 6 ordinary jobs and grouped by POST /v1/batches; the model
# job runs once they all ended.  Checked against what is known without
# the code: the family has one parameter (R), so after rigid Procrustes
# the first mode carries >= 95% of the variance and its scores are linear
# in R (|correlation| > 0.99, computed here with awk); the per-target
# status, counts, progress and ETA of GET /v1/batches/{id}, and its
# event stream (NDJSON followed live, SSE resumed); the model's files;
# the CLI's `shapematch batch --server` (submit, group, follow, fetch).  Then: a failing target (its worker exits 3: a wrapper worker
# fails the jobs whose params hold the marker max_iter 7) is reported and
# left out of the model, not fatal; DELETE of a live batch cancels the
# model job and every live member it owns alone; DELETE of a final one
# deletes it and the members it dismissed, while a member another batch
# shares and one that finished stay (unless ?members=all); the limits (--max-batch-targets: 413; unknown, foreign, duplicate
# or model jobs: 422; a body that is not JSON: 415/400).
source "$(dirname "$0")/lib.sh"

if ! make_case; then
    not_ok "gmsh builds the test meshes" "$(tail -5 "$WORK/case/gmsh.log")"
    exit 1
fi
RADII="0.60 0.65 0.70 0.75 0.80 0.85"
for R in $RADII 0.6 0.7 0.8; do
    awk -v R="$R" -f "$WORK/case/sdf.awk" "$BOX" >"$WORK/case/box-$R.sol"
done
cat >"$WORK/fail-worker.sh" <<EOF
#!/bin/sh
# the jobs whose params say max_iter 7 fail, as a worker that dies does
grep -q '"max_iter": 7,' "\$1/job.json" && exit 3
exec "$BIN/shapematch-worker" "\$@"
EOF
chmod +x "$WORK/fail-worker.sh"
start_daemon batches --workers 2 --max-batch-targets 8 --kill-grace 1 \
    --worker "$WORK/fail-worker.sh" || { not_ok "daemon starts"; exit 1; }

# targets [MAX_ITER] R...: submits one job per radius, prints the ids
targets() {
    local it=$1 R id
    shift
    for R in "$@"; do
        id=$(submit "$DISK" "$BOX" "$WORK/case/box-$R.sol" "$(quick_params "$it")")
        [ -n "$id" ] || { echo "# submit failed: $(cat "$WORK/submit.out")" >&2; return 1; }
        echo "$id"
    done
}
# batch_body ALIGN ID...: the description, members named r1, r2, ...
batch_body() {
    local align=$1 k=0 id
    shift
    for id in "$@"; do
        k=$((k + 1))
        echo "{\"job\": \"$id\", \"name\": \"r$k\"}"
    done | jq -s --arg a "$align" '{targets: ., model_align: $a}'
}
# post_batch BODY: the reply in $WORK/batch.out, prints the HTTP code
post_batch() {
    hcurl -o "$WORK/batch.out" -w '%{http_code}' -H 'Content-Type: application/json' \
        --data-binary "$1" "$BASE/v1/batches"
}
batch_state() { hcurl "$BASE/v1/batches/$1" | jq -r .status; }
batch_final() { case $(batch_state "$1") in successful | failed | dismissed) return 0 ;; esac; return 1; }

# ------------------------------------------------------------ the family
mapfile -t IDS < <(targets 30 $RADII)
code=$(post_batch "$(batch_body rigid "${IDS[@]}")")
B=$(jq -r '.batchID // empty' "$WORK/batch.out")
if [ "$code" = 201 ] && [ -n "$B" ] && [ "$(jq -r '.counts.total' "$WORK/batch.out")" = 6 ] &&
    [ "$(jq -r '.model.processID' "$WORK/batch.out")" = shape-model ]; then
    ok "POST /v1/batches: 201, the batch of 6 targets ($B)"
else
    not_ok "POST /v1/batches" "$code $(cat "$WORK/batch.out")"
fi
# while it runs: the document's progress is 0..100 and its ETA a number or null
doc=$(hcurl "$BASE/v1/batches/$B")
if jq -e '(.progress >= 0 and .progress <= 100) and (.eta == null or (.eta | type) == "number")
          and (.targets | length) == 6 and (.targets[0].href | startswith("/v1/jobs/"))' \
    <<<"$doc" >/dev/null; then
    ok "GET /v1/batches/{id}: per-target status, progress $(jq .progress <<<"$doc"), eta $(jq .eta <<<"$doc")"
else
    not_ok "the batch document while it runs" "$doc"
fi
poll 60 batch_final "$B"
doc=$(hcurl "$BASE/v1/batches/$B")
if jq -e '.status == "successful" and .counts.successful == 6 and .progress == 100 and .eta == 0
          and ([.targets[].status] | unique) == ["successful"]' <<<"$doc" >/dev/null; then
    ok "the batch ends successful: 6 targets and the model"
else
    not_ok "the batch ends successful" "$doc"
fi
# SSE on the final batch: the current state of every target, one batch
# event with id: = its seq, the status; resuming with that id sends the
# status only (nothing changed), with an older one every target again
sse() { hcurl -N --max-time $((10 * SLOW)) -H 'Accept: text/event-stream' "$@" "$BASE/v1/batches/$B/events"; }
sse >"$WORK/sse0.txt"
V=$(sed -n 's/^id: //p' "$WORK/sse0.txt" | tail -1)
sse -H "Last-Event-ID: $V" >"$WORK/sse1.txt"
sse -H "Last-Event-ID: $((V - 1))" >"$WORK/sse2.txt"
if [ "$(grep -c '^event: target' "$WORK/sse0.txt")" = 6 ] && grep -q "^data: .*\"seq\":$V," "$WORK/sse0.txt" &&
    [ "$(grep -c '^event: ' "$WORK/sse1.txt")" = 1 ] && grep -q '^event: status' "$WORK/sse1.txt" &&
    [ "$(grep -c '^event: target' "$WORK/sse2.txt")" = 6 ]; then
    ok "SSE: 6 targets, id $V, status; Last-Event-ID $V: the status only; $((V - 1)): every target again"
else
    not_ok "the batch's SSE stream and its resumption" "$(head -c 400 "$WORK/sse0.txt") / $(cat "$WORK/sse1.txt")"
fi
codes=$(for u in "/v1/batches/${IDS[0]}/events" "/v1/batches/0123456789abcdef0123456789abcdef/events"; do
    hcurl -o /dev/null -w '%{http_code} ' "$BASE$u"
done; hcurl -o /dev/null -w '%{http_code} ' -H 'Accept: text/html' "$BASE/v1/batches/$B/events"
hcurl -o /dev/null -w '%{http_code}' -H 'Last-Event-ID: x' "$BASE/v1/batches/$B/events")
if [ "$codes" = "404 404 406 400" ]; then
    ok "batch events: 404 for a member or an unknown id, 406 for text/html, 400 for a bad Last-Event-ID"
else
    not_ok "batch events refusals" "$codes"
fi
hcurl "$BASE/v1/batches/$B/model" >"$WORK/model.json"
hcurl -o "$WORK/scores.csv" "$BASE/v1/batches/$B/model/scores.csv"
hcurl -o "$WORK/mean.mesh" "$BASE/v1/batches/$B/model/mean.mesh"
hcurl -o "$WORK/mode_1.sol" "$BASE/v1/batches/$B/model/mode_1.sol"
if jq -e '.summary.members == 6 and .summary.variance_explained[0] >= 0.95
          and (.files | map(.name) | index("mode_1.sol")) != null' "$WORK/model.json" >/dev/null &&
    head -1 "$WORK/scores.csv" | grep -q '^target,mode1' && grep -q Vertices "$WORK/mean.mesh" &&
    grep -q SolAtVertices "$WORK/mode_1.sol"; then
    ok "the model: mode 1 carries $(jq '.summary.variance_explained[0]' "$WORK/model.json") of the variance (>= 0.95); mean.mesh, mode_1.sol, scores.csv served"
else
    not_ok "the model of the family" "$(head -c 600 "$WORK/model.json")"
fi
# scores of mode 1 against the radii: linear (Pearson's r from awk)
r=$(awk -F, -v radii="$RADII" 'BEGIN { split(radii, R, " ") }
    NR > 1 { k = substr($1, 2) + 0; x = R[k]; y = $2; n++; sx += x; sy += y; sxx += x * x; syy += y * y; sxy += x * y }
    END { c = (n * sxy - sx * sy) / sqrt((n * sxx - sx * sx) * (n * syy - sy * sy)); printf "%.4f", c < 0 ? -c : c }' \
    "$WORK/scores.csv")
if awk -v r="$r" 'BEGIN { exit !(r > 0.99) }'; then
    ok "mode 1's scores are linear in the radius: |r| = $r"
else
    not_ok "scores linear in the radius" "|r| = $r; $(cat "$WORK/scores.csv")"
fi
# the members stay ordinary jobs, their results as before
if [ "$(hcurl -o /dev/null -w '%{http_code}' "$BASE/v1/jobs/${IDS[0]}/results/mesh")" = 200 ]; then
    ok "a member's own results are served as any job's"
else
    not_ok "a member's results"
fi

# ----------------------------------------- the CLI: shapematch batch --server
# three circles from a LIST.csv: submitted, grouped, followed, fetched
printf 'name,target_mesh,target_sol\n' >"$WORK/list.csv"
for k in 1 2 3; do R=$(echo "0.6 0.7 0.8" | cut -d' ' -f$k); echo "r$k,$BOX,$WORK/case/box-$R.sol"; done >>"$WORK/list.csv"
"$BIN/shapematch" batch --server "$BASE" --template "$DISK" --targets "$WORK/list.csv" \
    --clamp-ball 0,0,0.1 --max-iter 30 -o "$WORK/cli" >"$WORK/cli.out" 2>"$WORK/cli.log"
rc=$?
CB_ID=$(jq -r '.batchID // empty' "$WORK/cli/batch.json" 2>/dev/null)
r=$(awk -F, -v radii="0.6 0.7 0.8" 'BEGIN { split(radii, R, " ") }
    NR > 1 { k = substr($1, 2) + 0; x = R[k]; y = $2; n++; sx += x; sy += y; sxx += x * x; syy += y * y; sxy += x * y }
    END { if (n < 3) { print 0; exit } c = (n * sxy - sx * sy) / sqrt((n * sxx - sx * sx) * (n * syy - sy * sy)); printf "%.4f", c < 0 ? -c : c }' \
    "$WORK/cli/model/scores.csv" 2>/dev/null)
if [ "$rc" = 0 ] && [ -n "$CB_ID" ] && jq -e '.status == "successful" and .counts.successful == 3' "$WORK/cli/batch.json" >/dev/null &&
    for k in 1 2 3; do [ -s "$WORK/cli/targets/r$k/result.mesh" ] || exit 1; done &&
    hcurl "$BASE/v1/batches/$CB_ID/model/scores.csv" | cmp -s - "$WORK/cli/model/scores.csv" &&
    grep -q Vertices "$WORK/cli/model/mean.mesh" && awk -v r="$r" 'BEGIN { exit !(r > 0.99) }' &&
    grep -q "batch $CB_ID of 3 targets" "$WORK/cli.log"; then
    ok "shapematch batch --server: 3 targets submitted and fetched into targets/r1..r3, the model's files (scores.csv = the daemon's; mode 1 linear in R, |r| = $r)"
else
    not_ok "shapematch batch --server" "rc $rc: $(tail -5 "$WORK/cli.log")"
fi
# it followed the batch by its event stream, not by polling the document
streams=$(grep -c "\"path\":\"/v1/batches/$CB_ID/events\"" "$DLOG")
polls=$(grep -c "\"path\":\"/v1/batches/$CB_ID\"" "$DLOG")
if [ -n "$CB_ID" ] && [ "$streams" -ge 1 ] && [ "$polls" = 0 ] && grep -q "successful, 100%: 3 of 3 targets ended" "$WORK/cli.log"; then
    ok "batch --server follows GET /v1/batches/{id}/events ($streams stream(s), no GET of the batch document) and shows its progress"
else
    not_ok "batch --server follows the event stream" "streams $streams, polls $polls" "$(cat "$WORK/cli.log")"
fi
"$BIN/shapematch" batch --server "$BASE" --template "$DISK" --target-mesh "$BOX" --target-sol "$WORK/case/box-0.6.sol" \
    --clamp-ball 0,0,0.1 --jobs 2 -o "$WORK/cli2" 2>"$WORK/cli2.log"
rc=$?
if [ "$rc" = 1 ] && grep -q -- "--jobs is for a local batch" "$WORK/cli2.log"; then
    ok "shapematch batch --server refuses a local-only option (--jobs: exit 1)"
else
    not_ok "batch --server with --jobs" "rc $rc: $(cat "$WORK/cli2.log")"
fi

# ------------------------------------------------------ a failing target
mapfile -t F < <(targets 30 0.6 0.7; targets 7 0.8)
code=$(post_batch "$(batch_body similarity "${F[@]}")")
FB=$(jq -r '.batchID // empty' "$WORK/batch.out")
poll 60 batch_final "$FB"
doc=$(hcurl "$BASE/v1/batches/$FB")
model=$(hcurl "$BASE/v1/batches/$FB/model")
if jq -e '.status == "successful" and .counts.failed == 1 and .counts.successful == 2
          and (.model.message | test("left out.*r3"))' <<<"$doc" >/dev/null &&
    jq -e '.summary.members == 2' <<<"$model" >/dev/null; then
    ok "a failing target is reported and left out: $(jq -r .model.message <<<"$doc")"
else
    not_ok "a failing target" "$doc $(head -c 300 <<<"$model")"
fi
# every target failing: the model job fails, saying why
mapfile -t G < <(targets 7 0.6)
post_batch "$(batch_body rigid "${G[@]}")" >/dev/null
GB=$(jq -r '.batchID // empty' "$WORK/batch.out")
poll 30 batch_final "$GB"
if [ "$(batch_state "$GB")" = failed ] &&
    hcurl "$BASE/v1/batches/$GB" | jq -e '.model.message | test("no target")' >/dev/null &&
    [ "$(hcurl -o /dev/null -w '%{http_code}' "$BASE/v1/batches/$GB/model")" = 409 ]; then
    ok "no target succeeded: the batch fails, its model answers 409"
else
    not_ok "a batch without a successful target" "$(hcurl "$BASE/v1/batches/$GB")"
fi

# ---------------------------------------------------------------- cancel
mapfile -t C < <(for R in 0.6 0.7 0.8; do
    submit "$FINE" "$BOX" "$WORK/case/box-$R.sol" "$(endless_params)"
done)
post_batch "$(batch_body rigid "${C[@]}")" >/dev/null
CB=$(jq -r '.batchID // empty' "$WORK/batch.out")
# its event stream (NDJSON), followed live until the daemon closes it
hcurl -N -H 'Accept: application/x-ndjson' "$BASE/v1/batches/$CB/events" \
    >"$WORK/batch-events.ndjson" 2>"$WORK/batch-events.err" &
EVPID=$!
poll 20 state_is "${C[0]}" running
iterating() { grep -q '"type":"target".*"status":"running".*"iteration":[1-9]' "$WORK/batch-events.ndjson"; }
poll 20 iterating
doc=$(hcurl -X DELETE "$BASE/v1/batches/$CB")
# the stream: every target (r1..r3), one running with its iteration, batch
# events whose seq grows, then (the cancel) the dismissed targets and last
# the status with the final document; closed by the daemon
if wait "$EVPID" && jq -e -s '
      ([.[] | select(.type == "target") | .name] | unique) == ["r1","r2","r3"]
      and any(.[]; .type == "target" and .status == "running" and .iteration >= 1)
      and any(.[]; .type == "target" and .status == "dismissed")
      and ([.[] | select(.type == "batch") | .seq] | . == sort and length >= 2)
      and (last | .type == "status" and .status == "dismissed" and .counts.dismissed == 3)
      and ([.[] | select(.type == "status")] | length) == 1' "$WORK/batch-events.ndjson" >/dev/null; then
    ok "GET /v1/batches/{id}/events (NDJSON) live: $(grep -c '"target"' "$WORK/batch-events.ndjson") target and $(grep -c '"batch"' "$WORK/batch-events.ndjson") batch events, the cancel, the final status; closed at the end"
else
    not_ok "the batch's event stream" "$(tail -c 800 "$WORK/batch-events.ndjson") $(cat "$WORK/batch-events.err")"
fi
poll 20 batch_final "$CB"
all_dismissed() {
    local id
    for id in "$CB" "${C[@]}"; do state_is "$id" dismissed || return 1; done
}
if poll 20 all_dismissed && [ "$(batch_state "$CB")" = dismissed ]; then
    ok "DELETE of a live batch cancels the model job and every member"
else
    not_ok "cancel" "$doc; $(hcurl "$BASE/v1/batches/$CB")"
fi
code=$(hcurl -o "$WORK/del.out" -w '%{http_code}' -X DELETE "$BASE/v1/batches/$CB")
if [ "$code" = 200 ] && [ "$(job_state "${C[1]}")" = 404 ] && [ "$(job_state "$CB")" = 404 ] &&
    [ "$(hcurl -o /dev/null -w '%{http_code}' "$BASE/v1/batches/$CB")" = 404 ]; then
    ok "DELETE of a final batch deletes it and its members"
else
    not_ok "delete of a final batch" "$code $(cat "$WORK/del.out")"
fi

# ------------------------------ deletion keeps shared and finished members
# X = {done (finished), shared (running, also in batch Y), own (running)}
mapfile -t D1 < <(targets 5 0.6)
wait_final "${D1[0]}" 60
mapfile -t D2 < <(for R in 0.7 0.8; do submit "$FINE" "$BOX" "$WORK/case/box-$R.sol" "$(endless_params)"; done)
DONE=${D1[0]} SHARED=${D2[0]} OWN=${D2[1]}
post_batch "$(batch_body rigid "$DONE" "$SHARED" "$OWN")" >/dev/null
XB=$(jq -r '.batchID // empty' "$WORK/batch.out")
post_batch "$(batch_body rigid "$SHARED")" >/dev/null
YB=$(jq -r '.batchID // empty' "$WORK/batch.out")
poll 20 state_is "$SHARED" running
poll 20 state_is "$OWN" running
bad=$(hcurl -o /dev/null -w '%{http_code}' -X DELETE "$BASE/v1/batches/$XB?members=some")
c1=$(hcurl -o /dev/null -w '%{http_code}' -X DELETE "$BASE/v1/batches/$XB")
poll 20 state_is "$OWN" dismissed
s1="$(job_state "$XB") $(job_state "$DONE") $(job_state "$SHARED") $(job_state "$OWN")"
c2=$(hcurl -o /dev/null -w '%{http_code}' -X DELETE "$BASE/v1/batches/$XB")
s2="$(job_state "$XB") $(job_state "$DONE") $(job_state "$SHARED") $(job_state "$OWN")"
if [ "$bad" = 400 ] && [ "$c1" = 200 ] && [ "$s1" = "dismissed successful running dismissed" ] &&
    [ "$c2" = 200 ] && [ "$s2" = "404 successful running 404" ]; then
    ok "DELETE of a batch twice: the members it owns alone go (cancelled, then deleted); a shared running member and a finished one stay"
else
    not_ok "batch deletion keeps shared and finished members" "?members=some $bad; first $c1: $s1; second $c2: $s2"
fi
# ?members=all: every member goes with the batch, shared ones too
c1=$(hcurl -o /dev/null -w '%{http_code}' -X DELETE "$BASE/v1/batches/$YB?members=all")
poll 20 state_is "$SHARED" dismissed
c2=$(hcurl -o /dev/null -w '%{http_code}' -X DELETE "$BASE/v1/batches/$YB?members=all")
# DONE belongs to no batch any more: ?members=all on a batch of it deletes it
post_batch "$(batch_body rigid "$DONE")" >/dev/null
ZB=$(jq -r '.batchID // empty' "$WORK/batch.out")
poll 30 batch_final "$ZB"
c3=$(hcurl -o /dev/null -w '%{http_code}' -X DELETE "$BASE/v1/batches/$ZB?members=all")
s3="$(job_state "$YB") $(job_state "$SHARED") $(job_state "$ZB") $(job_state "$DONE")"
if [ "$c1 $c2 $c3" = "200 200 200" ] && [ "$s3" = "404 404 404 404" ]; then
    ok "DELETE ?members=all: shared and finished members are cancelled, then deleted, with the batch"
else
    not_ok "DELETE ?members=all" "$c1 $c2 $c3: $s3"
fi

# ---------------------------------------------------------------- limits
# (the count is checked first: 9 ids, known or not, are refused for it)
mapfile -t L < <(targets 2 0.6)
code=$(post_batch "$(batch_body rigid "${L[0]}" $(seq 8 | awk '{ printf "%032x\n", $1 }'))")
if [ "$code" = 413 ] && jq -e '.detail | test("--max-batch-targets")' "$WORK/batch.out" >/dev/null; then
    ok "9 targets beyond --max-batch-targets 8: 413 naming the flag"
else
    not_ok "the targets limit" "$code $(cat "$WORK/batch.out")"
fi
c1=$(post_batch '{"targets": []}')
c2=$(post_batch "$(batch_body rigid "${L[0]}" "${L[0]}")")
c3=$(post_batch "$(batch_body rigid 0123456789abcdef0123456789abcdef)")
c4=$(post_batch "$(batch_body rigid "$B")")
c5=$(post_batch '{"targets": [{"job": "'"${L[0]}"'"}], "model_align": "affine"}')
c6=$(post_batch 'not json')
c7=$(hcurl -o /dev/null -w '%{http_code}' -F "x=1" "$BASE/v1/batches")
c8=$(post_batch '{"targets": [{"job": "'"${L[0]}"'", "name": "a/b"}]}')
if [ "$c1 $c2 $c3 $c4 $c5 $c6 $c7 $c8" = "422 422 422 422 422 400 415 422" ]; then
    ok "refused: no targets, a job twice, an unknown job, a batch as a target, a bad alignment, a name with '/' (422), not JSON (400), not application/json (415)"
else
    not_ok "the refusals" "$c1 $c2 $c3 $c4 $c5 $c6 $c7 $c8"
fi
codes=$(for u in "/v1/batches/$B/model/result.mesh" "/v1/batches/$B/model/mode_0.sol" \
    "/v1/batches/${IDS[0]}" "/v1/batches/0123456789abcdef0123456789abcdef"; do
    hcurl -o /dev/null -w '%{http_code} ' "$BASE$u"
done)
if [ "$codes" = "404 404 404 404 " ]; then
    ok "404: a file that is not the model's, a member job or an unknown id as a batch"
else
    not_ok "404s" "$codes"
fi

if reports_clean; then ok "no sanitizer reports"; else not_ok "sanitizer reports"; fi
stop_daemon
echo "1..$n"
