#!/usr/bin/env bash
# run.sh: weight 0.5 seconds 40
# The shapematch client against a real shapematchd on loopback, with real
# files (examples/2d): submit / watch / fetch / status / list / cancel,
# `submit --wait` end to end (the result equals `shapematch run`'s for the
# same inputs and parameters, byte for byte), gzip on the wire both ways,
# Idempotency-Key, SHAPEMATCH_SERVER / SHAPEMATCH_TOKEN, `watch` resuming
# after the daemon is killed (kill -9) and restarted mid-job (no event
# shown twice, the right outcome), and every exit code: cannot connect (6),
# 401 / 404 / 422 (7, with the problem detail), job failed (8), job
# cancelled (5), daemon error (9), bad input file (2), usage (1).
# A small fake daemon (python3, when present) serves crafted event streams:
# CRLF and CR line ends, one byte per chunk, comments, a BOM, multi-line
# data, a server that replays from the start after a reconnection, drops,
# 503s until the reconnect timeout, over-long lines, bad ids, a 500.
source "$(dirname "$0")/lib.sh"

SM=$BIN/shapematch
EX=$ROOT/examples/2d
T=$EX/template.mesh
M=$EX/background.mesh.gz
S=$EX/background.sol.gz
CLAMP=(--clamp-ball "$(cat "$EX/clamp" 2>/dev/null || echo 0.5,0.5,0.04)")
QUICK=(--max-iter 30)
LONG=(--max-iter 100000000 --tol-step 1e-15 --tol-stall 0)
INPUTS=(--template "$T" --target-mesh "$M" --target-sol "$S")
UNKNOWN=0123456789abcdef0123456789abcdef
unset SHAPEMATCH_TOKEN

# sm NAME ARGS...: runs the client; stdout in $WORK/NAME.out, stderr in
# $WORK/NAME.log (a .log, so that reports_clean sees sanitizer reports);
# the exit code in RC.  Bounded in time: a hung client fails, not hangs.
sm() {
    local name=$1
    shift
    timeout $((60 * SLOW)) "$SM" "$@" >"$WORK/$name.out" 2>"$WORK/$name.log"
    RC=$?
}
# expect NAME CODE DESC [ERE]: the last `sm NAME` exited with CODE and its
# stderr matches ERE
expect() {
    local name=$1 want=$2 desc=$3 pat=${4:-}
    if [ "$RC" = "$want" ] && { [ -z "$pat" ] || grep -qE -- "$pat" "$WORK/$name.log"; }; then
        ok "$desc"
    else
        not_ok "$desc" "exit $RC, expected $want${pat:+, stderr matching /$pat/}" \
            "$(tail -5 "$WORK/$name.log")"
    fi
}
# seqs_contiguous FILE: the NDJSON events with a seq are numbered 1..N in
# order, each once, and the last line is a status event
seqs_contiguous() {
    local got want
    got=$(jq -r 'select(.seq != null) | .seq' "$1" | tr '\n' ' ')
    want=$(seq 1 "$(jq -r 'select(.seq != null) | .seq' "$1" | wc -l)" | tr '\n' ' ')
    [ -n "$got" ] && [ "$got" = "$want" ] && [ "$(tail -1 "$1" | jq -r .type)" = status ]
}
# request_field JOB ROUTE METHOD FIELD: FIELD of the daemon's request log
# lines for this job and route (one per line)
request_field() {
    jq -r --arg j "$1" --arg r "$2" --arg m "$3" \
        "select(.event == \"request\" and .job == \$j and .route == \$r and .method == \$m) | .$4" "$DLOG"
}

if [ ! -f "$T" ] || [ ! -f "$M" ] || [ ! -f "$S" ]; then
    not_ok "examples/2d is present" "missing $T, $M or $S"
    exit 1
fi

# ------------------------------------------------------------ help

sm help --help
if [ "$RC" = 0 ] && grep -q '^  submit ' "$WORK/help.out" && grep -q '^  watch ' "$WORK/help.out" &&
    grep -q '^  fetch ' "$WORK/help.out" && grep -q '^  status ' "$WORK/help.out" &&
    grep -q '^  list ' "$WORK/help.out" && grep -q '^  cancel ' "$WORK/help.out" &&
    grep -q '^  6  cannot connect' "$WORK/help.out" && grep -q '^  9  daemon error' "$WORK/help.out" &&
    grep -q SHAPEMATCH_SERVER "$WORK/help.out"; then
    ok "shapematch --help lists the daemon commands, SHAPEMATCH_SERVER and exit codes 6-9"
else
    not_ok "shapematch --help" "$(cat "$WORK/help.out")"
fi
bad=""
for c in submit watch fetch status list cancel; do
    sm "help-$c" "$c" --help
    if [ "$RC" != 0 ] || ! grep -q -- '--server URL' "$WORK/help-$c.out" ||
        ! grep -q SHAPEMATCH_TOKEN "$WORK/help-$c.out" || ! grep -q '^  7  the daemon refused' "$WORK/help-$c.out" ||
        ! grep -q '^  8  the job failed' "$WORK/help-$c.out"; then
        bad="$bad $c"
    fi
