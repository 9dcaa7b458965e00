#!/usr/bin/env bash
# One job runner, one answer (issue 7): the same job run by `shapematch
# run`, by the daemon's worker, and downloaded with `shapematch fetch`
# gives the same summary.json, key by key:
#   - the same members at every level, except that the daemon's document
#     (GET /results, what fetch writes) may add jobID and links;
#   - the same values, except the members that legitimately differ, whose
#     presence only is compared: timings.* (wall times) and inputs.* (the
#     user's paths for run, the job folder's for the daemon);
#   - field_builds is 1 in each (the target field is built once per job).
# outputs lists what each wrote: run's (--format of all six mesh and
# displacement formats) is the worker's and fetch's minus history.json,
# which only the daemon's worker writes: compared as a subset, file by file.
# `run --format F` and `fetch --format F` write the same files, byte for
# byte, for each of the six formats.
# And a job with no valid step from the initial mesh (tol_step 0.5) is a
# failure for both: `run` exits 3 with status "failed" in its summary, the
# daemon's job ends "failed" with the same reason (it used to be
# "successful": step_tolerance after 0 iterations).
source "$(dirname "$0")/lib.sh"

if ! make_case; then
    not_ok "gmsh builds the test meshes" "$(tail -5 "$WORK/case/gmsh.log")"
    exit 1
fi
if ! start_daemon same --workers 1 --worker-threads 1; then
    not_ok "the daemon starts"
    exit 1
fi
ok "the daemon starts"

PARAMS="$BALL_PARAMS, \"max_iter\": 25, \"save_every\": 10}"
ID=$(submit "$DISK" "$BOX" "$BOXSOL" "$PARAMS")
if [ -n "$ID" ] && wait_final "$ID" 120 && state_is "$ID" successful; then
    ok "the job runs on the daemon (successful)"
else
    not_ok "the job runs on the daemon" "id '$ID', state $(job_state "$ID")" "$(cat "$WORK/submit.out")"
    exit 1
fi

# the same job locally, one numerical thread as the worker
FORMATS=mesh,meshb,vtu,binary,sol,solb
OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 \
    "$BIN/shapematch" run --template "$DISK" --target-mesh "$BOX" --target-sol "$BOXSOL" \
    --clamp-ball 0,0,0.1 --max-iter 25 --save-every 10 --format "$FORMATS" --quiet -o "$WORK/run" \
    >"$WORK/run.out" 2>"$WORK/run.err"
rc=$?
[ "$rc" = 0 ] && ok "shapematch run exits 0" || not_ok "shapematch run exits 0" "exit $rc" "$(cat "$WORK/run.err")"

"$BIN/shapematch" fetch --server "$BASE" --quiet --format "$FORMATS" -o "$WORK/fetched" "$ID" >"$WORK/fetch.out" 2>"$WORK/fetch.err"
rc=$?
[ "$rc" = 0 ] && ok "shapematch fetch exits 0" || not_ok "shapematch fetch exits 0" "exit $rc" "$(cat "$WORK/fetch.err")"

WORKER_SUMMARY=$SPOOL/jobs/$ID/results/summary.json
[ -f "$WORKER_SUMMARY" ] && ok "the worker wrote results/summary.json" ||
    not_ok "the worker wrote results/summary.json" "$(ls -R "$SPOOL/jobs/$ID" 2>&1 | head -20)"

# compare A B LABEL: prints the differences (empty: the same document)
cat >"$WORK/compare.py" <<'PY'
import json, sys
PRESENCE_ONLY = {"timings", "inputs"}   # members whose children may differ in value
DAEMON_EXTRA = {"jobID", "links"}       # the daemon's additions at the top level
SUBSET = {"outputs"}                    # a's files are among b's (run writes no history.json)
a = json.load(open(sys.argv[1], encoding="utf-8"))
b = json.load(open(sys.argv[2], encoding="utf-8"))
extra_ok = sys.argv[3] == "daemon"
diffs = []
def walk(x, y, path, presence):
    if isinstance(x, dict) and isinstance(y, dict):
        kx, ky = set(x), set(y)
        if path == "" and extra_ok:
            ky -= DAEMON_EXTRA
        for k in sorted(kx ^ ky):
            diffs.append("%s.%s only in %s" % (path, k, sys.argv[1] if k in kx else sys.argv[2]))
        for k in sorted(kx & ky):
            if path == "" and k in SUBSET:
                subset(x[k], y[k], "." + k)
                continue
            walk(x[k], y[k], path + "." + k, presence or (path == "" and k in PRESENCE_ONLY))
    elif presence:
        if type(x) != type(y) and not (isinstance(x, (int, float)) and isinstance(y, (int, float))):
            diffs.append("%s: %r vs %r (types)" % (path, x, y))
    elif x != y:
        diffs.append("%s: %r vs %r" % (path, x, y))
