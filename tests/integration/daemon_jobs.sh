#!/usr/bin/env bash
# run.sh: weight 0.5 seconds 40
# shapematchd end to end: submit examples/2d with curl -F, follow the
# events as SSE to the end, fetch the results in every format and compare
# them with what `shapematch run` writes for the same inputs and
# parameters; resume event streams with Last-Event-ID / ?after without
# loss or duplicates; several followers of one job; cancel a running job;
# delete a finished one; 404 for unknown ids; Idempotency-Key; 20 jobs
# submitted at once all succeed; listing and pagination; a result .meshb
# fed back as an input; clean shutdown (no sanitizer report).
source "$(dirname "$0")/lib.sh"

if ! make_case; then
    not_ok "gmsh builds the test meshes" "$(tail -5 "$WORK/case/gmsh.log")"
    exit 1
fi
ok "gmsh builds the test meshes"

# one BLAS/OpenMP thread per worker, as the CLI run below: the factorization
# is then bit-for-bit reproducible, so the results can be compared exactly
if ! start_daemon jobs --workers 2 --worker-threads 1 --kill-grace 2; then
    not_ok "the daemon starts"
    exit 1
fi
ok "the daemon starts on a free loopback port"

# ---------------------------------------------------------- examples/2d
EX=$ROOT/examples/2d
EXP='{"clamp": {"kind": "elements", "refs": [2]}, "max_iter": 300, "tol_boundary": 1e-4}'
if [ -f "$EX/template.mesh" ] && [ -f "$EX/background.mesh.gz" ] && [ -f "$EX/background.sol.gz" ]; then
    T=$EX/template.mesh M=$EX/background.mesh.gz S=$EX/background.sol.gz
    CLI_ARGS=(--clamp-elements 2 --max-iter 300 --tol-boundary 1e-4)
    P=$EXP
    what="examples/2d"
else
    T=$DISK M=$BOX S=$BOXSOL
    CLI_ARGS=(--clamp-ball 0,0,0.1 --max-iter 60)
    P=$(quick_params 60)
    what="the gmsh disk case (examples/2d missing)"
fi

hdr=$WORK/submit.hdr
code=$(curl -sS -D "$hdr" -o "$WORK/ex.json" -w '%{http_code}' -F "template=@$T" -F "target_mesh=@$M" \
    -F "target_sol=@$S" -F "params=$P" "$BASE/v1/jobs")
ID=$(jq -r '.jobID // empty' "$WORK/ex.json")
loc=$(tr -d '\r' <"$hdr" | awk -F': ' 'tolower($1) == "location" { print $2 }')
if [ "$code" = 201 ] && [ -n "$ID" ] && [ "$loc" = "/v1/jobs/$ID" ] &&
    [ "$(jq -r .status "$WORK/ex.json")" = accepted ]; then
    ok "POST /v1/jobs with $what: 201, Location /v1/jobs/{id}, status accepted"
else
    not_ok "POST /v1/jobs with $what" "code $code location '$loc'" "$(cat "$WORK/ex.json")"
fi

# follow as SSE to the end
sse=$WORK/ex.sse
curl -sS -N --max-time $((60 * SLOW)) -H 'Accept: text/event-stream' "$BASE/v1/jobs/$ID/events" >"$sse"
ids=$(awk '/^id: / { print $2 }' "$sse" | tr '\n' ' ')
nids=$(awk '/^id: / { n++ } END { print n + 0 }' "$sse")
expect_ids=$(seq 1 "$nids" | tr '\n' ' ')
last_event=$(awk '/^event: / { e = $2 } END { print e }' "$sse")
final=$(awk '/^event: status/ { getline; sub(/^data: /, ""); print }' "$sse")
if [ "$nids" -ge 4 ] && [ "$ids" = "$expect_ids" ] && [ "$last_event" = status ] &&
    [ "$(printf '%s' "$final" | jq -r .status)" = successful ] &&
    grep -q '^event: accepted' "$sse" && grep -q '^event: started' "$sse" &&
    grep -q '^event: progress' "$sse" && grep -q '^event: finished' "$sse"; then
    ok "SSE follows the job to the end: ids 1..$nids in order, accepted, started, progress, finished, then a status event"
else
    not_ok "SSE follows the job to the end" "ids: $ids" "last event: $last_event" "$(tail -5 "$sse")"