done
check "each daemon command's --help documents --server, SHAPEMATCH_TOKEN and its exit codes${bad:+ (bad:$bad)}" \
    test -z "$bad"

# ----------------------------------------------------- the main daemon

SPOOL=
if ! start_daemon main --workers 2 --worker-threads 1 --kill-grace 2; then
    not_ok "the daemon starts"
    exit 1
fi
MAIN=$BASE
MAIN_LOG=$DLOG
MAIN_PID=$DPID
export SHAPEMATCH_SERVER=$MAIN

# the reference: the same job run locally (one BLAS/OpenMP thread, as the
# daemon's workers, so that the factorization is bit-for-bit the same)
OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 "$SM" run "${INPUTS[@]}" "${CLAMP[@]}" "${QUICK[@]}" \
    -o "$WORK/run" --quiet 2>"$WORK/run.log"
check "shapematch run gives the reference results" test -f "$WORK/run/summary.json"

# ------------------------------------------------ submit, watch, status

sm submit submit "${INPUTS[@]}" "${CLAMP[@]}" "${QUICK[@]}"
ID=$(head -1 "$WORK/submit.out")
if [ "$RC" = 0 ] && [[ $ID =~ ^[0-9a-f]{32}$ ]] && [ "$(wc -l <"$WORK/submit.out")" = 1 ]; then
    ok "submit (server from SHAPEMATCH_SERVER) prints the job id and exits 0"
else
    not_ok "submit prints the job id" "exit $RC" "$(cat "$WORK/submit.out" "$WORK/submit.log")"
fi

sm watch watch "$ID"
iters=$(grep -cE '^iter [0-9]+ ' "$WORK/watch.log")
if [ "$RC" = 0 ] && grep -q "job $ID queued" "$WORK/watch.log" && grep -q "job $ID started" "$WORK/watch.log" &&
    grep -qE '^iter 0  result->target rms ' "$WORK/watch.log" && grep -qE '^iter 10  result->target rms ' "$WORK/watch.log" &&
    grep -qE '^iter 30  result->target rms [0-9.e+-]+  max [0-9.e+-]+  target->result rms [0-9.e+-]+  .*relative [0-9.e+-]+  L2 [0-9.e+-]+  J .* step ' "$WORK/watch.log" && [ "$iters" = 4 ] &&
    grep -q "job $ID successful: max_iterations after 30 iterations" "$WORK/watch.log" &&
    [ ! -s "$WORK/watch.out" ]; then
    ok "watch (not a terminal): queued, started, a plain line every 10 iterations (4), successful, exit 0"
else
    not_ok "watch prints plain progress lines" "exit $RC, $iters iteration lines" "$(head -20 "$WORK/watch.log")"
fi

sm watchjson watch --json --quiet "$ID"
nprog=$(jq -r 'select(.type == "progress") | .iteration' "$WORK/watchjson.out" | tr '\n' ' ')
if [ "$RC" = 0 ] && seqs_contiguous "$WORK/watchjson.out" &&
    [ "$(tail -1 "$WORK/watchjson.out" | jq -r .status)" = successful ] &&
    [ "$nprog" = "$(seq 0 30 | tr '\n' ' ')" ] && [ ! -s "$WORK/watchjson.log" ]; then
    ok "watch --json --quiet: every event once as NDJSON (seq 1..N, iterations 0..30), status last, nothing on stderr"
else
    not_ok "watch --json" "exit $RC" "iterations: $nprog" "$(tail -3 "$WORK/watchjson.out")" "$(cat "$WORK/watchjson.log")"
fi

sm status status "$ID"
if [ "$RC" = 0 ] && grep -qE '^status +successful \(100%\)' "$WORK/status.out" &&
    grep -qE "^job +$ID" "$WORK/status.out" && grep -qE '^last +iter 30 ' "$WORK/status.out" &&
    grep -qE '^finished +20[0-9]{2}-' "$WORK/status.out"; then
    ok "status: job, successful (100%), times, the last iteration's figures"
else
    not_ok "status" "exit $RC" "$(cat "$WORK/status.out" "$WORK/status.log")"
fi
sm statusjson status --json "$ID"
if [ "$RC" = 0 ] && [ "$(jq -r '.jobID + " " + .status' "$WORK/statusjson.out")" = "$ID successful" ]; then
    ok "status --json prints the daemon's statusInfo"
else
    not_ok "status --json" "exit $RC" "$(cat "$WORK/statusjson.out")"
fi

sm list list
sm listrun list --status running,accepted
sm listjson list --json --status successful
sm listlimit list --limit 1
if grep -qE "^$ID +successful +100% " "$WORK/list.out" && ! grep -q "$ID" "$WORK/listrun.out" &&
    [ "$(jq -r --arg id "$ID" '[.jobs[] | select(.jobID == $id)] | length' "$WORK/listjson.out")" = 1 ] &&
    [ "$(jq -r '[.jobs[] | select(.status != "successful")] | length' "$WORK/listjson.out")" = 0 ] &&
    [ "$(grep -cE '^[0-9a-f]{32} ' "$WORK/listlimit.out")" = 1 ]; then
    ok "list: a row per job; --status filters; --json; --limit"
