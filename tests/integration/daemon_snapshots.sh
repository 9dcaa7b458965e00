#!/usr/bin/env bash
# Snapshots through the daemon (params.save_every): a job with save_every
# 10 and max_iter 30 lists exactly the snapshots `shapematch run
# --save-every 10 --max-iter 30` writes (the first state 0, then 10, 20,
# 30; one BLAS/OpenMP thread on both sides), and each one fetched (plain and gzip) is byte-identical to the
# CLI's iter-NNNNN.mesh; unknown iterations and anything that is not an
# iteration (leading zeros, signs, letters, traversal attempts) are 404
# problem+json; a job without save_every lists none; a running job's
# snapshots are not served (result-not-ready) and its worker writes them
# in results.tmp/snapshots/; no sanitizer report.
source "$(dirname "$0")/lib.sh"

if ! make_case; then
    not_ok "gmsh builds the test meshes" "$(tail -5 "$WORK/case/gmsh.log")"
    exit 1
fi
if ! start_daemon snaps --workers 2 --worker-threads 1 --kill-grace 2; then
    not_ok "the daemon starts"
    exit 1
fi
ok "the daemon starts"

# a job that runs until cancelled, with a snapshot every iteration
E=$(submit "$FINE" "$BOX" "$BOXSOL" "$BALL_PARAMS, \"max_iter\": 100000000, \"tol_step\": 1e-15, \"tol_stall\": 0, \"save_every\": 1}")
S=$(submit "$DISK" "$BOX" "$BOXSOL" "$BALL_PARAMS, \"max_iter\": 30, \"save_every\": 10}")
N=$(submit "$DISK" "$BOX" "$BOXSOL" "$(quick_params 30)")
if [ -n "$E" ] && [ -n "$S" ] && [ -n "$N" ]; then
    ok "three jobs submitted (one endless with save_every 1, one with save_every 10, one without)"
else
    not_ok "submit" "$(cat "$WORK/submit.out")"
    exit 1
fi

# problem ID SUFFIX STATUS TYPE-SUFFIX: GET /v1/jobs/ID/results/SUFFIX
# answers STATUS as problem+json whose type ends with TYPE-SUFFIX
problem() {
    local id=$1 suffix=$2 want=$3 type=$4 got
    got=$(curl -sS -o "$WORK/p.json" -w '%{http_code} %{content_type}' "$BASE/v1/jobs/$id/results/$suffix")
    [ "$got" = "$want application/problem+json" ] &&
        jq -e --arg t "$type" --argjson s "$want" '.status == $s and (.type | endswith($t)) and (.detail | length > 0)' \
            "$WORK/p.json" >/dev/null
}

# ------------------------------------------------------------ running
if wait_state "$E" running 20 && poll 20 test -n "$(ls "$SPOOL/jobs/$E/results.tmp/snapshots/" 2>/dev/null)"; then
    first=$(ls "$SPOOL/jobs/$E/results.tmp/snapshots/" | head -1)
    if [ "$first" = iter-00000.mesh ]; then
        ok "a running job writes its snapshots into results.tmp/snapshots/ (first: $first)"
    else
        not_ok "snapshots of a running job" "$(ls "$SPOOL/jobs/$E/results.tmp/snapshots/")"
    fi
else
    not_ok "the endless job runs and writes snapshots" "$(job_state "$E")" "$(ls -R "$SPOOL/jobs/$E" 2>&1 | head)"
fi
if problem "$E" snapshots 404 result-not-ready && problem "$E" snapshots/1 404 result-not-ready; then
    ok "a running job: snapshot list and snapshot are 404 result-not-ready"
else
    not_ok "running job snapshots" "$(cat "$WORK/p.json")"
fi
curl -sS -o /dev/null -X DELETE "$BASE/v1/jobs/$E"
if wait_state "$E" dismissed 20; then ok "the endless job is cancelled"; else not_ok "cancel" "$(job_state "$E")"; fi
if problem "$E" snapshots 404 result-not-ready; then
    ok "a dismissed job: the snapshot list is 404 result-not-ready"
else
    not_ok "dismissed job snapshots" "$(cat "$WORK/p.json")"
fi

# ------------------------------------------------------------ finished
wait_state "$S" successful 30 && wait_state "$N" successful 30
if [ "$(job_state "$S")" = successful ] && [ "$(job_state "$N")" = successful ]; then
    ok "the two finite jobs are successful"
else
    not_ok "jobs successful" "$(job_state "$S") $(job_state "$N")"
fi

# the same run with the CLI, one thread as the daemon's workers
CLI=$WORK/cli-out
OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 \
    "$BIN/shapematch" run --template "$DISK" --target-mesh "$BOX" --target-sol "$BOXSOL" \
    --clamp-ball 0,0,0.1 --max-iter 30 --save-every 10 -o "$CLI" --quiet >"$WORK/cli.log" 2>&1
cli_iters=$(cd "$CLI" && ls iter-*.mesh 2>/dev/null | sed 's/^iter-0*\([0-9]\)/\1/; s/\.mesh$//' | sort -n | tr '\n' ' ')
if [ "$cli_iters" = "0 10 20 30 " ]; then
    ok "shapematch run --save-every 10 --max-iter 30 writes the first state and iterations 10 20 30"
else
    not_ok "the CLI's snapshots" "'$cli_iters'" "$(tail -5 "$WORK/cli.log")"
fi