fi
if [ "$(job_state "$ID")" = successful ]; then ok "the job is successful"; else not_ok "the job is successful" "$(job_state "$ID")"; fi

# the same run with the CLI
CLI=$WORK/cli-out
OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 \
    "$BIN/shapematch" run --template "$T" --target-mesh "$M" --target-sol "$S" "${CLI_ARGS[@]}" -o "$CLI" --quiet \
    >"$WORK/cli.log" 2>&1
R=$WORK/res
mkdir -p "$R"
fetch() { # NAME URL-SUFFIX [CURL ARGS]: body to $R/NAME, prints code content-type
    local name=$1 suffix=$2
    shift 2
    curl -sS -o "$R/$name" -w '%{http_code} %{content_type}' "$@" "$BASE/v1/jobs/$ID/results$suffix"
}
got=$(fetch summary.json "")
if [ "${got%% *}" = 200 ] && [ "$(jq -r .jobID "$R/summary.json")" = "$ID" ] &&
    [ "$(jq -r .stop_reason "$R/summary.json")" = "$(jq -r .stop_reason "$CLI/summary.json")" ] &&
    [ "$(jq -r .iterations "$R/summary.json")" = "$(jq -r .iterations "$CLI/summary.json")" ] &&
    [ "$(jq '[.links[] | select(.rel == "item")] | length' "$R/summary.json")" = 8 ]; then
    ok "results summary: stop reason and iterations as shapematch run, links to 8 files"
else
    not_ok "results summary" "$got" "$(head -c 600 "$R/summary.json")"
fi
got=$(fetch result.mesh /mesh)
if [ "$got" = "200 application/x-medit-mesh" ] && cmp -s "$R/result.mesh" "$CLI/result.mesh"; then
    ok "results/mesh (default Medit ASCII) is byte-identical to shapematch run's result.mesh"
else
    not_ok "results/mesh equals shapematch run" "$got" "$(cmp "$R/result.mesh" "$CLI/result.mesh" 2>&1)"
fi
got=$(fetch result.vtu '/mesh?format=vtu')
if [ "$got" = "200 application/vnd.vtk.vtu+xml" ] && cmp -s "$R/result.vtu" "$CLI/result.vtu"; then
    ok "results/mesh?format=vtu is byte-identical to shapematch run's result.vtu"
else
    not_ok "results/mesh?format=vtu equals shapematch run" "$got" "$(cmp "$R/result.vtu" "$CLI/result.vtu" 2>&1)"
fi
got=$(fetch result.meshb '/mesh?format=meshb')
magic=$(od -An -tx1 -N4 "$R/result.meshb" | tr -d ' ')
if [ "$got" = "200 application/x-medit-meshb" ] && [ "$magic" = 01000000 ]; then
    ok "results/mesh?format=meshb is a little-endian Medit binary file"
else
    not_ok "results/mesh?format=meshb" "$got magic $magic"
fi
got=$(fetch result.smmesh '/mesh?format=binary')
magic=$(head -c 6 "$R/result.smmesh")
if [ "$got" = "200 application/vnd.shapematch.mesh" ] && [ "$magic" = SMMESH ]; then
    ok "results/mesh?format=binary is the binary payload"
else
    not_ok "results/mesh?format=binary" "$got magic $magic"
fi
got=$(fetch accept.bin /mesh -H 'Accept: application/vnd.shapematch.mesh')
if [ "$got" = "200 application/vnd.shapematch.mesh" ] && cmp -s "$R/accept.bin" "$R/result.smmesh"; then
    ok "Accept: application/vnd.shapematch.mesh selects the binary payload"
else
    not_ok "Accept selects the binary payload" "$got"
fi
got=$(fetch accept.meshb /mesh -H 'Accept: text/html;q=0.9, application/x-medit-meshb')
if [ "$got" = "200 application/x-medit-meshb" ] && cmp -s "$R/accept.meshb" "$R/result.meshb"; then
    ok "Accept with several types and q-values picks meshb"
else
    not_ok "Accept picks meshb" "$got"
fi
got=$(fetch gz /mesh -H 'Accept-Encoding: gzip' -D "$R/gz.hdr")
if [ "${got%% *}" = 200 ] && tr -d '\r' <"$R/gz.hdr" | grep -qi '^content-encoding: gzip$' &&
    gzip -dc "$R/gz" | cmp -s - "$R/result.mesh"; then
    ok "Accept-Encoding: gzip gives Content-Encoding: gzip, same content once decompressed"
