#!/usr/bin/env bash
# TAP tests of a batch's warm starts, thread policy and shared backgrounds
# (docs/populations.md, proto/job/sm_job_batch_warm.h): the 2D example's
# disk onto eight ellipses, --jobs 1 (so the starts are deterministic):
#   - warm (--warm-start 1) against cold (0): each target's two-sided RMS
#     figures (summary's distance) within 10% of the cold ones, and each
#     result's boundary as near the exact ellipse (numpy, from the
#     analytic ellipse, not the tool's figures) as the cold one within
#     10%; fewer iterations in total; the targets that started warm name
#     the target they started from, whose start was nearer than the
#     template; the warm folder gone after the batch;
#   - the same with --align similarity (each map carried to the next
#     target's frame through both alignments);
#   - cold = the separate `run`s: result.mesh and displacement.sol equal
#     byte for byte;
#   - two targets naming one background (mesh + sol) read it once, with
#     the separate run's result;
#   - --jobs beyond the cores: children x threads <= the cores.
# The core's refusal of an invalid start (an inverted element) is
# tests/unit/test_match_start.c's.
# Env: SM_BIN (directory of the built binaries), SM_ROOT (repo root).
# run.sh: seconds 20 asan 90
source "$(dirname "$0")/../lib/cli.sh"
cd "$WORK" || exit 1
PY=/usr/bin/python3
[ -x "$PY" ] || PY=python3
T=$ROOT/examples/2d/template.mesh
export T
CLAMP=(--clamp-ball 0.5,0.5,0.04)

if ! $PY -c 'import numpy' 2>/dev/null; then
    skip "batch warm starts (python3-numpy not installed)"
    echo "1..$n"
    exit 0
fi