else
    not_ok "list" "$(cat "$WORK/list.out" "$WORK/listrun.out" "$WORK/listlimit.out")"
fi

# ------------------------------------------------------------- fetch

F=$WORK/fetched
sm fetch fetch "$ID" -o "$F"
hist_same() { # the history without its elapsed-time column (wall clock)
    cmp -s <(cut -d, -f1-6,8- "$1") <(cut -d, -f1-6,8- "$2")
}
if [ "$RC" = 0 ] && cmp -s "$F/result.mesh" "$WORK/run/result.mesh" &&
    cmp -s "$F/result.vtu" "$WORK/run/result.vtu" &&
    cmp -s "$F/displacement.sol" "$WORK/run/displacement.sol" &&
    hist_same "$F/history.csv" "$WORK/run/history.csv" &&
    [ "$(jq -r '.jobID + " " + .stop_reason + " " + (.iterations|tostring)' "$F/summary.json")" = "$ID max_iterations 30" ]; then
    ok "fetch: result.mesh, result.vtu, displacement.sol equal shapematch run's byte for byte; history.csv, summary.json"
else
    not_ok "fetch gives shapematch run's results" "exit $RC" "$(ls -la "$F" 2>&1)" "$(cat "$WORK/fetch.log")"
fi
if [ "$(jq -c '.parameters.clamp' "$F/summary.json")" = '{"kind":"ball","center":[0.5,0.5],"radius":0.04}' ] &&
    [ "$(jq -r '.parameters.max_iter' "$F/summary.json")" = 30 ]; then
    ok "the job ran with the parameters given on the command line (clamp ball, max_iter 30)"
else
    not_ok "parameters reach the daemon" "$(jq -c .parameters "$F/summary.json")"
fi
# compressed on the wire: what the daemon sent for the mesh is smaller than the mesh
# (the first mesh request of this job: fetch asks for mesh, then vtu)
mesh_out=$(request_field "$ID" '/v1/jobs/{id}/results/mesh' GET bytes_out | head -1)
mesh_size=$(stat -c %s "$F/result.mesh")
if [ -n "$mesh_out" ] && [ "$mesh_out" -gt 0 ] && [ "$mesh_out" -lt $((mesh_size / 2)) ]; then
    ok "fetch transfers are gzip-compressed ($mesh_out bytes on the wire for a $mesh_size-byte mesh)"
else
    not_ok "fetch transfers are compressed" "bytes_out '$mesh_out', size $mesh_size"
fi
F2=$WORK/fetched2
sm fetch2 fetch --format meshb,binary --quiet "$ID" -o "$F2"
curl -sS -o "$WORK/raw.meshb" "$MAIN/v1/jobs/$ID/results/mesh?format=meshb"
curl -sS -o "$WORK/raw.smmesh" "$MAIN/v1/jobs/$ID/results/mesh?format=binary"
if [ "$RC" = 0 ] && cmp -s "$F2/result.meshb" "$WORK/raw.meshb" && cmp -s "$F2/result.smmesh" "$WORK/raw.smmesh" &&
    [ ! -e "$F2/result.mesh" ] && [ -f "$F2/summary.json" ] && [ ! -s "$WORK/fetch2.log" ] &&
    [ -z "$(find "$F2" -name '.tmp*')" ]; then
    ok "fetch --format meshb,binary: the binary files as served (decompressed exactly), no temporary left, quiet"
else
    not_ok "fetch --format meshb,binary" "exit $RC" "$(ls -la "$F2" 2>&1)" "$(cat "$WORK/fetch2.log")"
fi

# ------------------------------------------------------ submit --wait

W=$WORK/waited
sm wait submit "${INPUTS[@]}" "${CLAMP[@]}" "${QUICK[@]}" --wait -o "$W"
WID=$(head -1 "$WORK/wait.out")
if [ "$RC" = 0 ] && [[ $WID =~ ^[0-9a-f]{32}$ ]] && [ "$WID" != "$ID" ] &&
    cmp -s "$W/result.mesh" "$WORK/run/result.mesh" && cmp -s "$W/result.vtu" "$WORK/run/result.vtu" &&
    [ -f "$W/summary.json" ] && grep -q "job $WID successful" "$WORK/wait.log" &&
    grep -q "results in $W" "$WORK/wait.log"; then
    ok "submit --wait -o: id on stdout, progress, then results equal to shapematch run's (result.mesh, result.vtu)"
else
    not_ok "submit --wait" "exit $RC" "$(tail -5 "$WORK/wait.log")"
fi

# uploads: files that are not gzip yet are compressed on the way (and the
# job is the same), unless --no-compress
gzip -dc "$M" >"$WORK/bg.mesh"
gzip -dc "$S" >"$WORK/bg.sol"
raw=$(($(stat -c %s "$T") + $(stat -c %s "$WORK/bg.mesh") + $(stat -c %s "$WORK/bg.sol")))
U=$WORK/uncompressed
sm upgz submit --template "$T" --target-mesh "$WORK/bg.mesh" --target-sol "$WORK/bg.sol" \
    "${CLAMP[@]}" "${QUICK[@]}" --wait -o "$U" --quiet