else
    not_ok "gzip transfer of the mesh" "$got" "$(cat "$R/gz.hdr")"
fi
got=$(fetch disp.sol /displacement)
if [ "$got" = "200 application/x-medit-sol" ] && cmp -s "$R/disp.sol" "$CLI/displacement.sol"; then
    ok "results/displacement is byte-identical to shapematch run's displacement.sol"
else
    not_ok "results/displacement equals shapematch run" "$got"
fi
got=$(fetch disp.solb '/displacement?format=solb')
if [ "$got" = "200 application/x-medit-solb" ] && [ -s "$R/disp.solb" ]; then
    ok "results/displacement?format=solb"
else
    not_ok "results/displacement?format=solb" "$got"
fi
got=$(fetch history.csv /history)
if [ "$got" = "200 text/csv" ] &&
    diff <(cut -d, -f1-6,8-9 "$R/history.csv") <(cut -d, -f1-6,8-9 "$CLI/history.csv") >/dev/null; then
    ok "results/history (CSV) has the rows of shapematch run's history.csv (elapsed aside)"
else
    not_ok "results/history CSV" "$got" "$(diff <(cut -d, -f1-6,8-9 "$R/history.csv") <(cut -d, -f1-6,8-9 "$CLI/history.csv") | head -5)"
fi
got=$(fetch history.json /history -H 'Accept: application/json')
rows=$(jq length "$R/history.json" 2>/dev/null)
if [ "$got" = "200 application/json" ] && [ "$rows" = "$(($(wc -l <"$CLI/history.csv") - 1))" ] &&
    [ "$(jq -r '.[-1].iteration' "$R/history.json")" = "$(jq -r .iterations "$CLI/summary.json")" ]; then
    ok "results/history as JSON (Accept): one row per iteration"
else
    not_ok "results/history JSON" "$got rows $rows"
fi
got=$(fetch bad '/mesh?format=obj')
if [ "${got%% *}" = 400 ] && jq -e '.status == 400 and (.detail | test("format"))' "$R/bad" >/dev/null; then
    ok "an unknown format is 400 (problem+json naming format)"
else
    not_ok "unknown format" "$got"
fi
got=$(fetch bad /mesh -H 'Accept: text/html')
if [ "$got" = "406 application/problem+json" ]; then ok "an Accept that allows no format is 406"; else not_ok "406" "$got"; fi

# a result fed back: the binary .meshb output is a valid template input
id2=$(submit "$R/result.meshb" "$BOX" "$BOXSOL" '{"clamp": {"kind": "none"}, "max_iter": 5}')
if [ "$(cat "$WORK/submit.code")" = 201 ] && [ -n "$id2" ]; then
    ok "the .meshb result is accepted as a template (binary format sniffed)"
else
    not_ok "the .meshb result as a template" "$(cat "$WORK/submit.code")" "$(cat "$WORK/submit.out")"
fi

# ------------------------------------------------------ resuming streams
nd=$WORK/full.ndjson
curl -sS --max-time $((30 * SLOW)) "$BASE/v1/jobs/$ID/events" >"$nd"
total=$(jq -r 'select(.seq) | .seq' "$nd" | wc -l)
bad=0
for k in 0 1 5 $((total - 1)) "$total"; do
    got_ids=$(curl -sS --max-time $((30 * SLOW)) -H 'Accept: text/event-stream' -H "Last-Event-ID: $k" \
        "$BASE/v1/jobs/$ID/events" | awk '/^id: / { print $2 }' | tr '\n' ' ')
    want=$( [ "$k" -lt "$total" ] && seq $((k + 1)) "$total" | tr '\n' ' ')
    [ "$got_ids" = "$want" ] || { bad=1; echo "# Last-Event-ID $k: got '$got_ids'"; }
    got_ids=$(curl -sS --max-time $((30 * SLOW)) "$BASE/v1/jobs/$ID/events?after=$k" |
        jq -r 'select(.seq) | .seq' | tr '\n' ' ')
    [ "$got_ids" = "$want" ] || { bad=1; echo "# after=$k: got '$got_ids'"; }
