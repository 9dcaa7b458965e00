#!/usr/bin/env bash
# Pre-alignment through the daemon: params align runs in the worker like
# in `shapematch run` (one job runner): examples/2d moved 30 degrees and
# 100 diameters (tests/cli/align_inputs.py) with align rigid ends
# successful, its events carry one "alignment" event before the first
# progress, with the figures of summary.json's alignment; an unknown align
# is answered 422 naming params.align.
source "$(dirname "$0")/lib.sh"

EX=$ROOT/examples/2d
if ! python3 "$ROOT/tests/cli/align_inputs.py" "$EX" "$WORK"; then
    not_ok "align inputs"
    exit 1
fi
if ! start_daemon align --workers 1; then
    not_ok "the daemon starts"
    exit 1
fi
ok "the daemon starts"
MC=$(python3 -c 'import math; a=math.radians(30); print("%.17g, %.17g" % (math.cos(a)*.5-math.sin(a)*.5+40, math.sin(a)*.5+math.cos(a)*.5-30))')
id=$(submit "$WORK/moved.mesh" "$EX/background.mesh.gz" "$EX/background.sol.gz" \
    "{\"clamp\": {\"kind\": \"ball\", \"center\": [$MC], \"radius\": 0.04}, \"align\": \"rigid\"}")
if [ -n "$id" ] && wait_final "$id" 120 && state_is "$id" successful; then
    ok "a moved template with align rigid: successful"
else
    not_ok "align rigid job" "$(cat "$WORK/submit.out")"
fi
hcurl "${AUTH[@]}" "$BASE/v1/jobs/$id/events" >"$WORK/events.ndjson"
hcurl "${AUTH[@]}" "$BASE/v1/jobs/$id/results" >"$WORK/summary.json"
first=$(jq -rs '[.[] | select(.type == "alignment" or .type == "progress") | .type] | first' \
    "$WORK/events.ndjson")
n=$(jq -s '[.[] | select(.type == "alignment")] | length' "$WORK/events.ndjson")
same=$(jq -n --slurpfile e "$WORK/events.ndjson" --slurpfile s "$WORK/summary.json" '
    ($e | map(select(.type == "alignment")) | first) as $a | $s[0].alignment as $b |
    $a.rms_after == $b.rms_after and $a.iterations == $b.iterations and $a.mode == "rigid"')
if [ "$first" = alignment ] && [ "$n" = 1 ] && [ "$same" = true ] &&
    [ "$(jq '.alignment.matrix | length' "$WORK/summary.json")" = 9 ]; then
    ok "one alignment event before the first progress, as summary.json's alignment"
else
    not_ok "alignment event" "first $first, count $n, same $same"
fi

code=$(hcurl "${AUTH[@]}" -o "$WORK/bad.out" -w '%{http_code}' -F "template=@$EX/template.mesh" \
    -F "target_mesh=@$EX/background.mesh.gz" -F "target_sol=@$EX/background.sol.gz" \
    -F 'params={"clamp": {"kind": "ball", "center": [0.5, 0.5], "radius": 0.04}, "align": "shear"}' \
    "$BASE/v1/jobs")
if [ "$code" = 422 ] && grep -q 'params.align' "$WORK/bad.out"; then
    ok "align \"shear\": 422 naming params.align"
else
    not_ok "unknown align refused" "$code $(cat "$WORK/bad.out")"
fi