UID_=$(head -1 "$WORK/upgz.out")
sent=$(request_field "$UID_" /v1/jobs POST bytes_in)
if [ "$RC" = 0 ] && cmp -s "$U/result.mesh" "$WORK/run/result.mesh" && [ -n "$sent" ] &&
    [ "$sent" -lt $((raw / 2)) ]; then
    ok "uncompressed inputs are gzip-compressed on upload ($sent bytes sent for $raw), same result"
else
    not_ok "uploads are compressed" "exit $RC, sent '$sent' for $raw" "$(tail -3 "$WORK/upgz.log")"
fi
sm upraw submit --template "$T" --target-mesh "$WORK/bg.mesh" --target-sol "$WORK/bg.sol" \
    "${CLAMP[@]}" "${QUICK[@]}" --no-compress
sent=$(request_field "$(head -1 "$WORK/upraw.out")" /v1/jobs POST bytes_in)
if [ "$RC" = 0 ] && [ -n "$sent" ] && [ "$sent" -ge "$raw" ]; then
    ok "--no-compress sends the files as they are ($sent bytes)"
else
    not_ok "--no-compress" "exit $RC, sent '$sent' for $raw" "$(cat "$WORK/upraw.log")"
fi

# Idempotency-Key: a retried submission gets the first job back
sm idem1 submit "${INPUTS[@]}" "${CLAMP[@]}" "${QUICK[@]}" --idempotency-key "client-test-$$"
sm idem2 submit "${INPUTS[@]}" "${CLAMP[@]}" "${QUICK[@]}" --idempotency-key "client-test-$$"
if [ "$RC" = 0 ] && [ -n "$(cat "$WORK/idem1.out")" ] && cmp -s "$WORK/idem1.out" "$WORK/idem2.out" &&
    grep -q 'already has a job for this Idempotency-Key' "$WORK/idem2.log"; then
    ok "--idempotency-key: the same key gives the same job id, and says so"
else
    not_ok "--idempotency-key" "$(cat "$WORK/idem1.out" "$WORK/idem2.out" "$WORK/idem2.log")"
fi
sm json submit "${INPUTS[@]}" "${CLAMP[@]}" "${QUICK[@]}" --json
if [ "$RC" = 0 ] && [ "$(jq -r .status "$WORK/json.out")" = accepted ] &&
    [[ $(jq -r .jobID "$WORK/json.out") =~ ^[0-9a-f]{32}$ ]]; then
    ok "submit --json prints the new job's status document"
else
    not_ok "submit --json" "$(cat "$WORK/json.out" "$WORK/json.log")"
fi

# ---------------------------------------------- cancel (exit code 5)

sm long submit "${INPUTS[@]}" "${CLAMP[@]}" "${LONG[@]}"
LID=$(head -1 "$WORK/long.out")
timeout $((60 * SLOW)) "$SM" watch --json "$LID" >"$WORK/cw.out" 2>"$WORK/cw.log" &
CW=$!
if wait_state "$LID" running 30; then ok "a long job runs"; else not_ok "a long job runs" "$(job_state "$LID")"; fi
sm notready fetch "$LID" -o "$WORK/notready"
expect notready 7 "fetch of a running job: exit 7, no results yet" "job $LID is running: no results yet"
sm cancel cancel "$LID"
if [ "$RC" = 0 ] && grep -q "job $LID cancelled: dismissed" "$WORK/cancel.out"; then
    ok "cancel of a running job: dismissed, exit 0"
else
    not_ok "cancel" "exit $RC" "$(cat "$WORK/cancel.out" "$WORK/cancel.log")"
fi
wait "$CW"
cw=$?
if [ "$cw" = 5 ] && grep -q "job $LID was cancelled (dismissed)" "$WORK/cw.log" &&
    [ "$(tail -1 "$WORK/cw.out" | jq -r .status)" = dismissed ] && seqs_contiguous "$WORK/cw.out" &&
    [ "$(jq -r 'select(.type == "cancelled") | .type' "$WORK/cw.out")" = cancelled ]; then
    ok "watch of a job cancelled meanwhile: exit 5, the cancelled event, status dismissed"
else
    not_ok "watch of a cancelled job" "exit $cw" "$(tail -3 "$WORK/cw.log")" "$(tail -2 "$WORK/cw.out")"
fi
sm watchcancelled watch --quiet "$LID"
expect watchcancelled 5 "watch of a dismissed job (replayed): exit 5" "was cancelled"
sm fetchcancelled fetch "$LID" -o "$WORK/fc"
expect fetchcancelled 5 "fetch of a dismissed job: exit 5" "no results"
sm delete cancel "$LID"
if [ "$RC" = 0 ] && grep -q "job $LID deleted" "$WORK/delete.out"; then
    ok "cancel of a finished job deletes it"
else
    not_ok "cancel deletes a finished job" "exit $RC" "$(cat "$WORK/delete.out" "$WORK/delete.log")"
fi
sm gone status "$LID"
expect gone 7 "status of the deleted job: exit 7 (404 no-such-job)" "404 Not Found \(no-such-job\)"

# ------------------------------------------- failed job (exit code 8)