done
if [ "$bad" = 0 ] && [ "$(tail -1 "$nd" | jq -r .type)" = status ]; then
    ok "replays resume after Last-Event-ID (SSE) and ?after= (NDJSON) exactly, for 0, 1, 5, N-1, N"
else
    not_ok "replay resume"
fi

# live: cut a stream in the middle of a running job, resume with the last id
LIVE=$(submit "$DISK" "$BOX" "$BOXSOL" "$(quick_params 1500)")
part1=$WORK/live1.sse
curl -sS -N --max-time $((60 * SLOW)) -H 'Accept: text/event-stream' "$BASE/v1/jobs/$LIVE/events" 2>/dev/null |
    head -n 120 >"$part1"
last=$(awk '/^id: / { i = $2 } END { print i }' "$part1")
state_mid=$(job_state "$LIVE")
part2=$WORK/live2.sse
curl -sS -N --max-time $((60 * SLOW)) -H 'Accept: text/event-stream' -H "Last-Event-ID: $last" \
    "$BASE/v1/jobs/$LIVE/events" >"$part2"
all=$(cat "$part1" "$part2" | awk '/^id: / { print $2 }')
count=$(printf '%s\n' "$all" | wc -l)
if [ -n "$last" ] && [ "$(printf '%s\n' "$all" | tr '\n' ' ')" = "$(seq 1 "$count" | tr '\n' ' ')" ] &&
    grep -q '^event: finished' "$part2" && [ "$(awk '/^event: / { e = $2 } END { print e }' "$part2")" = status ]; then
    ok "a live stream cut after event $last (job $state_mid) and resumed with Last-Event-ID: ids 1..$count, no gap, no duplicate"
else
    not_ok "live resume" "last $last" "$(printf '%s\n' "$all" | tr '\n' ' ' | head -c 800)"
fi

# several followers of one job see the same events
MANY=$(submit "$DISK" "$BOX" "$BOXSOL" "$(quick_params 200)")
pids=()
for i in 1 2 3 4 5; do
    curl -sS -N --max-time $((60 * SLOW)) "$BASE/v1/jobs/$MANY/events" | jq -c 'select(.seq)' >"$WORK/f$i.ndjson" &
    pids+=($!)
done
wait "${pids[@]}"
same=1
for i in 2 3 4 5; do cmp -s "$WORK/f1.ndjson" "$WORK/f$i.ndjson" || same=0; done
if [ "$same" = 1 ] && [ "$(tail -1 "$WORK/f1.ndjson" | jq -r .type)" = finished ]; then
    ok "five concurrent followers of one job receive the same $(wc -l <"$WORK/f1.ndjson") events"
else
    not_ok "five followers" "$(wc -l "$WORK"/f?.ndjson)"
fi

# many followers of two jobs (the event streams' table by job id grows
# past its first 64 buckets): each is woken by its own job's end and
# ends with that job's final status; the gauge counts them, then none
streams() { curl -sS "$BASE/metrics" | awk '$1 == "shapematch_event_streams" { print $2 }'; }
streams_at_least() { [ "$(streams)" -ge "$1" ]; }
JA=$(submit "$FINE" "$BOX" "$BOXSOL" "$(endless_params)")
JB=$(submit "$FINE" "$BOX" "$BOXSOL" "$(endless_params)")
pids=()
for i in $(seq 1 120); do
    j=$JA
    [ $((i % 2)) = 0 ] && j=$JB
    curl -sS -N --max-time $((90 * SLOW)) -H 'Accept: application/x-ndjson' "$BASE/v1/jobs/$j/events" \
        >"$WORK/m$i.ndjson" 2>/dev/null &
    pids+=($!)
done
poll 30 streams_at_least 120
peak=$(streams)
poll 30 state_is "$JA" running
curl -sS -o /dev/null -X DELETE "$BASE/v1/jobs/$JA"
curl -sS -o /dev/null -X DELETE "$BASE/v1/jobs/$JB"
wait "${pids[@]}"
bad=0
for i in $(seq 1 120); do
    j=$JA
    [ $((i % 2)) = 0 ] && j=$JB
    last=$(tail -1 "$WORK/m$i.ndjson")
    [ "$(jq -r '.type + " " + .status + " " + .jobID' <<<"$last" 2>/dev/null)" = "status dismissed $j" ] ||
        bad=$((bad + 1))
