#!/usr/bin/env bash
# TAP tests of `shapematch batch` (docs/populations.md): the 2D example's
# disk template matched onto a family of ellipses of semi-axes (a, b) made
# here; the shape model checked against numpy (tests/cli/batch_check.py:
# its own Procrustes, PCA and leave-one-out) and against the generating
# parameters (two modes carry >= 95% of the variance, the scores predict a
# and b linearly); a rigidly moved result changes nothing after rigid
# Procrustes; the template set up once; results identical to separate
# `run`s and whatever --jobs; a failing target reported and left out; bad
# LIST.csv lines rejected with their line numbers.
# Env: SM_BIN (directory of the built binaries), SM_ROOT (repo root).
source "$(dirname "$0")/../lib/cli.sh"
cd "$WORK" || exit 1
# Debian's python3, where python3-numpy is installed (a python3 earlier on
# the PATH may lack it)
PY=/usr/bin/python3
[ -x "$PY" ] || PY=python3
CHECK="$PY $ROOT/tests/cli/batch_check.py"
T=$ROOT/examples/2d/template.mesh
CLAMP=(--clamp-ball 0.5,0.5,0.04)

if ! $PY -c 'import numpy' 2>/dev/null; then
    skip "shapematch batch (python3-numpy not installed)"
    echo "1..$n"
    exit 0
fi

# ---- help ----
if "$BIN" batch --help >out.txt 2>&1 && grep -q -- '--model-align' out.txt &&
    grep -q -- '--targets LIST.csv' out.txt; then
    ok "batch --help lists its options"
else
    not_ok "batch --help lists its options" "$(head -c 400 out.txt)"
fi