def subset(x, y, path):
    for kind, files in x.items():
        other = y.get(kind)
        if isinstance(files, dict) and isinstance(other, dict):
            for fmt, name in files.items():
                if other.get(fmt) != name:
                    diffs.append("%s.%s.%s: %r vs %r" % (path, kind, fmt, name, other.get(fmt)))
        elif files != other:
            diffs.append("%s.%s: %r vs %r" % (path, kind, files, other))
    if sorted(x.get("history", {})) != ["csv"]:
        diffs.append("%s.history: %r, expected csv only" % (path, x.get("history")))
walk(a, b, "", False)
for d in (a, b):
    if d.get("field_builds") != 1:
        diffs.append("field_builds is %r, not 1" % d.get("field_builds"))
if not a.get("timings") or not a.get("inputs"):
    diffs.append("timings or inputs missing")
print("\n".join(diffs))
PY
if [ -f "$WORK/run/summary.json" ] && [ -f "$WORKER_SUMMARY" ]; then
    d=$(python3 "$WORK/compare.py" "$WORK/run/summary.json" "$WORKER_SUMMARY" worker 2>&1)
    [ -z "$d" ] && ok "run's summary.json and the worker's are the same document (timings, inputs: keys only)" ||
        not_ok "run's summary.json and the worker's are the same document" "$d"
fi
if [ -f "$WORK/run/summary.json" ] && [ -f "$WORK/fetched/summary.json" ]; then
    d=$(python3 "$WORK/compare.py" "$WORK/run/summary.json" "$WORK/fetched/summary.json" daemon 2>&1)
    [ -z "$d" ] && ok "run's summary.json and fetch's are the same document (plus jobID and links)" ||
        not_ok "run's summary.json and fetch's are the same document" "$d"
    if [ "$(jq -r .jobID "$WORK/fetched/summary.json")" = "$ID" ] &&
        [ "$(jq -r '.links | length > 0' "$WORK/fetched/summary.json")" = true ]; then
        ok "fetch's summary carries jobID and links"
    else
        not_ok "fetch's summary carries jobID and links" "$(head -c 400 "$WORK/fetched/summary.json")"
    fi
fi
# the same result set: every file of the worker's results/ is in run's
# output folder (run also holds its snapshots next to them)
missing=""
for f in $(cd "$SPOOL/jobs/$ID/results" && ls); do
    [ "$f" = snapshots ] && continue
    [ "$f" = history.json ] && continue # the daemon's only
    [ -s "$WORK/run/$f" ] || missing="$missing $f"
done
for f in result.mesh result.meshb result.vtu result.smmesh displacement.sol displacement.solb \
    history.csv; do
    [ -s "$SPOOL/jobs/$ID/results/$f" ] || missing="$missing worker:$f"
    [ "$f" = history.csv ] || [ "$f" = history.json ] || cmp -s "$WORK/run/$f" "$SPOOL/jobs/$ID/results/$f" ||
        missing="$missing differs:$f"
done
[ -z "$missing" ] && ok "run and the worker write the same result set, the results byte for byte" ||
    not_ok "run and the worker write the same result set" "$missing"

# run --format and fetch --format: the same files, byte for byte
differs=""
for f in result.mesh result.meshb result.vtu result.smmesh displacement.sol displacement.solb; do
    cmp -s "$WORK/run/$f" "$WORK/fetched/$f" || differs="$differs $f"
done
[ -z "$differs" ] && ok "run --format $FORMATS and fetch --format $FORMATS: the same six files, byte for byte" ||
    not_ok "run and fetch --format write the same files" "differ or missing:$differs"

# ---- no valid step from the initial mesh: failed for both ----
STUCK="$BALL_PARAMS, \"tol_step\": 0.5}"
"$BIN/shapematch" run --template "$DISK" --target-mesh "$BOX" --target-sol "$BOXSOL" \
    --clamp-ball 0,0,0.1 --tol-step 0.5 --quiet -o "$WORK/stuck" >/dev/null 2>"$WORK/stuck.err"
rc=$?
if [ "$rc" = 3 ] && grep -q "no valid step" "$WORK/stuck.err" &&
    [ "$(jq -r .status "$WORK/stuck/summary.json")" = failed ]; then
    ok "run: no valid step from the initial mesh exits 3, status failed"
else
    not_ok "run: no valid step exits 3" "exit $rc" "$(cat "$WORK/stuck.err")"
fi
SID=$(submit "$DISK" "$BOX" "$BOXSOL" "$STUCK")
if [ -n "$SID" ] && wait_final "$SID" 120 && state_is "$SID" failed &&
    hcurl "$BASE/v1/jobs/$SID" | jq -e '.message | test("no valid step")' >/dev/null; then
    ok "daemon: the same job is failed, with the reason"
else
    not_ok "daemon: the same job is failed" "state $(job_state "$SID")" "$(hcurl "$BASE/v1/jobs/$SID")"
fi

reports_clean && ok "no sanitizer report" || not_ok "no sanitizer report"
stop_daemon
echo "1..$n"
