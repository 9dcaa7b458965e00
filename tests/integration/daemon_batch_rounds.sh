#!/usr/bin/env bash
# run.sh: weight 0.25 seconds 40
# `shapematch batch --server URL --template-from mean|medoid` (client/
# cmd_batch_remote.c; docs/populations.md): the rounds of the local batch
# (proto/job/sm_job_template_from.c, one choice of the next template for
# both) with each round a daemon's batch.  On four 2D ellipses made by
# tests/cli/batch_check.py (as tests/cli/batch_rounds.sh's):
# - mean, --rounds 2: the daemon's rounds give the local run's mean (each
#   round's model/mean.mesh and the chosen template.mesh) to 1e-9 of the
#   size — the daemon's workers run the same matching on the same inputs
#   (measured: byte-identical), so any difference is a bug; summary
#   template_from (mode, rounds, movement) equal to the local one;
# - each round's batch document carries "templateFrom" (mode, round,
#   the previous round's batch id), also after a GET;
# - medoid: the same medoid as the local run; FILE: one batch, so named;
# - POST /v1/batches with a malformed template_from (unknown member,
#   wrong type, round out of range, round 2 without previous, a previous
#   that is a plain job or no batch at all, not an object): 422
#   problem+json naming it; a valid one is taken (201).
source "$(dirname "$0")/lib.sh"
PY=/usr/bin/python3
[ -x "$PY" ] || PY=python3
if ! $PY -c 'import numpy' 2>/dev/null; then
    skip "batch --server --template-from (python3-numpy not installed)"
    echo "1..$n"
    exit 0
fi
MAKE="$PY $ROOT/tests/cli/batch_check.py"
DISC=$ROOT/examples/2d/template.mesh
OPTS=(--clamp-ball 0.5,0.5,0.04 --max-iter 40)
cd "$WORK" || exit 1
targets=()
for ab in 0.22:0.30 0.30:0.23 0.24:0.27 0.28:0.25; do
    $MAKE ellipse "f${ab/:/x}.mesh" "${ab%:*}" "${ab#*:}"
    targets+=("f${ab/:/x}.mesh")
done
start_daemon rounds --workers 2 || { not_ok "daemon starts"; exit 1; }

# ---------------------------------------------------------------- mean
"$BIN/shapematch" batch --template "$DISC" --target-surface "${targets[@]}" "${OPTS[@]}" \
    --template-from mean --rounds 2 --jobs 2 -o local >local.out 2>local.log ||
    not_ok "local batch --template-from mean" "$(cat local.log)"
"$BIN/shapematch" batch --server "$BASE" --template "$DISC" --target-surface "${targets[@]}" \
    "${OPTS[@]}" --template-from mean --rounds 2 -o remote >remote.out 2>remote.log
rc=$?
if [ $rc = 0 ] && [ -f remote/model/mean.mesh ] && [ -f remote/template.mesh ] &&
    [ -f remote/rounds/1/model/mean.mesh ] && [ -f remote/rounds/2/template.mesh ]; then
    ok "batch --server --template-from mean --rounds 2: two daemon batches, the files of the local run"
else
    not_ok "batch --server --template-from mean" "rc $rc: $(tail -5 remote.log)"
fi
# the means and templates, vertex by vertex, against the local run's
if $PY - <<'PY'; then
import json, numpy as np
def coords(p):
    lines = open(p).read().split("\n")
    i = next(k for k, l in enumerate(lines) if l.strip() == "Vertices")
    n = int(lines[i + 1])
    return np.array([[float(v) for v in l.split()[:-1]] for l in lines[i + 2:i + 2 + n]])
worst = 0
for f in ("rounds/1/model/mean.mesh", "rounds/2/template.mesh", "model/mean.mesh", "template.mesh"):
    a, b = coords("local/" + f), coords("remote/" + f)
    size = np.linalg.norm(a.max(0) - a.min(0))
    worst = max(worst, np.abs(a - b).max() / size)
assert worst < 1e-9, worst
ls = json.load(open("local/summary.json"))["template_from"]
rs = json.load(open("remote/batch.json"))["template_from"]
rm = json.load(open("remote/model/summary.json"))["template_from"]
assert rs == rm, (rs, rm)
for k in ("mode", "rounds", "max_rounds", "tolerance", "stop", "template"):
    assert ls[k] == rs[k], (k, ls[k], rs[k])
assert rs["mode"] == "mean" and rs["rounds"] == 2 and len(rs["movement"]) == 1, rs
assert abs(ls["movement"][0] - rs["movement"][0]) <= 1e-9, (ls["movement"], rs["movement"])
print("# largest vertex difference local/daemon: %.3g of the size" % worst)
PY
    ok "the daemon's rounds give the local means and templates (< 1e-9 of the size) and template_from"
else
    not_ok "daemon rounds = local rounds"