done
poll 10 eval '[ "$(streams)" = 0 ]'
if [ "$peak" -ge 120 ] && [ "$bad" = 0 ] && [ "$(streams)" = 0 ]; then
    ok "120 followers of two jobs: each ends with its own job's final status (dismissed); streams $peak, then 0"
else
    not_ok "120 followers of two jobs" "peak $peak, $bad without their final status, now $(streams)" \
        "$(tail -2 "$WORK/m1.ndjson")"
fi
# out of the table again: the listing below counts the dismissed jobs
curl -sS -o /dev/null -X DELETE "$BASE/v1/jobs/$JA"
curl -sS -o /dev/null -X DELETE "$BASE/v1/jobs/$JB"

# --------------------------------------------------------- cancel, delete
RUN=$(submit "$FINE" "$BOX" "$BOXSOL" "$(endless_params)")
poll 20 state_is "$RUN" running
sleep 0.3
wpid=$(worker_pid "$RUN")
code=$(curl -sS -o "$WORK/del.json" -w '%{http_code}' -X DELETE "$BASE/v1/jobs/$RUN")
if [ "$code" = 200 ] && [ "$(jq -r .status "$WORK/del.json")" = dismissed ]; then
    ok "DELETE of a running job: 200, status dismissed"
else
    not_ok "DELETE of a running job" "$code" "$(cat "$WORK/del.json")"
fi
worker_gone() { ! kill -0 "$wpid" 2>/dev/null; }
if [ -n "$wpid" ] && poll 10 worker_gone; then
    ok "its worker process ($wpid) is gone"
else
    not_ok "the cancelled worker is gone" "pid '$wpid'"
fi
ev=$(curl -sS --max-time $((20 * SLOW)) "$BASE/v1/jobs/$RUN/events" | jq -r .type | tail -2 | tr '\n' ' ')
if [ "$ev" = "cancelled status " ] && [ "$(job_state "$RUN")" = dismissed ]; then
    ok "the cancelled job's log ends with cancelled, then status dismissed"
else
    not_ok "cancelled log" "$ev"
fi
code=$(curl -sS -o "$WORK/r.json" -w '%{http_code}' "$BASE/v1/jobs/$RUN/results")
if [ "$code" = 404 ] && jq -e '.type | endswith("result-not-ready")' "$WORK/r.json" >/dev/null; then
    ok "results of a dismissed job: 404 result-not-ready"
else
    not_ok "results of a dismissed job" "$code" "$(cat "$WORK/r.json")"
fi
code=$(curl -sS -o "$WORK/del.json" -w '%{http_code}' -X DELETE "$BASE/v1/jobs/$ID")
gone=$(curl -sS -o "$WORK/g.json" -w '%{http_code}' "$BASE/v1/jobs/$ID")
if [ "$code" = 200 ] && [ "$gone" = 404 ] && [ ! -e "$SPOOL/jobs/$ID" ] &&
    jq -e '.type | endswith("no-such-job")' "$WORK/g.json" >/dev/null; then
    ok "DELETE of a finished job removes it and its files; then 404 no-such-job"
else
    not_ok "DELETE of a finished job" "delete $code, get $gone" "$(ls "$SPOOL/jobs" | head)"
fi
bad=0
for url in "/v1/jobs/0123456789abcdef0123456789abcdef" "/v1/jobs/nothex" "/v1/jobs/..%2F..%2Fjobs" \
    "/v1/jobs/0123456789abcdef0123456789abcdef/events" "/v1/jobs/0123456789abcdef0123456789abcdef/results/mesh"; do
    c=$(curl -sS -o "$WORK/u.json" -w '%{http_code} %{content_type}' "$BASE$url")
    [ "$c" = "404 application/problem+json" ] && jq -e '.status == 404' "$WORK/u.json" >/dev/null ||
        { bad=1; echo "# $url: $c"; }
    case $url in *%2F*) ;; *) jq -e '.type | endswith("no-such-job")' "$WORK/u.json" >/dev/null || bad=1 ;; esac
done
c=$(curl -sS -o /dev/null -w '%{http_code}' -X DELETE "$BASE/v1/jobs/0123456789abcdef0123456789abcdef")
[ "$c" = 404 ] || bad=1
if [ "$bad" = 0 ]; then ok "unknown and malformed ids: 404 no-such-job (GET, DELETE, events, results); an escaped ../ path is 404"; else not_ok "unknown ids"; fi