code=$(curl -sS -o "$WORK/list.json" -w '%{http_code} %{content_type}' "$BASE/v1/jobs/$S/results/snapshots")
listed=$(jq -r '[.snapshots[].iteration | tostring] | join(" ")' "$WORK/list.json" 2>/dev/null)
if [ "$code" = "200 application/json" ] && [ "$listed " = "$cli_iters" ] &&
    jq -e --arg id "$S" '.jobID == $id and all(.snapshots[]; .href == "/v1/jobs/\($id)/results/snapshots/\(.iteration)" and .type == "application/x-medit-mesh") and ([.links[].rel] | index("self") and index("up"))' \
        "$WORK/list.json" >/dev/null; then
    ok "GET .../results/snapshots lists the CLI's iterations ($listed) with hrefs"
else
    not_ok "snapshot list" "$code" "listed '$listed', CLI '$cli_iters'" "$(head -c 800 "$WORK/list.json")"
fi

same=0 total=0 sizes=0 names=0
for it in $listed; do
    total=$((total + 1))
    f=$(printf 'iter-%05d.mesh' "$it")
    got=$(curl -sS -o "$WORK/$f" -D "$WORK/snap.hdr" -w '%{http_code} %{content_type}' "$BASE/v1/jobs/$S/results/snapshots/$it")
    [ "$got" = "200 application/x-medit-mesh" ] && cmp -s "$WORK/$f" "$CLI/$f" && same=$((same + 1))
    bytes=$(jq -r --argjson i "$it" '.snapshots[] | select(.iteration == $i) | .bytes' "$WORK/list.json")
    [ "$bytes" = "$(stat -c %s "$CLI/$f")" ] && sizes=$((sizes + 1))
    tr -d '\r' <"$WORK/snap.hdr" | grep -qi "^content-disposition: attachment; filename=\"$f\"$" && names=$((names + 1))
done
if [ "$total" -ge 1 ] && [ "$same" = "$total" ] && [ "$sizes" = "$total" ] && [ "$names" = "$total" ]; then
    ok "each of the $total snapshots is byte-identical to the CLI's iter-NNNNN.mesh, its listed size and file name match"
else
    not_ok "snapshots equal the CLI's" "$same/$total identical, $sizes sizes, $names names"
fi

got=$(curl -sS -o "$WORK/snap.gz" -D "$WORK/gz.hdr" -w '%{http_code}' -H 'Accept-Encoding: gzip' \
    "$BASE/v1/jobs/$S/results/snapshots/20?format=mesh")
if [ "$got" = 200 ] && tr -d '\r' <"$WORK/gz.hdr" | grep -qi '^content-encoding: gzip$' &&
    gzip -dc "$WORK/snap.gz" | cmp -s - "$CLI/iter-00020.mesh"; then
    ok "?format=mesh with Accept-Encoding: gzip: gzip of the CLI's iter-00020.mesh"
else
    not_ok "gzip snapshot" "$got" "$(cat "$WORK/gz.hdr")"
fi
if problem "$S" 'snapshots/20?format=vtu' 400 about:blank; then
    ok "a snapshot in another format than mesh: 400"
else
    not_ok "format=vtu" "$(cat "$WORK/p.json")"
fi

# not snapshots: each a 404 problem, none a file
bad=""
for seg in 15 40 00 010 00010 +10 -10 1e1 0x14 abc 1234567890 99999999999999999999 '..%2Fsummary.json' \
    '..%2F..%2Fjob.json' '%2E%2E' iter-00010.mesh '10.mesh' '10%2F'; do
    problem "$S" "snapshots/$seg" 404 about:blank || bad="$bad $seg($(head -c 120 "$WORK/p.json"))"
done
if [ -z "$bad" ]; then
    ok "missing iterations, non-canonical numbers, names and traversal attempts: 404 problem+json"
else
    not_ok "404 for what is not a snapshot" "$bad"
fi
if problem 0123456789abcdef0123456789abcdef snapshots 404 no-such-job &&
    problem 0123456789abcdef0123456789abcdef snapshots/10 404 no-such-job; then
    ok "an unknown job: 404 no-such-job"
else
    not_ok "unknown job" "$(cat "$WORK/p.json")"
fi

code=$(curl -sS -o "$WORK/none.json" -w '%{http_code}' "$BASE/v1/jobs/$N/results/snapshots")
if [ "$code" = 200 ] && jq -e --arg id "$N" '.jobID == $id and .snapshots == []' "$WORK/none.json" >/dev/null &&
    [ ! -e "$SPOOL/jobs/$N/results/snapshots" ] && problem "$N" snapshots/10 404 about:blank; then
    ok "a job without save_every lists no snapshot and writes no snapshots/ folder"
else
    not_ok "job without save_every" "$code" "$(head -c 400 "$WORK/none.json")"
fi
if jq -e --arg id "$S" '[.links[] | select(.rel == "related") | .href] == ["/v1/jobs/\($id)/results/snapshots"]' \
    <(curl -sS "$BASE/v1/jobs/$S/results") >/dev/null; then
    ok "the results summary links to the snapshot list"
else
    not_ok "summary link to snapshots"
fi

stop_daemon
rc=$?
if [ "$rc" = 0 ]; then ok "SIGTERM: the daemon exits 0"; else not_ok "daemon exit" "status $rc"; fi
if reports_clean; then ok "no sanitizer report in the daemon or worker logs"; else not_ok "sanitizer reports"; fi
echo "1..$n"