fi
# each round's batch says where its template came from
B1=$(jq -r '.batchID // empty' remote/rounds/1/batch.json 2>/dev/null)
B2=$(jq -r '.batchID // empty' remote/batch.json 2>/dev/null)
if [ -n "$B1" ] && [ -n "$B2" ] &&
    hcurl "$BASE/v1/batches/$B1" | jq -e '.templateFrom == {mode: "mean", round: 1}' >/dev/null &&
    hcurl "$BASE/v1/batches/$B2" | jq -e --arg p "$B1" \
        '.templateFrom == {mode: "mean", round: 2, previous: $p}' >/dev/null &&
    jq -e --arg p "$B1" '.templateFrom.previous == $p' remote/batch.json >/dev/null; then
    ok "GET /v1/batches/{id}: templateFrom round 1, round 2 naming round 1's batch"
else
    not_ok "batch documents carry templateFrom" "$B1 $B2 $(hcurl "$BASE/v1/batches/$B2" | head -c 600)"
fi

# -------------------------------------------------------------- medoid
"$BIN/shapematch" batch --template "$DISC" --target-surface "${targets[@]}" "${OPTS[@]}" \
    --template-from medoid --jobs 2 -q -o local-med 2>local-med.log
"$BIN/shapematch" batch --server "$BASE" --template "$DISC" --target-surface "${targets[@]}" \
    "${OPTS[@]}" --template-from medoid -q -o remote-med 2>remote-med.log
rc=$?
lm=$(jq -r '.template_from.medoid // empty' local-med/summary.json 2>/dev/null)
rm_=$(jq -r '.template_from.medoid // empty' remote-med/batch.json 2>/dev/null)
if [ $rc = 0 ] && [ -n "$lm" ] && [ "$lm" = "$rm_" ] &&
    cmp -s remote-med/template.mesh remote-med/rounds/1/targets/"$rm_"/result.mesh; then
    ok "medoid on the daemon: $rm_, as locally; round 2 on its result mesh"
else
    not_ok "medoid on the daemon" "rc $rc local '$lm' remote '$rm_' $(tail -3 remote-med.log)"
fi

# ---------------------------------------------------------------- FILE
"$BIN/shapematch" batch --server "$BASE" --template-from "$DISC" --target-surface \
    "${targets[@]:0:2}" "${OPTS[@]}" -q -o remote-file 2>remote-file.log
rc=$?
BF=$(jq -r '.batchID // empty' remote-file/batch.json 2>/dev/null)
if [ $rc = 0 ] && [ -n "$BF" ] &&
    jq -e '.template_from.mode == "file" and .template_from.rounds == 1' remote-file/batch.json \
        remote-file/model/summary.json >/dev/null &&
    hcurl "$BASE/v1/batches/$BF" | jq -e '.templateFrom == {mode: "file", round: 1}' >/dev/null &&
    [ ! -e remote-file/rounds ]; then
    ok "--template-from FILE on the daemon: one batch, template_from file in batch.json, model and document"
else
    not_ok "--template-from FILE on the daemon" "rc $rc $(tail -3 remote-file.log)"
fi

# ------------------------------------------- malformed template_from
id=$(jq -r '.targets[0].jobID' remote/batch.json)
post() { # TEMPLATE_FROM: prints the HTTP code, the reply in post.out
    hcurl -o post.out -w '%{http_code}' -H 'Content-Type: application/json' --data-binary \
        "{\"targets\": [{\"job\": \"$id\", \"name\": \"x\"}], \"template_from\": $1}" \
        "$BASE/v1/batches"
}
bad_ok=1
for tf in '{"mode": "mean", "round": 1, "extra": 1}' '{"mode": "mean", "round": "1"}' \
    '{"mode": "mean", "round": 21}' '{"mode": "file", "round": 2, "previous": "'"$B1"'"}' \
    '{"mode": "mean", "round": 2}' '{"mode": "mean", "round": 1, "previous": "'"$B1"'"}' \
    '{"mode": "median", "round": 1}' '{"mode": "mean", "round": 2, "previous": "../x"}' \
    '{"mode": "mean", "round": 2, "previous": "'"$id"'"}' \
    '{"mode": "mean", "round": 2, "previous": "0123456789abcdef0123456789abcdef"}' \
    '"mean"' '[]'; do
    code=$(post "$tf")
    if [ "$code" != 422 ] || ! jq -e '.detail | startswith("template_from")' post.out >/dev/null; then
        bad_ok=0
        echo "# $tf: $code $(cat post.out)"
    fi
done
code=$(post '{"mode": "mean", "round": 2, "previous": "'"$B1"'"}')
if [ $bad_ok = 1 ] && [ "$code" = 201 ]; then
    ok "POST /v1/batches: a malformed template_from is refused (422, naming it); a valid one taken"
else
    not_ok "POST /v1/batches template_from validation" "valid: $code $(cat post.out)"
fi
if reports_clean; then ok "no sanitizer reports"; else not_ok "sanitizer reports"; fi
stop_daemon
echo "1..$n"