# ------------------------------------------------------------ warnings
# a background covering part of the template: the job succeeds, and says so
mkdir -p "$WORK/warn"
if python3 "$ROOT/tests/cli/warnings_inputs.py" "$WORK/warn"; then
    EXT=$ROOT/examples/2d/template.mesh
    wj=$(submit "$EXT" "$WORK/warn/part.mesh" "$WORK/warn/part.sol" \
        '{"clamp": {"kind": "ball", "center": [0.5, 0.5], "radius": 0.04}, "max_iter": 20}')
    if [ -n "$wj" ] && wait_final "$wj" 60 && state_is "$wj" successful &&
        hcurl "${AUTH[@]}" "$BASE/v1/jobs/$wj" | jq -e '.message | test("finished(, not converged)?: .*; warning: outside-background: ")' >/dev/null &&
        hcurl "${AUTH[@]}" "$BASE/v1/jobs/$wj/results" | jq -e '.warnings[0].code == "outside-background" and .warnings[0].figure > 0.2' >/dev/null &&
        hcurl "${AUTH[@]}" "$BASE/v1/jobs/$wj/events" | jq -se 'map(select(.type == "finished"))[0].message | test("; warning: outside-background: ")' >/dev/null; then
        ok "warnings reach the job's status message, its finished event and its results (outside-background)"
    else
        not_ok "warnings in the daemon's job" "$(hcurl "${AUTH[@]}" "$BASE/v1/jobs/$wj/results" | jq -c .warnings | head -c 300) / $(hcurl "${AUTH[@]}" "$BASE/v1/jobs/$wj/events" | jq -c "[.type, .message]" | tail -n 4)"
    fi
else
    not_ok "crafted inputs for the warnings"
fi

# -------------------------------------------------------- idempotency
k1=$(submit "$DISK" "$BOX" "$BOXSOL" "$(quick_params 5)" -H 'Idempotency-Key: retry-1')
k1code=$(cat "$WORK/submit.code")
k2=$(submit "$DISK" "$BOX" "$BOXSOL" "$(quick_params 5)" -H 'Idempotency-Key: retry-1')
k2code=$(cat "$WORK/submit.code")
k3=$(submit "$DISK" "$BOX" "$BOXSOL" "$(quick_params 5)" -H 'Idempotency-Key: retry-2')
if [ "$k1code" = 201 ] && [ "$k2code" = 200 ] && [ -n "$k1" ] && [ "$k1" = "$k2" ] && [ -n "$k3" ] && [ "$k3" != "$k1" ]; then
    ok "Idempotency-Key: a retried submission returns the same job (200), another key a new one"
else
    not_ok "Idempotency-Key" "$k1code $k1 / $k2code $k2 / $k3"
fi
k4=$(submit "$DISK" "$BOX" "$BOXSOL" "$(quick_params 6)" -H 'Idempotency-Key: retry-1')
k4code=$(cat "$WORK/submit.code")
k4type=$(jq -r '.type + " " + (.status|tostring)' "$WORK/submit.out" 2>/dev/null)
k4why=$(jq -r .detail "$WORK/submit.out" 2>/dev/null)
k5=$(submit "$DISK" "$BOX" "$BOXSOL" "$(quick_params 5)" -H 'Idempotency-Key: retry-1')
if [ "$k4code" = 422 ] && [ -z "$k4" ] &&
    [ "$k4type" = "https://shapematch.invalid/problems/idempotency-key-mismatch 422" ] &&
    [ "${k4why#*different request}" != "$k4why" ] && [ "$k5" = "$k1" ]; then
    ok "Idempotency-Key reused with different params: 422 idempotency-key-mismatch; the same request still replays"
else
    not_ok "Idempotency-Key mismatch" "$k4code $k4type / $k5 vs $k1: $k4why"
fi

# ------------------------------------------------------- 20 at once
pids=()
for i in $(seq 1 20); do
    curl -sS --max-time $((60 * SLOW)) -o "$WORK/c$i.json" -F "template=@$DISK" -F "target_mesh=@$BOX" \
        -F "target_sol=@$BOXSOL" -F "params=$(quick_params 30)" "$BASE/v1/jobs" &
    pids+=($!)
done
wait "${pids[@]}"
CIDS=()
for i in $(seq 1 20); do
    id=$(jq -r '.jobID // empty' "$WORK/c$i.json" 2>/dev/null)
    [ -n "$id" ] && CIDS+=("$id")
