#!/usr/bin/env bash
# run.sh: weight 1 seconds 40
# `make demo` as CI runs it: examples/demo.sh with the binaries of the
# variant, its results and spool in a temporary folder.  Checks the
# results (files, summary, that the fetched files agree with each other and
# with the template), that the daemon is gone afterwards - after success,
# after a failing client, after SIGTERM and after Ctrl-C (SIGINT) - and, in
# the release variant, that a second run in a row works and that the job
# gives what `shapematch run` gives locally.
# Env: SM_BIN, SM_ROOT, SM_VARIANT (tests/run.sh).  Prints TAP.
set -u
ROOT=${SM_ROOT:-$(cd "$(dirname "$0")/../.." && pwd)}
BIN=${SM_BIN:-$ROOT/build/release}
VARIANT=${SM_VARIANT:-release}
W=$ROOT/build/test-integration/$VARIANT-demo-$$
rm -rf "$W"
mkdir -p "$W"
EX=$ROOT/examples/2d
SLOW=1
[ "$VARIANT" = asan ] && SLOW=4

source "$(dirname "$0")/../lib/tap.sh"
STARTED=() # pids of demo runs started in the background here
cleanup() {
    local pid
    for pid in "${STARTED[@]}"; do kill -KILL "$pid" 2>/dev/null; done
    if [ "$failed" -eq 0 ]; then rm -rf "$W"; else echo "# kept $W"; fi
}
trap cleanup EXIT