sm fail submit "${INPUTS[@]}" "${CLAMP[@]}" "${LONG[@]}"
FID=$(head -1 "$WORK/fail.out")
wait_state "$FID" running 30
DLOG=$MAIN_LOG
has_worker() { [ -n "$(worker_pid "$FID")" ]; }
poll 10 has_worker
wpid=$(worker_pid "$FID")
[ -n "$wpid" ] && kill -KILL "$wpid" 2>/dev/null
sm failwatch watch "$FID"
expect failwatch 8 "watch of a job whose worker was killed: exit 8 with the reason" "job $FID failed: .*(signal|SIGKILL)"
sm failfetch fetch "$FID" -o "$WORK/ff"
expect failfetch 8 "fetch of a failed job: exit 8" "job $FID failed"

# ----------------------------------------------------- error exit codes

sm unk-status status "$UNKNOWN"
expect unk-status 7 "status of an unknown id: exit 7 with the problem detail" "404 Not Found \(no-such-job\): no job $UNKNOWN"
sm unk-watch watch "$UNKNOWN"
expect unk-watch 7 "watch of an unknown id: exit 7" "no-such-job"
sm unk-fetch fetch "$UNKNOWN" -o "$WORK/unk"
expect unk-fetch 7 "fetch of an unknown id: exit 7" "no-such-job"
sm unk-cancel cancel "$UNKNOWN"
expect unk-cancel 7 "cancel of an unknown id: exit 7" "no-such-job"

sm p422 submit "${INPUTS[@]}" --clamp-ball 5,5,0.04 --max-iter 5
expect p422 7 "a clamp ball outside the template: 422, exit 7, the detail names params.clamp" \
    "422 Unprocessable Content: params\.clamp"
sm p422dim submit "${INPUTS[@]}" --clamp-ball 0.5,0.5,0.5,0.04 --max-iter 5
expect p422dim 7 "a 3D clamp ball for a 2D template: 422, exit 7, params.clamp.center" "422 .*params\.clamp\.center"
sm p422file submit --template "$S" --target-mesh "$M" --target-sol "$S" "${CLAMP[@]}"
expect p422file 7 "a sol file given as the template: 422, exit 7, the detail names the part" "422 .*template"

sm nofile submit --template "$WORK/nonexistent.mesh" --target-mesh "$M" --target-sol "$S" "${CLAMP[@]}"
expect nofile 2 "an unreadable input file: exit 2, named" "template: cannot read '.*nonexistent.mesh'"
sm u1 submit "${INPUTS[@]}" --max-iter 5 --wait -o "$WORK/u1"
expect u1 10 "submit without a clamp option: the default clamp, reported (5 iterations: not converged)" "clamp-default: no clamp given"
sm u2 submit "${INPUTS[@]}" "${CLAMP[@]}" --wait
expect u2 1 "submit --wait without -o: exit 1" "needs -o"
sm u3 watch ../../etc/passwd
expect u3 1 "a job id that is not one: exit 1, nothing sent" "is not a job id"
sm u4 list --status bogus
expect u4 1 "list --status with an unknown state: exit 1" "not a job state"
sm u5 status --server 'ftp://example.org' "$UNKNOWN"
expect u5 1 "a non-HTTP --server URL: exit 1" "only http:// and https://"
sm u6 fetch "$ID" -o "$WORK/x" --format obj
expect u6 1 "fetch --format with an unknown format: exit 1" "not a result format"
sm nowrite fetch "$ID" -o "$WORK/run/summary.json/sub"
expect nowrite 4 "fetch into a directory that cannot be created: exit 4" "output directory: cannot create"

# nothing listens on this port: cannot connect (6) for every command
DEAD=$(python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])' 2>/dev/null || echo 1)
bad=""
for c in "submit ${INPUTS[*]} ${CLAMP[*]}" "watch $ID" "fetch $ID -o $WORK/dead" "status $ID" "list" "cancel $ID"; do
    # shellcheck disable=SC2086
    SHAPEMATCH_SERVER=http://127.0.0.1:$DEAD sm dead $c
    if [ "$RC" != 6 ] || ! grep -q "cannot connect to the daemon at http://127.0.0.1:$DEAD" "$WORK/dead.log"; then
        bad="$bad ${c%% *}($RC)"
    fi
done
check "no daemon listening: every command exits 6, 'cannot connect' (SHAPEMATCH_SERVER honoured)${bad:+; bad:$bad}" test -z "$bad"
SHAPEMATCH_SERVER=http://127.0.0.1:$DEAD sm override status --server "$MAIN" "$ID"
expect override 0 "--server wins over SHAPEMATCH_SERVER"

# ---------------------------------------------------------------- tokens

