#!/usr/bin/env bash
# Pre-alignment through the daemon: params align runs in the worker like
# in `shapematch run` (one job runner): examples/2d moved 30 degrees and
# 100 diameters (tests/cli/align_inputs.py) with align rigid ends
# successful, its events carry one "alignment" event before the first
# progress, with the figures of summary.json's alignment; an unknown align
# is answered 422 naming params.align.  Landmarks: the parts
# template_landmarks and target_landmarks (curl) and `shapematch submit
# --landmarks --wait` give the job the same start as `shapematch run
# --landmarks`: the same alignment matrix and boundary RMS; a malformed
# landmark part, one part alone, and landmarks with align none are 422s
# naming the part, as are one over 1 MiB, a gzip-compressed one, one
# pair in 2D and coincident points (the landmark start is computed at
# upload); the
# OGC execute request takes them as inputs.
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

# ------------------------------------------------------------ landmarks
LMT=$WORK/lm_template.csv
LMG=$WORK/lm_target.csv
MCC=${MC/, /,}
"$BIN/shapematch" run --template "$WORK/moved.mesh" --target-mesh "$EX/background.mesh.gz" \
    --target-sol "$EX/background.sol.gz" --clamp-ball "$MCC,0.04" --align rigid \
    --landmarks "$LMT,$LMG" --max-iter 3 -o "$WORK/lmrun" >/dev/null 2>"$WORK/lmrun.err"
LMP="{\"clamp\": {\"kind\": \"ball\", \"center\": [$MC], \"radius\": 0.04}, \"align\": \"rigid\", \"max_iter\": 3}"
# same_as_run SUMMARY: the landmark start taken, the alignment and the
# match as the CLI's (one job runner; 1e-9 relative for the thread count)
same_as_run() {
    jq -en --slurpfile a "$1" --slurpfile b "$WORK/lmrun/summary.json" '
        $a[0] as $x | $b[0] as $y |
        def near(p; q): ((p - q) | fabs) <= 1e-9 * ((q | fabs) + 1e-12);
        $x.alignment.landmarks == 4 and $y.alignment.landmarks == 4 and
        ([range(9)] | all(near($x.alignment.matrix[.]; $y.alignment.matrix[.]))) and
        near($x.boundary_rms; $y.boundary_rms) and $x.iterations == $y.iterations' >/dev/null
}
id=$(submit "$WORK/moved.mesh" "$EX/background.mesh.gz" "$EX/background.sol.gz" "$LMP" \
    -F "template_landmarks=@$LMT" -F "target_landmarks=@$LMG")
if [ -n "$id" ] && wait_final "$id" 120 && state_is "$id" successful &&
    hcurl "${AUTH[@]}" "$BASE/v1/jobs/$id/results" >"$WORK/lm_curl.json" &&
    same_as_run "$WORK/lm_curl.json"; then
    ok "landmark parts (curl): the alignment and the result of run --landmarks"
else
    not_ok "landmark parts (curl)" "$(cat "$WORK/submit.out")" "$(head -c 400 "$WORK/lm_curl.json")"
fi
hcurl "${AUTH[@]}" -o "$WORK/lm_back.csv" "$BASE/v1/jobs/$id/inputs/target_landmarks"
hcurl "${AUTH[@]}" "$BASE/v1/jobs/$id/inputs" >"$WORK/lm_inputs.json"
if cmp -s "$WORK/lm_back.csv" "$LMG" &&
    [ "$(jq -r '[.inputs[] | select(.part == "template_landmarks") | .file] | first' "$WORK/lm_inputs.json")" = template_landmarks.csv ]; then
    ok "the job's inputs list template_landmarks.csv; target_landmarks served as sent"
else
    not_ok "landmark inputs served" "$(head -c 400 "$WORK/lm_inputs.json")"
fi
timeout $((120 * SLOW)) "$BIN/shapematch" submit --server "$BASE" --template "$WORK/moved.mesh" \
    --target-mesh "$EX/background.mesh.gz" --target-sol "$EX/background.sol.gz" \
    --clamp-ball "$MCC,0.04" --align rigid --landmarks "$LMT,$LMG" --max-iter 3 --wait --quiet \
    -o "$WORK/lmsub" >/dev/null 2>"$WORK/lmsub.err"