# run_demo NAME [ENV=VALUE...]: runs examples/demo.sh into $W/NAME.out
# (stdout+stderr), results in $W/NAME, spool $W/NAME-spool; sets RC.
run_demo() {
    local name=$1
    shift
    RC=0
    env SM_BIN="$BIN" DEMO_OUT="$W/$name" DEMO_SPOOL="$W/$name-spool" "$@" \
        timeout $((120 * SLOW)) bash "$ROOT/examples/demo.sh" >"$W/$name.out" 2>&1 || RC=$?
}
# daemon_pid NAME / daemon_port NAME: from the demo's output
daemon_pid() { sed -n 's/^shapematchd (pid \([0-9]*\)) listening on .*/\1/p' "$W/$1.out" | head -1; }
daemon_port() { sed -n 's/^shapematchd (pid [0-9]*) listening on http:\/\/127\.0\.0\.1:\([0-9]*\)$/\1/p' "$W/$1.out" | head -1; }
# daemon_gone NAME: the demo's daemon process is gone and its port refuses
daemon_gone() {
    local pid port
    pid=$(daemon_pid "$1")
    port=$(daemon_port "$1")
    [ -n "$pid" ] && [ -n "$port" ] || return 1
    ! kill -0 "$pid" 2>/dev/null || return 1
    curl -s --max-time 2 -o /dev/null "http://127.0.0.1:$port/healthz"
    [ $? -eq 7 ] # 7: could not connect
}
# no sanitizer report in the daemon's or a worker's log
reports_clean() {
    ! grep -lE 'Sanitizer|runtime error' "$W/$1.out" "$W/$1-spool.log" "$W/$1-spool"/jobs/*/worker.log \
        2>/dev/null | grep -q .
}

# medit_vertices FILE: "x y" per vertex of a Medit ASCII 2D mesh;
# medit_sol2 FILE: "u v" per vertex of a 2D vector SolAtVertices file
medit_vertices() {
    awk '{ for (i = 1; i <= NF; i++) t[++k] = $i }
    END {
        for (i = 1; i <= k; i++) if (t[i] == "Vertices") { nv = t[i + 1]; s = i + 1; break }
        for (v = 0; v < nv; v++) print t[s + 1 + 3 * v], t[s + 2 + 3 * v]
    }' "$1"
}
medit_sol2() {
    awk '{ for (i = 1; i <= NF; i++) t[++k] = $i }
    END {
        for (i = 1; i <= k; i++) if (t[i] == "SolAtVertices") { nv = t[i + 1]; s = i + 3; break }
        for (v = 0; v < nv; v++) print t[s + 1 + 2 * v], t[s + 2 + 2 * v]
    }' "$1"
}

# ------------------------------------------------------------ a first run
run_demo one
if [ "$RC" -eq 0 ]; then ok "examples/demo.sh exits 0"; else not_ok "examples/demo.sh exits 0 (got $RC)" "$(tail -30 "$W/one.out")"; fi
O=$W/one
missing=
for f in result.mesh result.vtu displacement.sol history.csv summary.json; do [ -s "$O/$f" ] || missing="$missing $f"; done
check "result.mesh, result.vtu, displacement.sol, history.csv, summary.json fetched into DEMO_OUT" test -z "$missing"

stop=$(jq -r .stop_reason "$O/summary.json" 2>/dev/null)
iters=$(jq -r .iterations "$O/summary.json" 2>/dev/null)
bl2=$(jq -r .boundary_l2 "$O/summary.json" 2>/dev/null)
if [ -n "$bl2" ] && awk -v e="$bl2" 'BEGIN { exit !(e + 0 <= 1e-3 && e + 0 > 0) }'; then
    ok "L2 of d on the boundary $bl2 <= 1e-3"
else
    not_ok "L2 of d on the boundary <= 1e-3" "summary: $(head -c 400 "$O/summary.json" 2>/dev/null)"
fi
# the demo asks for 1e-4: reaching it is the expected way to stop
if [ "$stop" = boundary_tolerance ] && awk -v e="$bl2" 'BEGIN { exit !(e + 0 <= 1e-4) }' &&
    [ "$iters" -ge 1 ] 2>/dev/null && [ "$iters" -lt 500 ]; then
    ok "stopped on the boundary tolerance 1e-4 after $iters iterations"
else
    not_ok "stopped on the boundary tolerance 1e-4" "stop_reason=$stop iterations=$iters boundary_l2=$bl2"
fi
# the one-line summary says what summary.json says
line=$(grep '^summary: ' "$W/one.out")
rt=$(jq -r .distance.result_to_target.rms "$O/summary.json" 2>/dev/null)
tr=$(jq -r .distance.target_to_result.rms "$O/summary.json" 2>/dev/null)
p99=$(jq -r .distance.target_to_result.p99 "$O/summary.json" 2>/dev/null)
want=$(awk -v s="$stop" -v i="$iters" -v a="$rt" -v b="$tr" -v c="$p99" -v e="$bl2" \
    'BEGIN { printf "summary: %s after %d iterations: result->target RMS %.3g, target->result RMS %.3g (p99 %.3g); L2 of d on the boundary %.3g", s, i, a, b, c, e }')
if [[ $line == "$want"* ]]; then ok "one-line summary: ${line#summary: }"; else not_ok "one-line summary matches summary.json" "printed: $line" "expected: $want..."; fi
check "the output says where the results are" grep -qF "results in $O/:" "$W/one.out"
check "progress was shown while the job ran" grep -qE '^iter +[0-9]+ +result->target rms ' "$W/one.out"

# history: a header, iterations 0..N, its last row the final state
rows=$(($(grep -c . "$O/history.csv") - 1))
last_bl2=$(awk -F, 'NR == 1 { for (i = 1; i <= NF; i++) if ($i == "boundary_l2") c = i } END { print $c }' "$O/history.csv")
if [ "$rows" -eq $((iters + 1)) ] && awk -v a="$last_bl2" -v b="$bl2" 'BEGIN { d = a - b; exit !(d * d <= 1e-24 * b * b) }'; then
    ok "history.csv: $rows rows (iterations 0..$iters), last boundary_l2 = summary's"
else
    not_ok "history.csv agrees with the summary" "rows=$rows iterations=$iters last=$last_bl2 summary=$bl2"
fi

# result = template + displacement at every vertex; clamped vertices (in
# the disk of examples/2d/clamp) do not move; the others do
IFS=, read -r cx cy cr <"$EX/clamp"
medit_vertices "$EX/template.mesh" >"$W/t.xy"
medit_vertices "$O/result.mesh" >"$W/r.xy" 2>/dev/null
medit_sol2 "$O/displacement.sol" >"$W/u.xy" 2>/dev/null
verdict=$(paste -d' ' "$W/t.xy" "$W/r.xy" "$W/u.xy" | awk -v cx="$cx" -v cy="$cy" -v cr="$cr" '
    NF != 6 { bad = "file lengths differ at vertex " NR; exit }
    {
        ex = $3 - ($1 + $5); ey = $4 - ($2 + $6)
        err = sqrt(ex * ex + ey * ey); if (err > maxerr) maxerr = err
        u = sqrt($5 * $5 + $6 * $6)
        if ((($1 - cx)^2 + ($2 - cy)^2) <= cr * cr * (1 - 1e-9)) { clamped++; if (u > umax_clamped) umax_clamped = u }
        else if (u > 1e-3) moved++
        n++
    }
    END {
        if (bad != "") { print bad; exit }
        if (n != 440) { print "expected 440 vertices, got " n; exit }
        if (maxerr > 1e-9) { print "result != template + displacement: max error " maxerr; exit }
        if (clamped < 1 || umax_clamped != 0) { print "clamped vertices " clamped ", max displacement there " umax_clamped; exit }
        if (moved < n / 2) { print "only " moved " of " n " vertices moved"; exit }
        printf "ok %d vertices, %d clamped, %d moved, max |x - (x0 + u)| = %.1e\n", n, clamped, moved, maxerr
    }')
if [[ $verdict == ok* ]]; then ok "result.mesh = template + displacement.sol: ${verdict#ok }"; else not_ok "result.mesh = template + displacement.sol" "$verdict"; fi
check "result.vtu holds the 440 vertices, 778 triangles and the 116 facets (100 boundary, 16 clamp edges)" \
    grep -q 'NumberOfPoints="440" NumberOfCells="894"' "$O/result.vtu"
check "the daemon is stopped after the demo (process gone, port closed)" daemon_gone one
check "no sanitizer report from the client, the daemon or the worker" reports_clean one

# ---------------------------------------------------------- refuse to wipe
mkdir -p "$W/precious-spool"
echo keep >"$W/precious-spool/data"
run_demo precious
if [ "$RC" -ne 0 ] && [ -f "$W/precious-spool/data" ] && ! grep -q 'listening on' "$W/precious.out"; then
    ok "a DEMO_SPOOL that is not a demo spool is refused and left alone"
else
    not_ok "a DEMO_SPOOL that is not a demo spool is refused and left alone" "rc=$RC" "$(cat "$W/precious.out")"
fi

# --------------------------------------- the daemon stops whatever happens
# fake clients next to the real daemon: one that fails, one that hangs
fake_bin() { # NAME BODY: $W/NAME-bin with the real daemon and a fake client
    mkdir -p "$W/$1-bin"
    ln -sf "$BIN/shapematchd" "$BIN/shapematch-worker" "$W/$1-bin/"
    printf '#!/bin/sh\n%s\n' "$2" >"$W/$1-bin/shapematch"
    chmod +x "$W/$1-bin/shapematch"
}
fake_bin failing 'case "$*" in *--help*) exit 0 ;; esac; echo "fake client: failing on purpose" >&2; exit 3'
fake_bin hanging 'case "$*" in *--help*) exit 0 ;; esac; exec sleep 300'

BIN_SAVED=$BIN
BIN=$W/failing-bin
run_demo failing
BIN=$BIN_SAVED
if [ "$RC" -ne 0 ] && grep -q 'client failed (exit 3)' "$W/failing.out"; then
    ok "a failing client makes the demo fail with the client's status"
else
    not_ok "a failing client makes the demo fail with the client's status" "rc=$RC" "$(cat "$W/failing.out")"
fi
check "... and the daemon is stopped" daemon_gone failing

# signal SIG NAME: the demo with the hanging client, signalled once its
# daemon listens; it must exit promptly, daemon and client gone
signal_demo() {
    local sig=$1 name=$2
    # a background job of a script ignores SIGINT; python restores the
    # default disposition as an interactive shell would have it
    env SM_BIN="$W/hanging-bin" DEMO_OUT="$W/$name" DEMO_SPOOL="$W/$name-spool" \
        python3 -c 'import os, signal, sys; signal.signal(signal.SIGINT, signal.SIG_DFL); os.execvp("bash", ["bash", sys.argv[1]])' \
        "$ROOT/examples/demo.sh" >"$W/$name.out" 2>&1 &
    local demo=$!
    STARTED+=("$demo")
    local i
    for ((i = 0; i < 200 * SLOW; i++)); do
        grep -qs 'listening on' "$W/$name.out" && break
        sleep 0.05
    done
    # the fake client is running (the demo waits for it)
    local client=
    for ((i = 0; i < 100 * SLOW; i++)); do
        client=$(pgrep -P "$demo" -x sleep) && break
        sleep 0.05
    done
    kill -"$sig" "$demo"
    local t0=$SECONDS
    for ((i = 0; i < 200 * SLOW; i++)); do
        kill -0 "$demo" 2>/dev/null || break
        sleep 0.05
    done
    if kill -0 "$demo" 2>/dev/null; then
        not_ok "SIG$sig: the demo exits" "still running after $((SECONDS - t0)) s" "$(cat "$W/$name.out")"
        kill -KILL "$demo"
        return
    fi
    wait "$demo"
    RC=$?
    local want=$((128 + $(kill -l "$sig")))
    if [ "$RC" -eq "$want" ] && daemon_gone "$name" && grep -q 'stopped$' "$W/$name.out" &&
        { [ -z "$client" ] || ! kill -0 "$client" 2>/dev/null; }; then
        ok "SIG$sig during the job: demo exits $RC within $((SECONDS - t0)) s, daemon and client stopped"
    else
        not_ok "SIG$sig during the job: demo exits $want, daemon and client stopped" "rc=$RC client=$client" "$(cat "$W/$name.out")"
    fi
}
signal_demo TERM term
signal_demo INT int

# ------------------------------------------------------- twice in a row
if [ "$VARIANT" = release ]; then
    run_demo one
    jobs_in_spool=$(find "$W/one-spool/jobs" -mindepth 1 -maxdepth 1 -type d | wc -l)
    iters2=$(jq -r .iterations "$W/one/summary.json" 2>/dev/null)
    if [ "$RC" -eq 0 ] && [ "$iters2" = "$iters" ] && [ "$jobs_in_spool" -eq 1 ] && daemon_gone one; then
        ok "a second run in a row (same DEMO_OUT and spool) works: $iters2 iterations, a fresh spool"
    else
        not_ok "a second run in a row works" "rc=$RC iterations=$iters2 (first $iters) jobs in spool=$jobs_in_spool" "$(tail -20 "$W/one.out")"
    fi

    # the daemon's job gives what the local CLI gives (same core, same inputs)
    "$BIN/shapematch" run --quiet --template "$EX/template.mesh" --target-mesh "$EX/background.mesh.gz" \
        --target-sol "$EX/background.sol.gz" --clamp-ball "$(cat "$EX/clamp")" --tol-boundary 1e-4 \
        -o "$W/local" >"$W/local.out" 2>&1
    li=$(jq -r .iterations "$W/local/summary.json" 2>/dev/null)
    lb=$(jq -r '.boundary_l2 // .boundary_error_l2' "$W/local/summary.json" 2>/dev/null)
    if [ "$li" = "$iters" ] && awk -v a="$lb" -v b="$bl2" 'BEGIN { d = a - b; exit !(d * d <= 1e-20 * b * b) }'; then
        ok "same iterations ($li) and boundary_l2 as 'shapematch run' locally"
    else
        not_ok "same result as 'shapematch run' locally" "local: iterations=$li boundary=$lb; demo: $iters $bl2" "$(tail -5 "$W/local.out")"
    fi
fi

[ "$failed" -eq 0 ]