printf '# tokens of the client test\nclient-secret-%s\n' $$ >"$WORK/tokens"
TOKEN=client-secret-$$
SPOOL=
if start_daemon auth --workers 1 --worker-threads 1 --tokens-file "$WORK/tokens"; then
    AUTHBASE=$BASE
    SHAPEMATCH_SERVER=$AUTHBASE sm t-none list
    expect t-none 7 "a daemon with tokens, no token given: 401, exit 7, says a token is needed" "needs a token"
    SHAPEMATCH_SERVER=$AUTHBASE sm t-none-submit submit "${INPUTS[@]}" "${CLAMP[@]}" "${QUICK[@]}"
    expect t-none-submit 7 "submit (a streamed upload) without a token: 401, exit 7" "401 Unauthorized"
    SHAPEMATCH_SERVER=$AUTHBASE SHAPEMATCH_TOKEN=wrong-token sm t-wrong list
    expect t-wrong 7 "a wrong SHAPEMATCH_TOKEN: 401, exit 7, says the token is refused" "token given .* is not one the daemon accepts"
    SHAPEMATCH_SERVER=$AUTHBASE sm t-wrong-watch watch --token wrong-token "$UNKNOWN"
    expect t-wrong-watch 7 "watch with a wrong --token: 401, exit 7" "401 Unauthorized"
    SHAPEMATCH_SERVER=$AUTHBASE sm t-flag list --token "$TOKEN"
    expect t-flag 0 "the right --token: list succeeds"
    SHAPEMATCH_SERVER=$AUTHBASE SHAPEMATCH_TOKEN=$TOKEN sm t-env submit "${INPUTS[@]}" "${CLAMP[@]}" \
        "${QUICK[@]}" --wait -o "$WORK/tokenrun" --quiet
    if [ "$RC" = 0 ] && cmp -s "$WORK/tokenrun/result.mesh" "$WORK/run/result.mesh"; then
        ok "SHAPEMATCH_TOKEN: submit --wait end to end (upload, events, downloads) on a daemon with tokens"
    else
        not_ok "SHAPEMATCH_TOKEN end to end" "exit $RC" "$(tail -3 "$WORK/t-env.log")"
    fi
    check "the daemon with tokens stops cleanly" stop_daemon
else
    not_ok "a daemon with a tokens file starts"
fi

# ------------------------- watch across a daemon restart (kill -9, same port)