echo "name,target_surface" >list.csv
: >axes.txt
for ab in 0.22:0.30 0.30:0.22 0.26:0.26 0.23:0.24 0.29:0.28 0.21:0.27 0.25:0.29 0.28:0.23; do
    a=${ab%:*} b=${ab#*:}
    name=e${a#0.}x${b#0.}
    $PY "$ROOT/tests/cli/batch_check.py" ellipse "$name.mesh" "$a" "$b"
    echo "$name,$name.mesh" >>list.csv
    echo "$name $a $b" >>axes.txt
done
for w in 0 1; do
    if "$BIN" batch --template "$T" --targets list.csv "${CLAMP[@]}" --jobs 1 --warm-start $w \
        --no-model -q -o "w$w" >"out$w.txt" 2>"err$w.txt"; then
        ok "batch --warm-start $w of eight ellipses exits 0"
    else
        not_ok "batch --warm-start $w of eight ellipses exits 0" "$(head -c 1500 "err$w.txt")"
    fi
done

cat >warm_check.py <<'PY'
import json, math, os, sys
import numpy as np
cold_dir, warm_dir, axes = sys.argv[1], sys.argv[2], sys.argv[3]
def medit(path):
    tok = open(path).read().split()
    i = tok.index("Vertices"); n = int(tok[i + 1])
    v = np.array(tok[i + 2:i + 2 + 3 * n], dtype=float).reshape(n, 3)[:, :2]
    i = tok.index("Edges"); m = int(tok[i + 1])
    e = np.array(tok[i + 2:i + 2 + 3 * m], dtype=int).reshape(m, 3)
    return v, e
tv, te = medit(os.environ["T"])
outer = np.unique(te[te[:, 2] == 1][:, :2]) - 1   # the disk's outer circle
def exact_rms(path, a, b):
    v, _ = medit(path)
    p = v[outer] - 0.5
    t = np.linspace(0, 2 * math.pi, 200000, endpoint=False)
    e = np.stack([a * np.cos(t), b * np.sin(t)], 1)
    d = [np.sqrt(((e - q) ** 2).sum(1)).min() for q in p]   # brute force
    return float(np.sqrt(np.mean(np.square(d))))
sw = json.load(open(warm_dir + "/summary.json"))
assert sw["warm_start"] is True and sw["jobs"] == 1, sw
assert not os.path.exists(warm_dir + "/.warm"), "the warm folder was left"
it = {"cold": 0, "warm": 0}
started = 0
for line in open(axes):
    name, a, b = line.split()
    c = json.load(open("%s/targets/%s/summary.json" % (cold_dir, name)))
    w = json.load(open("%s/targets/%s/summary.json" % (warm_dir, name)))
    assert c["status"] == "finished" and w["status"] == "finished", (name, c["status"], w["status"])
    it["cold"] += c["iterations"]; it["warm"] += w["iterations"]
    for side in ("result_to_target", "target_to_result"):
        rc, rw = c["distance"][side]["rms"], w["distance"][side]["rms"]
        assert rw <= 1.1 * rc, "%s %s: warm %.4g against cold %.4g" % (name, side, rw, rc)
    ec = exact_rms("%s/targets/%s/result.mesh" % (cold_dir, name), float(a), float(b))
    ew = exact_rms("%s/targets/%s/result.mesh" % (warm_dir, name), float(a), float(b))
    assert ew <= 1.1 * ec, "%s: exact distance warm %.4g against cold %.4g" % (name, ew, ec)
    row = [t for t in sw["targets"] if t["name"] == name][0]
    st = row["start"]
    if st["from"]:
        started += 1
        assert st["from"] != name and os.path.isdir("%s/targets/%s" % (warm_dir, st["from"]))
        assert st["start_distance"] < st["template_distance"], st
    else:
        assert st["start_distance"] == st["template_distance"], st
assert started >= 2, "only %d targets started warm" % started
assert it["warm"] < it["cold"], it
print("iterations warm %d, cold %d; %d started warm" % (it["warm"], it["cold"], started))
PY
if out=$($PY warm_check.py w0 w1 axes.txt 2>&1); then
    ok "warm starts: two-sided figures and exact distances within 10% of cold, fewer iterations ($out)"
else
    not_ok "warm starts: two-sided figures and exact distances within 10% of cold, fewer iterations" "$out"
fi

# with an alignment: each map carried through both targets' transforms
for w in 0 1; do
    "$BIN" batch --template "$T" --targets list.csv "${CLAMP[@]}" --align similarity --jobs 1 \
        --warm-start $w --no-model -q -o "a$w" >/dev/null 2>"aerr$w.txt" ||
        echo "batch --align similarity --warm-start $w failed" >>"aerr$w.txt"
done
if out=$($PY warm_check.py a0 a1 axes.txt 2>&1); then
    ok "--align similarity: warm starts carried through the alignments, within 10% of cold, fewer iterations ($out)"
else
    not_ok "--align similarity: warm starts within 10% of cold, fewer iterations" \
        "$out $(cat aerr0.txt aerr1.txt)"
fi

# cold = separate runs, byte for byte
same=yes
while IFS=, read -r name surf; do
    [ "$name" = name ] && continue
    "$BIN" run --template "$T" --target-surface "$surf" "${CLAMP[@]}" -q -o "sep/$name" \
        >/dev/null 2>&1 || same="no ($name: run failed)"
    for f in result.mesh displacement.sol; do
        cmp -s "sep/$name/$f" "w0/targets/$name/$f" || same="no ($name/$f)"
    done
done <list.csv
check "--warm-start 0: every result.mesh and displacement.sol equal the separate runs'" \
    test "$same" = yes

# one background named by two targets: read once, the separate run's answer
BG=$ROOT/examples/2d/background.mesh.gz
SOL=$ROOT/examples/2d/background.sol.gz
printf 'name,target_mesh,target_sol\nb1,%s,%s\nb2,%s,%s\n' "$BG" "$SOL" "$BG" "$SOL" >bg.csv
"$BIN" batch --template "$T" --targets bg.csv "${CLAMP[@]}" --max-iter 20 --jobs 1 --no-model \
    -q -o bgb >/dev/null 2>bgerr.txt
"$BIN" run --template "$T" --target-mesh "$BG" --target-sol "$SOL" "${CLAMP[@]}" --max-iter 20 \
    -q -o bgrun >/dev/null 2>&1
if $PY -c 'import json,sys; s=json.load(open("bgb/summary.json")); sys.exit(s["shared_backgrounds"] != 1 or s["targets_ok"] != 2)' &&
    cmp -s bgrun/result.mesh bgb/targets/b1/result.mesh &&
    cmp -s bgrun/result.mesh bgb/targets/b2/result.mesh; then
    ok "two targets on one background: read once, results equal the separate run's"
else
    not_ok "two targets on one background: read once, results equal the separate run's" \
        "$(cat bgerr.txt; head -c 600 bgb/summary.json 2>/dev/null)"
fi

# --jobs beyond the cores: capped, children x threads <= cores
cores=$(nproc)
"$BIN" batch --template "$T" --targets list.csv "${CLAMP[@]}" --max-iter 3 --jobs 64 --no-model \
    -q -o many >/dev/null 2>&1
if $PY - "$cores" <<'PY'; then
import json, sys
s = json.load(open("many/summary.json"))
cores = int(sys.argv[1])
assert s["cores"] == cores and 1 <= s["jobs"] <= cores, s
assert s["jobs"] * s["threads_per_target"] <= cores, s
PY
    ok "--jobs 64 on $cores cores: children x threads <= cores"
else
    not_ok "--jobs 64 on $cores cores: children x threads <= cores" "$(head -c 600 many/summary.json)"
fi
echo "1..$n"