# ---- the family: six ellipses, (a, b) spread over [0.21, 0.31]^2 ----
params=""
echo "name,target_surface" >list.csv
for ab in 0.22:0.30 0.30:0.22 0.26:0.26 0.23:0.24 0.29:0.28 0.21:0.27; do
    a=${ab%:*} b=${ab#*:}
    name=e${a#0.}x${b#0.}
    $CHECK ellipse "$name.mesh" "$a" "$b"
    echo "$name,$name.mesh" >>list.csv
    params="${params:+$params,}$name:$a:$b"
done
if "$BIN" batch --template "$T" --targets list.csv "${CLAMP[@]}" --jobs 2 -q -o b1 \
    >out.txt 2>err.txt; then
    ok "a batch of six ellipses exits 0"
else
    not_ok "a batch of six ellipses exits 0" "$(head -c 1500 err.txt)"
fi
if out=$($CHECK model b1 "$params" 2>&1); then
    ok "the model equals numpy's (Procrustes, PCA, leave-one-out); two modes >= 95%, scores predict (a, b)"
else
    not_ok "the model equals numpy's; two modes >= 95%, scores predict (a, b)" "$out"
fi
if $PY - b1 <<'PY'; then
import json, sys
s = json.load(open(sys.argv[1] + "/summary.json"))
m = json.load(open(sys.argv[1] + "/model/summary.json"))
assert s["template_setup"]["count"] == 1, s["template_setup"]
assert s["targets_ok"] == 6 and s["failed"] == [] and s["model"] == "model", s
assert all(t["status"] == "finished" for t in s["targets"]), s["targets"]
assert m["members"] == 6 and len(m["variance_explained"]) == m["modes"] <= 5, m
assert all(x >= y for x, y in zip(m["variance_explained"], m["variance_explained"][1:]))
assert len(m["specificity"]) == m["evaluation"]["modes"] and min(m["specificity"]) > 0
PY
    ok "summary: the template set up once, six targets, the model's curves"
else
    not_ok "summary: the template set up once, six targets, the model's curves"
fi

# the leave-one-out eigenproblems (secular equation and dense fallback) on
# random and degenerate shapes, through this variant's libshapematch.so
LIB=$(dirname "$BIN")/libshapematch.so
pre=()
if ldd "$LIB" 2>/dev/null | grep -q libasan; then
    pre=(env LD_PRELOAD="$(gcc -print-file-name=libasan.so) $(gcc -print-file-name=libubsan.so)"
        ASAN_OPTIONS=detect_leaks=0:halt_on_error=1)
fi
if out=$("${pre[@]}" $CHECK loo "$LIB" 2>&1); then
    ok "leave-one-out generalization equals numpy's on random, duplicate, collinear and tied shapes"
else
    not_ok "leave-one-out generalization equals numpy's on random, duplicate, collinear and tied shapes" "$out"
fi

# ---- identical to separate runs, and whatever --jobs ----
same=1
for name in e22x30 e26x26; do
    "$BIN" run --template "$T" --target-surface "$name.mesh" "${CLAMP[@]}" -q -o "r-$name" \
        >/dev/null 2>&1 || same=0
    for f in result.mesh displacement.sol; do
        cmp -s "r-$name/$f" "b1/targets/$name/$f" || same=0
    done
done
[ $same = 1 ] && ok "result.mesh and displacement.sol identical to separate runs" ||
    not_ok "result.mesh and displacement.sol identical to separate runs"
"$BIN" batch --template "$T" --target-surface e23x24.mesh --target-surface e29x28.mesh \
    --target-surface e21x27.mesh "${CLAMP[@]}" --jobs 1 --no-model -q -o b2 >/dev/null 2>&1
same=1
for name in e23x24 e29x28 e21x27; do
    cmp -s "b1/targets/$name/result.mesh" "b2/targets/$name/result.mesh" || same=0
done
[ $same = 1 ] && [ ! -e b2/model ] && ok "--jobs 1 gives the results of --jobs 2; --no-model" ||
    not_ok "--jobs 1 gives the results of --jobs 2; --no-model"

# ---- a rigidly moved result: nothing changes after rigid Procrustes ----
cp -r b1 b3
$CHECK move b1/targets/e30x22/result.mesh b3/targets/e30x22/result.mesh 0.7 3.0 -2.0
if "$BIN" batch --model-from b3 -q >/dev/null 2>err.txt && out=$($CHECK same b1/model b3/model); then
    ok "a rigidly moved result leaves variances and scores unchanged (rigid)"
else
    not_ok "a rigidly moved result leaves variances and scores unchanged (rigid)" "$out" \
        "$(cat err.txt)"
fi
"$BIN" batch --model-from b3 --model-align none -q >/dev/null 2>&1
$CHECK same b1/model b3/model >diff.txt 2>&1
if grep -q 'differ' diff.txt; then
    ok "without alignment the moved result changes the model"
else
    not_ok "without alignment the moved result changes the model"
fi

# ---- a failing target: reported, left out of the model ----
printf 'not a mesh\n' >broken.mesh
"$BIN" batch --template "$T" --target-surface e22x30.mesh --target-surface broken.mesh \
    --target-surface e26x26.mesh --target-surface e30x22.mesh "${CLAMP[@]}" -q -o b4 \
    >out.txt 2>err.txt
rc=$?
if [ $rc = 11 ] && grep -q 'broken: failed' err.txt && $PY - b4 <<'PY'; then
import json, sys
s = json.load(open(sys.argv[1] + "/summary.json"))
m = json.load(open(sys.argv[1] + "/model/summary.json"))
assert s["failed"] == ["broken"] and s["targets_ok"] == 3, s
bad = [t for t in s["targets"] if t["name"] == "broken"][0]
assert bad["status"] == "failed" and bad["exit_code"] == 2 and "broken.mesh" in bad["message"], bad
assert m["targets"] == ["e22x30", "e26x26", "e30x22"], m["targets"]
PY
    ok "a failing target exits 11, is reported and left out of the model"
else
    not_ok "a failing target exits 11, is reported and left out of the model" "exit $rc" \
        "$(head -c 1500 err.txt)"
fi

# ---- SIGINT: the running targets stop and write their state, no new one
# starts, no model, exit 5 (job control on, so the background job does not
# start with SIGINT ignored) ----
set -m
env --default-signal=INT "$BIN" batch --template "$T" --target-surface e22x30.mesh \
    --target-surface e30x22.mesh --target-surface e26x26.mesh --target-surface e23x24.mesh \
    "${CLAMP[@]}" --jobs 2 --max-iter 100000000 --tol-stall 0 --tol-step 1e-15 \
    --tol-boundary 0 --save-every 1 -q -o b6 >/dev/null 2>err.txt &
pid=$!
set +m
for _ in $(seq 1 400); do # both running targets into their runs (a snapshot)
    [ "$(ls b6/targets/*/iter-00001.mesh 2>/dev/null | wc -l)" -ge 2 ] && break
    kill -0 "$pid" 2>/dev/null || break
    sleep 0.05
done
kill -INT "$pid" 2>/dev/null
(
    for _ in $(seq 1 600); do
        kill -0 "$pid" 2>/dev/null || exit 0
        sleep 0.05
    done
    kill -KILL "$pid" 2>/dev/null
) >/dev/null 2>&1 &
wait "$pid"
rc=$?
if [ $rc = 5 ] && $PY - b6 <<'PY'; then
import json, os, sys
s = json.load(open(sys.argv[1] + "/summary.json"))
st = {t["name"]: t["status"] for t in s["targets"]}
assert s["cancelled"] is True and s["model"] is None, s
assert list(st.values()).count("cancelled") == 2 and list(st.values()).count("not_run") == 2, st
for name, status in st.items():
    if status == "cancelled":
        assert os.path.exists("%s/targets/%s/result.mesh" % (sys.argv[1], name)), name
PY
    ok "SIGINT: the two running targets cancelled with their state written, two not run, exit 5"
else
    not_ok "SIGINT: the two running targets cancelled with their state written, two not run, exit 5" \
        "exit $rc" "$(head -c 1500 err.txt)"
fi

# ---- LIST.csv errors name their line ----
printf 'name,target_surface\n# a comment\na,e22x30.mesh\nb,e26x26.mesh,extra\n' >bad1.csv
printf 'target_surface,colour\n' >bad2.csv
printf 'target_mesh,target_sol\nb.mesh,\n' >bad3.csv
for case in "bad1.csv:line 4: 3 fields" "bad2.csv:line 1: unknown column 'colour'" \
    "bad3.csv:line 2: a target needs"; do
    f=${case%%:*} msg=${case#*:}
    "$BIN" batch --template "$T" --targets "$f" "${CLAMP[@]}" -o bx >out.txt 2>err.txt
    rc=$?
    if [ $rc = 2 ] && grep -qF "$msg" err.txt && [ ! -e bx ]; then
        ok "LIST.csv $f rejected: $msg"
    else
        not_ok "LIST.csv $f rejected: $msg" "exit $rc" "$(cat err.txt)"
    fi
done
# unique names: the same stem twice
"$BIN" batch --template "$T" --target-surface e22x30.mesh --target-surface ./e22x30.mesh \
    "${CLAMP[@]}" --no-model -q -o b5 >/dev/null 2>&1
[ -f b5/targets/e22x30/result.mesh ] && [ -f b5/targets/e22x30-2/result.mesh ] &&
    ok "the same stem twice: NAME and NAME-2" || not_ok "the same stem twice: NAME and NAME-2"

# several files after one option (a shell glob), as after repeated options
"$BIN" batch --template "$T" --target-surface e22x30.mesh e26x26.mesh "${CLAMP[@]}" --no-model \
    --jobs 1 -q -o b6 >/dev/null 2>b6.err
[ -f b6/targets/e22x30/result.mesh ] && [ -f b6/targets/e26x26/result.mesh ] &&
    ok "--target-surface A B: two targets (a shell glob)" ||
    not_ok "--target-surface A B: two targets (a shell glob)" "$(cat b6.err)"
# a stray word elsewhere names batch, not run
"$BIN" batch --template "$T" "${CLAMP[@]}" stray --target-surface e22x30.mesh -o b7 \
    >/dev/null 2>b7.err
rc=$?
[ $rc = 1 ] && grep -q "unexpected argument 'stray' (batch takes options only)" b7.err &&
    ok "a stray argument: usage error naming batch" ||
    not_ok "a stray argument: usage error naming batch" "exit $rc" "$(cat b7.err)"

echo "1..$n"
[ "$failed" -eq 0 ]