SPOOL=
if start_daemon restart --workers 1 --worker-threads 1; then
    RBASE=$BASE
    RPORT=${BASE##*:}
    sm rsub submit --server "$RBASE" "${INPUTS[@]}" "${CLAMP[@]}" --max-iter 3000 --tol-step 1e-15 --tol-stall 0
    RID=$(head -1 "$WORK/rsub.out")
    timeout $((90 * SLOW)) "$SM" watch --server "$RBASE" --json "$RID" >"$WORK/rw.out" 2>"$WORK/rw.log" &
    RW=$!
    # its worker paused once progress is seen, so that the daemon is
    # killed while the job runs (the 3000 iterations once took 1.3 s in
    # all, and the job had ended before the kill); the kill takes the
    # worker with it (PR_SET_PDEATHSIG), paused or not
    progressed() { grep -q '"type":"progress"' "$WORK/rw.out"; }
    for ((i = 0; i < 3000 * SLOW; i++)); do # every 10 ms: the job is short
        progressed && break
        sleep 0.01
    done
    if progressed && kill -STOP "$(worker_pid "$RID")" 2>/dev/null && state_is "$RID" running; then
        ok "the watched job runs (progress seen; its worker paused until the kill)"
    else
        not_ok "the watched job runs" "$(job_state "$RID")" "$(tail -3 "$WORK/rw.log")"
    fi
    seen_before=$(jq -r 'select(.seq != null) | .seq' "$WORK/rw.out" | tail -1)
    kill9_daemon
    sleep 1 # the client meets refused connections for a while
    if start_daemon restart --workers 1 --worker-threads 1 --listen "127.0.0.1:$RPORT"; then
        ok "the daemon restarts on the same port with the same spool"
    else
        not_ok "the daemon restarts on the same port"
    fi
    wait "$RW"
    rw=$?
    dups=$(sort "$WORK/rw.out" | uniq -d | wc -l)
    attempts=$(jq -r 'select(.type == "started") | .attempt' "$WORK/rw.out" | tr '\n' ' ')
    if [ "$rw" = 0 ] && seqs_contiguous "$WORK/rw.out" && [ "$dups" = 0 ] && [ "$attempts" = "1 2 " ] &&
        [ "$(tail -1 "$WORK/rw.out" | jq -r .status)" = successful ]; then
        ok "watch resumes after the restart: exit 0, events 1..N each once (last before the kill: $seen_before), attempts 1 then 2, status successful"
    else
        not_ok "watch resumes after the restart" "exit $rw, duplicates $dups, attempts '$attempts'" \
            "$(grep -v '^iter' "$WORK/rw.log" | tail -5)"
    fi
    if grep -q 'connection to the daemon lost' "$WORK/rw.log" && grep -q 'reconnected to the daemon; resuming after event' "$WORK/rw.log"; then
        ok "watch says it lost the connection and resumed"
    else
        not_ok "watch reports the reconnection" "$(grep -v '^iter' "$WORK/rw.log" | tail -5)"
    fi
    sm rfetch fetch --server "$BASE" "$RID" -o "$WORK/restarted" --quiet
    rows=$(($(wc -l <"$WORK/restarted/history.csv" 2>/dev/null || echo 0) - 1))
    if [ "$RC" = 0 ] && [ "$rows" = 3001 ] && [ "$(jq -r .iterations "$WORK/restarted/summary.json")" = 3000 ]; then
        ok "the re-run job's results are complete (3000 iterations, 3001 history rows)"
    else
        not_ok "results of the re-run job" "exit $RC, $rows rows" "$(cat "$WORK/rfetch.log")"
    fi
    check "the restarted daemon stops cleanly" stop_daemon
else
    not_ok "the restart daemon starts"
fi

# ------------------------------------------------- crafted event streams

if command -v python3 >/dev/null; then
    cat >"$WORK/fake_sse.py" <<'EOF'
# Fake events endpoint: GET /v1/jobs/<scenario>/events answers a crafted
# stream; prints its port; logs "path last-event-id" per request.
import json, socket, socketserver, sys, threading, time
LOG = sys.argv[1]
lock = threading.Lock()
PROG = dict(J=-0.1, step=0.01, boundary_l2=0.003, boundary_max=0.01, min_quality=0.4,
            elapsed=0.5, accepted=1, rejected=0)
RESULT = dict(stop_reason="max_iterations", iterations=11, J_initial=-0.1, J_final=-0.2,
              boundary_l2=0.001, boundary_max=0.002, min_quality=0.4, accepted=11, rejected=0,
              timings=dict(setup=0, sample=0, assembly=0, factor=0, solve=0, step=0, total=0))
def ev(seq, typ, **kw):
    return dict(type=typ, jobID="fake", **({"seq": seq} if seq else {}), **kw)
def events(n):
    return [ev(1, "accepted"), ev(2, "started", attempt=1)] + \
           [ev(3 + i, "progress", iteration=i, **PROG) for i in range(n)]
def sse(d, eol="\n"):
    out = ("id: %d%s" % (d["seq"], eol)) if d.get("seq") else ""
    return out + "event: %s%sdata: %s%s%s" % (d["type"], eol, json.dumps(d), eol, eol)
def status(state, msg=""):
    return ev(0, "status", status=state, message=msg)
class H(socketserver.BaseRequestHandler):
    def head(self, code=200, ctype="text/event-stream", body=None):
        reason = {200: "OK", 500: "Internal Server Error", 503: "Service Unavailable"}[code]
        if body is None:
            self.request.sendall(("HTTP/1.1 %d %s\r\nContent-Type: %s\r\nTransfer-Encoding: chunked\r\n"
                                  "Connection: close\r\n\r\n" % (code, reason, ctype)).encode())
        else:
            self.request.sendall(("HTTP/1.1 %d %s\r\nContent-Type: %s\r\nContent-Length: %d\r\n"
                                  "Connection: close\r\n\r\n%s" % (code, reason, ctype, len(body), body)).encode())
    def chunk(self, data, pieces=1):
        b = data.encode("utf-8") if isinstance(data, str) else data
        step = max(1, (len(b) + pieces - 1) // pieces)
        for i in range(0, len(b), step):
            self.request.sendall(b"%x\r\n" % len(b[i:i + step]) + b[i:i + step] + b"\r\n")
            if pieces > 1:
                time.sleep(0.0002)
    def end(self):
        self.request.sendall(b"0\r\n\r\n")
    def drop(self):
        self.request.shutdown(socket.SHUT_RDWR)
    def handle(self):
        self.request.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        raw = b""
        while b"\r\n\r\n" not in raw:
            got = self.request.recv(4096)
            if not got:
                return
            raw += got
        lines = raw.decode("latin-1").split("\r\n")
        path = lines[0].split(" ")[1]
        last = "-"
        for l in lines[1:]:
            if l.lower().startswith("last-event-id:"):
                last = l.split(":", 1)[1].strip()
        with lock:
            with open(LOG, "a") as f:
                f.write("%s %s\n" % (path, last))
            n = sum(1 for l in open(LOG) if l.split()[0] == path)
        scen = path.split("/")[3]
        try:
            self.serve(scen, n)
        except OSError:
            pass
    def serve(self, scen, n):
        if scen == "crlf":
            # a BOM, CRLF line ends, one byte per chunk, comments, unknown
            # fields, the result split over two data lines
            self.head()
            body = "\ufeff: hello\r\n\r\n"
            for d in events(12):
                body += sse(d, "\r\n") + ": keepalive\r\n\r\nfoo: ignored\r\n"
            js = json.dumps(ev(15, "finished", result=RESULT))
            cut = js.index('"result"')
            body += "id: 15\r\nevent: finished\r\ndata: %s\r\ndata: %s\r\n\r\n" % (js[:cut], js[cut:])
            body += sse(status("successful", "done"), "\r\n")
            b = body.encode("utf-8")
            self.chunk(b, pieces=len(b))
            self.end()
        elif scen == "cr":
            self.head()
            self.chunk("".join(sse(d, "\r") for d in events(5)) + sse(status("successful"), "\r"), pieces=7)
            self.end()
        elif scen == "replay":
            # the first stream breaks inside event 9; the next ones replay
            # everything from the start (a misbehaving server)
            self.head()
            evs = events(10)
            if n == 1:
                self.chunk("".join(sse(d) for d in evs[:8]) + sse(evs[8])[:25])
                self.drop()
                return
            self.chunk("".join(sse(d) for d in evs) + sse(status("successful")), pieces=3)
            self.end()
        elif scen == "toolong":
            self.head()
            self.chunk(sse(events(1)[0]) + "data: " + "x" * 200000 + "\n\n")
            self.end()
        elif scen == "failed":
            self.head()
            self.chunk("".join(sse(d) for d in events(3)) +
                       sse(ev(6, "failed", message="worker killed by signal 9 (SIGKILL)")) +
                       sse(status("failed", "worker killed by signal 9 (SIGKILL)")))
            self.end()
        elif scen == "away":
            if n == 1:
                self.head()
                self.chunk("".join(sse(d) for d in events(2)))
                self.drop()
                return
            self.head(503, "application/problem+json",
                      '{"type":"about:blank","title":"Service Unavailable","status":503,"detail":"shutting down"}')
        elif scen == "servererror":
            self.head(500, "application/problem+json",
                      '{"type":"about:blank","title":"Internal Server Error","status":500,"detail":"disk full"}')
        elif scen == "badid":
            self.head()
            self.chunk("id: seven\nevent: accepted\ndata: {}\n\n")
            self.end()
class Server(socketserver.ThreadingTCPServer):
    daemon_threads = True
    allow_reuse_address = True
srv = Server(("127.0.0.1", 0), H)
print(srv.server_address[1], flush=True)
srv.serve_forever()
EOF
    python3 "$WORK/fake_sse.py" "$WORK/fake-requests.txt" >"$WORK/fake-port.txt" 2>"$WORK/fake-stderr.txt" &
    DAEMON_PIDS+=($!)
    poll 10 test -s "$WORK/fake-port.txt"
    FAKE=http://127.0.0.1:$(head -1 "$WORK/fake-port.txt")
    fw() { # NAME ARGS: watch on the fake daemon
        local name=$1
        shift
        sm "$name" watch --server "$FAKE" --json "$@"
    }
    fw f-crlf crlf
    if [ "$RC" = 0 ] && seqs_contiguous "$WORK/f-crlf.out" && [ "$(wc -l <"$WORK/f-crlf.out")" = 16 ] &&
        grep -q 'job crlf successful: max_iterations after 11 iterations' "$WORK/f-crlf.log" &&
        [ "$(jq -r 'select(.type == "finished") | .result.iterations' "$WORK/f-crlf.out")" = 11 ]; then
        ok "SSE parsing: BOM, CRLF line ends, one byte per chunk, comments, unknown fields, multi-line data"
    else
        not_ok "SSE with CRLF, split bytes" "exit $RC" "$(tail -3 "$WORK/f-crlf.log")" "$(tail -2 "$WORK/f-crlf.out")"
    fi
    fw f-cr cr
    if [ "$RC" = 0 ] && seqs_contiguous "$WORK/f-cr.out" && [ "$(wc -l <"$WORK/f-cr.out")" = 8 ]; then
        ok "SSE parsing: CR-only line ends"
    else
        not_ok "SSE with CR line ends" "exit $RC" "$(cat "$WORK/f-cr.log")"
    fi
    fw f-replay replay --reconnect-timeout 5
    if [ "$RC" = 0 ] && seqs_contiguous "$WORK/f-replay.out" && [ "$(wc -l <"$WORK/f-replay.out")" = 13 ] &&
        grep -q '^/v1/jobs/replay/events 8$' "$WORK/fake-requests.txt"; then
        ok "a stream broken mid-event: reconnects with Last-Event-ID 8; a server replaying from 1 shows nothing twice"
    else
        not_ok "reconnection with a replaying server" "exit $RC" "$(cat "$WORK/fake-requests.txt")" "$(tail -3 "$WORK/f-replay.log")"
    fi
    start=$SECONDS
    fw f-away away --reconnect-timeout 1
    took=$((SECONDS - start))
    tries=$(grep -c '^/v1/jobs/away/events 4$' "$WORK/fake-requests.txt")
    if [ "$RC" = 6 ] && [ "$took" -le 8 ] && [ "$tries" -ge 2 ] &&
        grep -q 'could not resume the event stream within 1 s' "$WORK/f-away.log"; then
        ok "a daemon that stays away (503): $tries retries with Last-Event-ID, gives up after --reconnect-timeout, exit 6"
    else
        not_ok "bounded reconnection" "exit $RC after ${took}s, $tries retries" "$(tail -3 "$WORK/f-away.log")"
    fi
    fw f-failed failed
    expect f-failed 8 "a failed status ends watch with exit 8 and the failure's message" "job failed failed: worker killed by signal 9"
    fw f-long toolong
    expect f-long 9 "an over-long event line: exit 9, not an unbounded buffer" "line of the event stream is too long"
    fw f-badid badid
    expect f-badid 9 "an event id that is not a sequence number: exit 9" "not a sequence number"
    fw f-500 servererror
    expect f-500 9 "HTTP 500 with a problem document: exit 9 with its detail" "500 Internal Server Error: disk full"
else
    skip "crafted event streams need python3"
fi

# ------------------------------------------------------------------ end

DPID=$MAIN_PID
DLOG=$MAIN_LOG
check "the main daemon stops cleanly" stop_daemon
check "no sanitizer report from the client or the daemons" reports_clean

echo "1..$n"
[ "$failed" -eq 0 ]
