#!/usr/bin/env bash
# Warning events through the daemon (issue 10): the crafted input of
# tests/cli/warnings.sh whose background covers part of the shape makes
# the worker send a "warning" event (code, message, figure) that the job's
# event stream carries before "finished", as NDJSON and as SSE (event:
# warning), with the same code and figure as summary.json's warnings;
# `shapematch watch` prints it on stderr (also with --quiet).  The clean
# 2D example sends none.
source "$(dirname "$0")/lib.sh"

EX=$ROOT/examples/2d
if ! python3 "$ROOT/tests/cli/warnings_inputs.py" "$WORK"; then
    not_ok "crafted inputs"
    exit 1
fi
if ! start_daemon warn --workers 1; then
    not_ok "the daemon starts"
    exit 1
fi
ok "the daemon starts"
CLAMP='"clamp": {"kind": "ball", "center": [0.5, 0.5], "radius": 0.04}'

part=$(submit "$EX/template.mesh" "$WORK/part.mesh" "$WORK/part.sol" "{$CLAMP, \"max_iter\": 60}")
clean=$(submit "$EX/template.mesh" "$EX/background.mesh.gz" "$EX/background.sol.gz" "{$CLAMP}")
if [ -n "$part" ] && [ -n "$clean" ] && wait_final "$part" 120 && wait_final "$clean" 120 &&
    state_is "$part" successful && state_is "$clean" successful; then
    ok "both jobs end successful"
else
    not_ok "both jobs end successful" "$(cat "$WORK/submit.out")"
fi

hcurl "${AUTH[@]}" "$BASE/v1/jobs/$part/events" >"$WORK/part.ndjson"
hcurl "${AUTH[@]}" "$BASE/v1/jobs/$part/results" >"$WORK/part.summary.json"
ev=$(jq -c 'select(.type == "warning" and .code == "outside-background")' "$WORK/part.ndjson")
sfig=$(jq '[.warnings[] | select(.code == "outside-background") | .figure] | first' \
    "$WORK/part.summary.json")
efig=$(jq -n --argjson e "${ev:-null}" '$e.figure')
if [ -n "$ev" ] && [ "$efig" = "$sfig" ] && [ "$(jq -n --argjson e "$ev" '$e.seq > 0 and
        ($e.message | length) > 0 and ($e.time | length) > 0')" = true ]; then
    ok "the part-covered background: a warning event outside-background (figure $efig, as summary.json)"
else
    not_ok "warning event outside-background" "event: $ev; summary figure: $sfig"
fi
# one event per warning of the summary, before finished
nsum=$(jq '.warnings | length' "$WORK/part.summary.json")
nev=$(jq -s '[.[] | select(.type == "warning")] | length' "$WORK/part.ndjson")
order=$(jq -rs '[.[] | select(.type == "warning" or .type == "finished") | .type] | last' \
    "$WORK/part.ndjson")
if [ "$nev" = "$nsum" ] && [ "$order" = finished ]; then
    ok "as many warning events as summary warnings ($nev), all before finished"
else
    not_ok "warning events vs summary" "events $nev, summary $nsum, last $order"
fi

hcurl "${AUTH[@]}" -H 'Accept: text/event-stream' "$BASE/v1/jobs/$part/events" >"$WORK/part.sse"
if grep -q '^event: warning$' "$WORK/part.sse" &&
    grep -q '^data: {"type":"warning".*"code":"outside-background"' "$WORK/part.sse"; then
    ok "SSE: event: warning with its data line"
else
    not_ok "SSE warning event" "$(grep -c . "$WORK/part.sse") lines"
fi

"$BIN/shapematch" watch --server "$BASE" --quiet "$part" >"$WORK/watch.out" 2>"$WORK/watch.err"
rc=$?
if [ $rc -eq 0 ] && grep -q '^shapematch: warning: outside-background: ' "$WORK/watch.err"; then
    ok "watch --quiet prints the warning on stderr"
else
    not_ok "watch prints the warning (exit $rc)" "$(cat "$WORK/watch.err")"
fi

hcurl "${AUTH[@]}" "$BASE/v1/jobs/$clean/events" >"$WORK/clean.ndjson"
if [ "$(jq -s '[.[] | select(.type == "warning")] | length' "$WORK/clean.ndjson")" = 0 ] &&
    [ "$(jq -s '[.[] | select(.type == "finished")] | length' "$WORK/clean.ndjson")" = 1 ]; then
    ok "the clean 2D example: no warning event"
else
    not_ok "clean example without warning events" "$(jq -c 'select(.type == "warning")' "$WORK/clean.ndjson")"
fi
reports_clean && ok "no sanitizer report" || not_ok "no sanitizer report"
stop_daemon
echo "1..$n"