rc=$?
# 10: finished, not converged (3 iterations), as the run's
if [ "$rc" = 10 ] && same_as_run "$WORK/lmsub/summary.json"; then
    ok "submit --landmarks --wait: the alignment and the result of run --landmarks"
else
    not_ok "submit --landmarks --wait (exit $rc)" "$(head -c 600 "$WORK/lmsub.err")"
fi
# the OGC execute request takes the landmark files as inline inputs too
jq -n --rawfile t <(base64 -w0 "$WORK/moved.mesh") --rawfile m <(base64 -w0 "$EX/background.mesh.gz") \
    --rawfile s <(base64 -w0 "$EX/background.sol.gz") --rawfile a <(base64 -w0 "$LMT") \
    --rawfile b <(base64 -w0 "$LMG") --argjson p "$LMP" \
    '{inputs: {template: {value: $t}, target_mesh: {value: $m}, target_sol: {value: $s},
               template_landmarks: {value: $a}, target_landmarks: {value: $b}, params: $p}}' \
    >"$WORK/lm_exec.json"
id=$(hcurl "${AUTH[@]}" -H 'Content-Type: application/json' --data-binary "@$WORK/lm_exec.json" \
    "$BASE/v1/processes/match/execution" | jq -r '.jobID // empty')
if [ -n "$id" ] && wait_final "$id" 120 && state_is "$id" successful &&
    hcurl "${AUTH[@]}" "$BASE/v1/jobs/$id/results" >"$WORK/lm_exec_summary.json" &&
    same_as_run "$WORK/lm_exec_summary.json"; then
    ok "OGC execute with template_landmarks and target_landmarks: the alignment of run --landmarks"
else
    not_ok "OGC execute with landmarks" "job '$id'"
fi

# refused: NAME EXTRA-PARAMS-JSON PATTERN CURL-ARGS...
refused() {
    local name=$1 extra=$2 pattern=$3
    shift 3
    local p="{\"clamp\": {\"kind\": \"ball\", \"center\": [$MC], \"radius\": 0.04}$extra}"
    id=$(submit "$WORK/moved.mesh" "$EX/background.mesh.gz" "$EX/background.sol.gz" "$p" "$@")
    if [ "$(cat "$WORK/submit.code")" = 422 ] && grep -q -- "$pattern" "$WORK/submit.out"; then
        ok "$name: 422 naming $pattern"
    else
        not_ok "$name" "$(cat "$WORK/submit.code") $(cat "$WORK/submit.out")"
    fi
}
refused "a malformed target_landmarks" ', "align": "rigid"' 'target_landmarks: line 2' \
    -F "template_landmarks=@$LMT" -F "target_landmarks=@$WORK/lm_bad.csv"
refused "template_landmarks alone" ', "align": "rigid"' 'target_landmarks' -F "template_landmarks=@$LMT"
refused "landmarks with align none" '' 'template_landmarks: landmarks need an alignment' \
    -F "template_landmarks=@$LMT" -F "target_landmarks=@$LMG"
# the landmark start is computed at upload: too few pairs, or the same
# point three times, are refused then, not by the run
printf '0.5,0.5\n' >"$WORK/lm_one.csv"
refused "one landmark pair in 2D" ', "align": "rigid"' 'template_landmarks: landmarks: 1 pair(s); a 2D alignment needs at least 2' \
    -F "template_landmarks=@$WORK/lm_one.csv" -F "target_landmarks=@$WORK/lm_one.csv"
refused "coincident landmarks" ', "align": "rigid"' 'template_landmarks: ' \
    -F "template_landmarks=@$WORK/lm_same.csv" -F "target_landmarks=@$LMG"
python3 -c 'import sys; sys.stdout.write("0.5,0.5\n" * 150000)' >"$WORK/lm_huge.csv" # 1.2 MB
refused "a landmark part over 1 MiB" ', "align": "rigid"' 'template_landmarks: larger than 1048576 bytes' \
    -F "template_landmarks=@$WORK/lm_huge.csv" -F "target_landmarks=@$LMG"
gzip -c "$LMG" >"$WORK/lm_target.csv.gz"
refused "a gzip-compressed landmark part" ', "align": "rigid"' 'target_landmarks: a landmark CSV is sent as plain text' \
    -F "template_landmarks=@$LMT" -F "target_landmarks=@$WORK/lm_target.csv.gz"