done
all_done() {
    local id
    for id in "${CIDS[@]}"; do state_in "$id" successful failed dismissed || return 1; done
}
poll 90 all_done
nok=0
for id in "${CIDS[@]}"; do [ "$(job_state "$id")" = successful ] && nok=$((nok + 1)); done
if [ "${#CIDS[@]}" = 20 ] && [ "$nok" = 20 ]; then
    ok "20 jobs submitted concurrently: all accepted and all successful"
else
    not_ok "20 concurrent jobs" "accepted ${#CIDS[@]}, successful $nok"
fi

# ------------------------------------------------------------ listing
lst=$(curl -sS "$BASE/v1/jobs?status=successful&limit=5")
nm=$(printf '%s' "$lst" | jq .numberMatched)
if [ "$(printf '%s' "$lst" | jq '.jobs | length')" = 5 ] && [ "$nm" -ge 20 ] &&
    [ "$(printf '%s' "$lst" | jq '[.jobs[].status] | unique')" = '[
  "successful"
]' ] && printf '%s' "$lst" | jq -e '.links[] | select(.rel == "next") | .href | test("offset=5")' >/dev/null; then
    ok "GET /v1/jobs?status=successful&limit=5: a page of 5 successful jobs of $nm, with a next link"
else
    not_ok "job listing" "$(printf '%s' "$lst" | head -c 600)"
fi
dis=$(curl -sS "$BASE/v1/jobs?status=dismissed" | jq -r '.jobs[].jobID' | tr '\n' ' ')
if [ "$dis" = "$RUN " ]; then ok "GET /v1/jobs?status=dismissed lists the cancelled job"; else not_ok "status filter" "$dis"; fi
code=$(curl -sS -o /dev/null -w '%{http_code}' "$BASE/v1/jobs?status=bogus")
if [ "$code" = 400 ]; then ok "an unknown status filter is 400"; else not_ok "bad status filter" "$code"; fi

# --------------------------------------------------------------- metrics
m=$(curl -sS "$BASE/metrics")
if printf '%s\n' "$m" | grep -q '^shapematch_jobs{state="successful"} [1-9]' &&
    printf '%s\n' "$m" | grep -q '^shapematch_queue_depth 0' &&
    printf '%s\n' "$m" | grep -q '^shapematch_http_requests_total{route="/v1/jobs",method="POST",code="201"} [1-9]' &&
    printf '%s\n' "$m" | grep -q '^shapematch_http_request_duration_seconds_bucket{route="/v1/jobs/{id}",le="+Inf"}' &&
    printf '%s\n' "$m" | grep -q '^shapematch_workers 2' &&
    printf '%s\n' "$m" | grep -q '^shapematch_http_received_bytes_total [1-9]'; then
    ok "/metrics: jobs by state, queue depth, workers, requests by route/method/code, latency histogram, bytes"
else
    not_ok "/metrics" "$(printf '%s\n' "$m" | grep -v '^#' | head -20)"
fi

# ------------------------------------------------------------- shutdown
stop_daemon
rc=$?
if [ "$rc" = 0 ]; then ok "SIGTERM: the daemon exits 0"; else not_ok "SIGTERM: the daemon exits 0" "status $rc" "$(tail -5 "$DLOG")"; fi
if [ -z "$(ls -A "$SPOOL/tmp")" ]; then ok "no upload left in the spool's tmp/"; else not_ok "tmp/ is empty" "$(ls "$SPOOL/tmp")"; fi
if reports_clean; then ok "no sanitizer report in the daemon or worker logs"; else not_ok "sanitizer reports" "$(grep -lE 'Sanitizer|runtime error' "$WORK"/*.log "$SPOOL"/jobs/*/worker.log 2>/dev/null)"; fi
bad_lines=$(grep -cv '^{' "$DLOG")
if [ "$bad_lines" = 0 ] && jq -e . "$DLOG" >/dev/null 2>&1 && grep -q '"event":"request"' "$DLOG" &&
    grep -q '"event":"job_finished"' "$DLOG"; then
    ok "the log is JSON lines: one per request and per job state change"
else
    not_ok "JSON-lines log" "$(grep -v '^{' "$DLOG" | head -3)"
fi
echo "1..$n"
