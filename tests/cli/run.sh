#!/usr/bin/env bash
# TAP tests of the `shapematch` client, `run` command: help and version,
# usage errors (exit 1, message naming the flag), bad inputs (exit 2),
# unwritable outputs (exit 4), an end-to-end run on a case built here
# with gmsh (a disk of radius 0.5 matched onto a circle of radius 0.8
# whose signed distance is computed analytically), NDJSON events,
# snapshots, cancellation by SIGINT (exit 5), and examples/2d when present.
# Env: SM_BIN (directory of the built binaries), SM_ROOT (repo root).
source "$(dirname "$0")/../lib/cli.sh"
cd "$WORK" || exit 1

# expect CODE PATTERN DESC -- ARGS...: the binary exits with CODE and its
# stderr contains PATTERN (fixed string; empty: not checked).
expect() {
    local code=$1 pattern=$2 desc=$3
    shift 4
    "$BIN" "$@" >out.txt 2>err.txt
    local rc=$?
    if [ "$rc" -ne "$code" ]; then
        not_ok "$desc" "expected exit $code, got $rc" "stderr: $(head -c 600 err.txt)"
    elif [ -n "$pattern" ] && ! grep -qF -- "$pattern" err.txt; then
        not_ok "$desc" "stderr does not mention '$pattern'" "stderr: $(head -c 600 err.txt)"
    else
        ok "$desc"
    fi
}

# ---- help and version ----
if "$BIN" --help >out.txt 2>err.txt && grep -q 'Exit codes' out.txt &&
    grep -q '^  5 ' out.txt && grep -q 'run' out.txt; then
    ok "--help exits 0 and documents the exit codes"
else
    not_ok "--help exits 0 and documents the exit codes" "$(head -c 400 out.txt err.txt)"
fi
if "$BIN" --version >out.txt 2>err.txt && grep -qE '^shapematch [0-9]+\.[0-9]+' out.txt; then
    ok "--version exits 0 and prints the version"
else
    not_ok "--version exits 0 and prints the version" "$(cat out.txt err.txt)"
fi
if "$BIN" run --help >out.txt 2>err.txt && grep -q -- '--clamp-ball' out.txt &&
    grep -q -- '--refactor-every' out.txt && grep -q 'Exit codes' out.txt; then
    ok "run --help exits 0 and lists the options"
else
    not_ok "run --help exits 0 and lists the options" "$(head -c 400 out.txt err.txt)"
fi
expect 1 "" "no command is a usage error" --
expect 1 "frobnicate" "unknown command is a usage error" -- frobnicate

# ---- test case: gmsh disk template, box background, analytic distance ----
have_case=1
cp "$ROOT"/tests/lib/case/{disk,box,cube}.geo .
cp "$ROOT/tests/lib/case/sphere_sdf.awk" sdf.awk
if ! command -v gmsh >/dev/null; then
    have_case=0
    not_ok "gmsh is installed (needed to build the test meshes)"
elif { gmsh -2 disk.geo -format mesh -o disk.mesh -v 0 >gmsh1.log 2>&1 &
    gmsh -2 box.geo -format mesh -o box.mesh -v 0 >gmsh2.log 2>&1 &
    gmsh -3 cube.geo -format mesh -o cube.mesh -v 0 >gmsh3.log 2>&1 &
    wait; } && [ -s disk.mesh ] && [ -s box.mesh ] && [ -s cube.mesh ] &&
    awk -v R=0.8 -f sdf.awk box.mesh >box.sol && awk -v R=0.8 -f sdf.awk cube.mesh >cube.sol; then
    ok "gmsh builds the test meshes"
else
    have_case=0
    not_ok "gmsh builds the test meshes" "$(tail -5 gmsh*.log)"
fi

IN=(--template disk.mesh --target-mesh box.mesh --target-sol box.sol)

# ---- usage errors: exit 1, message naming the flag ----
expect 1 "--template" "missing --template" -- run --target-mesh box.mesh --target-sol box.sol --no-clamp -o o
expect 1 "--target-sol" "missing --target-sol" -- run --template disk.mesh --target-mesh box.mesh --no-clamp -o o
expect 1 "--output" "missing -o" -- run "${IN[@]}" --no-clamp
expect 1 "--no-clamp" "two clamp options" -- run "${IN[@]}" --clamp-ball 0,0,0.1 --no-clamp -o o
expect 1 "--clamp-elements" "the same clamp option twice" -- run "${IN[@]}" --clamp-elements 1 --clamp-elements 2 -o o
expect 1 "--young" "bad number '1e'" -- run "${IN[@]}" --no-clamp --young 1e -o o
expect 1 "--tol-step" "non-finite number" -- run "${IN[@]}" --no-clamp --tol-step inf -o o
expect 1 "--poisson" "number out of range" -- run "${IN[@]}" --no-clamp --poisson 0.5 -o o
expect 1 "--max-iter" "integer expected" -- run "${IN[@]}" --no-clamp --max-iter 10.5 -o o
expect 1 "--young" "option missing its value" -- run "${IN[@]}" --no-clamp -o o --young
expect 1 "--alpha" "--alpha without --no-clamp" -- run "${IN[@]}" --clamp-ball 0,0,0.1 --alpha 0.1 -o o
expect 1 "'obj' is not an output format" "--format with a bad name" -- run "${IN[@]}" --no-clamp --format mesh,obj -o o
expect 1 "--format" "--format gz alone" -- run "${IN[@]}" --no-clamp --format gz -o o
expect 1 "--frobnicate" "unknown option" -- run "${IN[@]}" --no-clamp --frobnicate 3 -o o
expect 1 "--clamp-elements" "malformed reference list" -- run "${IN[@]}" --clamp-elements 1,,2 -o o
expect 1 "--step-initial" "--step-initial above --step-max" -- run "${IN[@]}" --no-clamp --step-initial 0.5 --step-max 0.2 -o o

if [ "$have_case" = 1 ]; then
    expect 1 "--clamp-ball" "3D ball for a 2D template" -- run "${IN[@]}" --clamp-ball 0,0,0,0.1 -o o
    expect 1 "--clamp-ball" "clamp ball holding no vertex" -- run "${IN[@]}" --clamp-ball 5,5,0.1 -o o
    expect 1 "rotations" "a clamp of one vertex leaves rotations free (3D)" -- \
        run --template cube.mesh --target-mesh cube.mesh --target-sol cube.sol --clamp-ball 1,1,1,0.01 -o o
    [ ! -e o ] && ok "usage errors create no output directory" || not_ok "usage errors create no output directory"

    # ---- bad inputs: exit 2, message naming the file ----
    expect 2 "nothere.mesh" "missing template file" -- run --template nothere.mesh --target-mesh box.mesh --target-sol box.sol --no-clamp -o o
    expect 2 "nothere.sol" "missing distance file" -- run --template disk.mesh --target-mesh box.mesh --target-sol nothere.sol --no-clamp -o o
    printf 'MeshVersionFormatted 2\nDimension 2\nVertices\n3\n0 0 0\n1 0 0\n' >truncated.mesh
    expect 2 "truncated.mesh" "malformed template" -- run --template truncated.mesh --target-mesh box.mesh --target-sol box.sol --no-clamp -o o
    printf 'MeshVersionFormatted 2\nDimension 2\nSolAtVertices\n1126\n1 1\n0.5 zero\n' >garbage.sol
    expect 2 "garbage.sol" "malformed distance file" -- run --template disk.mesh --target-mesh box.mesh --target-sol garbage.sol --no-clamp -o o
    expect 2 "dimension" "2D template with a 3D background" -- run --template disk.mesh --target-mesh cube.mesh --target-sol cube.sol --no-clamp -o o
    expect 2 "box.mesh" "distance size differs from the background vertices" -- run --template disk.mesh --target-mesh box.mesh --target-sol cube.sol --no-clamp -o o

    printf 'MeshVersionFormatted 2\nDimension 2\nSolAtVertices\n2\n1 2\n0 0\n1 1\nEnd\n' >vector.sol
    expect 2 "scalar" "vector field given as the distance" -- run --template disk.mesh --target-mesh box.mesh --target-sol vector.sol --no-clamp --json -o o
    cp out.txt failed.out # with --json: a "failed" event on stdout (checked below)

    # ---- outputs that cannot be written: exit 4 ----
    : >plainfile
    expect 4 "plainfile" "output directory is a regular file" -- run "${IN[@]}" --no-clamp -o plainfile

    # ---- end-to-end run ----
    "$BIN" run "${IN[@]}" --clamp-ball 0,0,0.1 --max-iter 30 --save-every 10 -o out/nested >e2e.out 2>e2e.err
    rc=$?
    [ "$rc" -eq 0 ] && ok "end-to-end run exits 0" || not_ok "end-to-end run exits 0" "exit $rc" "$(tail -5 e2e.err)"
    # the default --format mesh,vtu,sol, plus history.csv and summary.json
    got=$(cd out/nested 2>/dev/null && ls -d result.* displacement.* history.* summary.json 2>/dev/null | tr '\n' ' ')
    want="displacement.sol history.csv result.mesh result.vtu summary.json "
    [ "$got" = "$want" ] && ok "the default outputs exist, and only they (nested directory created)" ||
        not_ok "the default outputs exist, and only they (nested directory created)" "got: $got" "want: $want"
    leftovers=$(find out/nested -name '.*' | head -3)
    [ -z "$leftovers" ] && ok "no temporary file left behind" || not_ok "no temporary file left behind" "$leftovers"
    snaps=$(cd out/nested && ls iter-*.mesh 2>/dev/null | tr '\n' ' ')
    [ "$snaps" = "iter-00000.mesh iter-00010.mesh iter-00020.mesh iter-00030.mesh " ] &&
        ok "--save-every 10 writes the first state and iterations 10, 20, 30" ||
        not_ok "--save-every 10 writes the first state and iterations 10, 20, 30" "got: $snaps"
    # not a TTY: a plain line every 10 iterations, then the final summary
    plines=$(grep -cE '^iter (0|10|20|30) ' e2e.err)
    grep -q 'max_iterations after 30 iterations' e2e.err && [ "$plines" -eq 4 ] &&
        [ "$(grep -c '^iter ' e2e.err)" -eq 4 ] &&
        ok "plain progress lines every 10 iterations and a final line" ||
        not_ok "plain progress lines every 10 iterations and a final line" "$(cat e2e.err)"
    [ ! -s e2e.out ] && ok "nothing on stdout without --json" || not_ok "nothing on stdout without --json"

    # ---- --format: each format alone, all of them, gz ----
    # two iterations do not converge: exit 10, every output written
    short=(--clamp-ball 0,0,0.1 --max-iter 2 --quiet)
    finished() { "$BIN" "$@"; local rc=$?; [ $rc = 0 ] || [ $rc = 10 ]; }
    ALL=mesh,meshb,vtu,binary,sol,solb
    finished run "${IN[@]}" "${short[@]}" --format $ALL -o fmt-all >/dev/null 2>fmt.err ||
        not_ok "run --format $ALL" "$(cat fmt.err)"
    declare -A FILE_OF=([mesh]=result.mesh [meshb]=result.meshb [vtu]=result.vtu
        [binary]=result.smmesh [sol]=displacement.sol [solb]=displacement.solb)
    bad=""
    for fmt in mesh meshb vtu binary sol solb; do
        f=${FILE_OF[$fmt]}
        finished run "${IN[@]}" "${short[@]}" --format $fmt -o "fmt-$fmt" >/dev/null 2>fmt.err ||
            bad="$bad $fmt:exit"
        got=$(cd "fmt-$fmt" && ls | tr '\n' ' ')
        want=$(printf '%s\n' "$f" history.csv summary.json | sort | tr '\n' ' ')
        [ "$got" = "$want" ] || bad="$bad $fmt:files($got)"
        cmp -s "fmt-$fmt/$f" "fmt-all/$f" || bad="$bad $fmt:bytes"
        listed=$(jq -r '[.outputs.mesh, .outputs.displacement, .outputs.history | to_entries[] |
            "\(.key)=\(.value)"] | join(" ")' "fmt-$fmt/summary.json")
        [ "$listed" = "$fmt=$f csv=history.csv" ] || bad="$bad $fmt:outputs($listed)"
    done
    [ -z "$bad" ] && ok "--format F alone writes F's file (same bytes as with all), history.csv, summary.json; outputs lists them" ||
        not_ok "--format F alone writes F's file and outputs lists it" "$bad"
    finished run "${IN[@]}" "${short[@]}" --format $ALL,gz -o fmt-gz >/dev/null 2>fmt.err ||
        not_ok "run --format $ALL,gz" "$(cat fmt.err)"
    bad=""
    for f in "${FILE_OF[@]}"; do
        if [ "$f" = result.vtu ]; then # compressed inside: never a .vtu.gz (vtu_files.sh)
            cmp -s fmt-gz/result.vtu fmt-all/result.vtu && [ ! -e fmt-gz/result.vtu.gz ] ||
                bad="$bad result.vtu:not-as-is"
            continue
        fi
        [ "$(jq -r --arg f "$f.gz" '[.outputs[] | objects | .[]] | index($f) != null' fmt-gz/summary.json)" = true ] ||
            bad="$bad $f:not-listed"
        [ -e "fmt-gz/$f" ] && bad="$bad $f:uncompressed-too"
        gzip -t "fmt-gz/$f.gz" 2>/dev/null && gzip -dc "fmt-gz/$f.gz" | cmp -s - "fmt-all/$f" || bad="$bad $f.gz"
    done
    [ -s fmt-gz/history.csv ] && [ -s fmt-gz/summary.json ] || bad="$bad history/summary"
    [ -z "$bad" ] && ok "--format ...,gz writes FILE.gz (gzip of the same bytes; result.vtu as it is), history.csv and summary.json plain" ||
        not_ok "--format ...,gz writes FILE.gz of the same bytes" "$bad"

    # ---- no step possible from the start: exit 3, outputs still written ----
    # (the first step, 1% of the diameter, is below a 50% step tolerance)
    expect 3 "no valid step" "no valid step at the start is a numerical failure" -- \
        run "${IN[@]}" --clamp-ball 0,0,0.1 --tol-step 0.5 --quiet -o outstuck
    grep -q '"status": "failed"' outstuck/summary.json 2>/dev/null &&
        ok "a failed start still writes summary.json (status failed)" ||
        not_ok "a failed start still writes summary.json (status failed)"

    # ---- file names needing JSON escaping ----
    odd=$'we"ird\\ \xe9t\xc3\xa9\t.mesh'
    cp disk.mesh "$odd"
    "$BIN" run --template "$odd" --target-mesh box.mesh --target-sol box.sol --no-clamp --max-iter 2 \
        --quiet -o outodd >/dev/null 2>odd.err
    rc_odd=$?

    # ---- --json on compressed inputs, --quiet ----
    gzip -c box.mesh >box.mesh.gz && gzip -c box.sol >box.sol.gz
    "$BIN" run --template disk.mesh --target-mesh box.mesh.gz --target-sol box.sol.gz --no-clamp \
        --max-iter 12 --quiet --json -o outjson >json.out 2>json.err
    rc_json=$?

    # ---- SIGINT: clean stop, outputs written, exit 5 ----
    # job control on, so the background job does not start with SIGINT
    # ignored (which the client would rightly respect); env restores the
    # default too when this suite itself was started with SIGINT ignored
    # (a background `make test` from a script)
    set -m
    env --default-signal=INT "$BIN" run "${IN[@]}" --clamp-ball 0,0,0.1 --max-iter 100000000 --tol-stall 0 --tol-step 1e-15 --tol-boundary 0 --json -o outcancel \
        >cancel.out 2>cancel.err &
    pid=$!
    set +m
    for _ in $(seq 1 200); do
        [ "$(wc -l <cancel.out)" -ge 3 ] && break
        sleep 0.05
    done
    kill -INT "$pid" 2>/dev/null
    # watchdog: ends by itself once the run is gone (and holds no output
    # descriptor, so it never keeps a reader of this suite waiting)
    (
        for _ in $(seq 1 600); do
            kill -0 "$pid" 2>/dev/null || exit 0
            sleep 0.05
        done
        kill -KILL "$pid" 2>/dev/null
    ) >/dev/null 2>&1 &
    wait "$pid"
    rc_cancel=$?
fi

# ---- examples/2d (skipped until the example exists) ----
EX=$ROOT/examples/2d
pick() { local f; for f in "$EX/$1" "$EX/$1.gz"; do [ -f "$f" ] && { echo "$f"; return 0; }; done; return 1; }
ex_template=""
if ex_template=$(pick template.mesh) && b=$(pick background.mesh) && s=$(pick background.sol); then
    # the clamp the example documents: examples/2d/clamp (as demo.sh
    # reads it), else the "--clamp-ball X,Y,R" hint in template.geo
    hint=$(grep -o -- '--clamp-ball [-0-9.eE+,]*' "$EX/template.geo" 2>/dev/null | head -1)
    if [ -s "$EX/clamp" ]; then
        clamp=(--clamp-ball "$(tr -d ' \n' <"$EX/clamp")")
    elif [ -n "$hint" ]; then
        clamp=(--clamp-ball "${hint#--clamp-ball }")
    else
        clamp=(--no-clamp)
    fi
    ex_start=$SECONDS
    "$BIN" run --template "$ex_template" --target-mesh "$b" --target-sol "$s" "${clamp[@]}" \
        --max-iter 500 --tol-boundary 1e-4 --quiet -o outex >ex.out 2>ex.err
    rc_ex=$?
    ex_seconds=$((SECONDS - ex_start))
else
    ex_template=""
fi

# ---- content checks, one Python pass (its start-up is the slow part):
# prints "PASS<TAB>name" or "FAIL<TAB>name<TAB>reason" per check ----
cat >verify.py <<'PY'
import csv, gzip, json, math, os, re, sys, traceback
env = os.environ
checks = []
def check(name, enabled=True):
    def deco(fn):
        if enabled:
            checks.append((name, fn))
        return fn
    return deco
def tokens(path):
    op = gzip.open if path.endswith(".gz") else open
    with op(path, "rt", encoding="latin-1") as f:
        return f.read().split()
def mesh(path):
    t = tokens(path)
    dim = int(t[t.index("Dimension") + 1])
    k = t.index("Vertices"); n = int(t[k + 1])
    v = t[k + 2:k + 2 + n * (dim + 1)]
    xy = [(float(v[i * (dim + 1)]), float(v[i * (dim + 1) + 1])) for i in range(n)]
    tri = []
    if "Triangles" in t:
        k = t.index("Triangles"); m = int(t[k + 1])
        tri = [[int(t[k + 2 + 4 * e + c]) - 1 for c in range(3)] for e in range(m)]
    return xy, tri
def sol_vectors(path):
    t = tokens(path)
    dim = int(t[t.index("Dimension") + 1])
    k = t.index("SolAtVertices"); n = int(t[k + 1])
    assert t[k + 2] == "1" and t[k + 3] == "2", "one vector field expected"
    v = t[k + 4:k + 4 + n * dim]
    return [[float(v[i * dim + c]) for c in range(dim)] for i in range(n)]
def summary(d):
    return json.load(open(os.path.join(d, "summary.json"), encoding="utf-8"))
def ndjson(path):
    return [json.loads(l) for l in open(path).read().splitlines()]
have_case = env.get("HAVE_CASE") == "1"
E2E = "out/nested"

@check("summary.json parses, stop reason allowed, figures consistent", have_case)
def _():
    s = summary(E2E)
    assert s["status"] == "finished" and s["exit_code"] == 0, s["status"]
    assert s["stop_reason"] in ("step_tolerance", "boundary_tolerance", "max_iterations"), s["stop_reason"]
    assert 1 <= s["iterations"] <= 30, s["iterations"]
    for k in ("J_initial", "J_final", "boundary_l2", "boundary_max", "min_quality", "accepted", "rejected"):
        assert isinstance(s[k], (int, float)), k
    assert s["J_final"] < s["J_initial"]
    assert set(s["timings"]) >= {"setup", "sample", "assembly", "factor", "solve", "step", "total"}
    assert s["inputs"] == {"template": "disk.mesh", "target_mesh": "box.mesh", "target_sol": "box.sol"}
    p = s["parameters"]
    assert p["clamp"] == {"kind": "ball", "center": [0, 0], "radius": 0.1}, p["clamp"]
    assert p["max_iter"] == 30 and p["save_every"] == 10 and p["young"] == 1
    assert s["shapematch_version"] and s["inverted_elements"] == 0
    assert s["field_builds"] == 1, s.get("field_builds")  # the target field is built once
    return "%s after %d iterations, J %.4f -> %.4f" % (s["stop_reason"], s["iterations"], s["J_initial"], s["J_final"])

@check("history.csv has iterations+1 rows and non-increasing J", have_case)
def _():
    s = summary(E2E)
    rows = list(csv.reader(open(os.path.join(E2E, "history.csv"))))
    assert rows[0] == ["iteration", "J", "step", "boundary_l2", "boundary_max", "min_quality",
                       "elapsed", "accepted", "rejected"], rows[0]
    data = rows[1:]
    assert len(data) == s["iterations"] + 1, (len(data), s["iterations"])
    assert [int(r[0]) for r in data] == list(range(len(data)))
    J = [float(r[1]) for r in data]
    assert all(b <= a for a, b in zip(J, J[1:])), "J increases"
    assert J[0] == s["J_initial"] and J[-1] == s["J_final"], (J[0], J[-1])
    assert int(data[-1][7]) == s["accepted"] and int(data[-1][8]) == s["rejected"]
    return "%d rows" % len(data)

@check("template + displacement == result (1e-12); vtu distance = d(final vertices)", have_case)
def _():
    x0, t0 = mesh("disk.mesh")
    x1, t1 = mesh(os.path.join(E2E, "result.mesh"))
    u = sol_vectors(os.path.join(E2E, "displacement.sol"))
    assert len(x0) == len(x1) == len(u) and t0 == t1, (len(x0), len(x1), len(u))
    err = max(abs(a[c] + b[c] - r[c]) for a, b, r in zip(x0, u, x1) for c in range(2))
    assert err <= 1e-12, err
    moved = max(math.hypot(*b) for b in u)
    assert moved > 0.05, "nothing moved: %g" % moved
    sys.path.insert(0, os.path.join(env["SM_ROOT_DIR"], "tests", "lib"))
    import vtu
    fields = vtu.read(os.path.join(E2E, "result.vtu"))[1]
    assert "distance" in fields and "displacement" in fields, "point fields missing"
    dist = fields["distance"]
    assert len(dist) == len(x1)
    # r - 0.8 has a cone point at the origin where P1 interpolation is
    # only O(h); away from it the error is O(h^2 / r)
    far = [(dv, p) for dv, p in zip(dist, x1) if math.hypot(*p) >= 0.3]
    assert len(far) > len(dist) // 2
    derr = max(abs(dv - (math.hypot(*p) - 0.8)) for dv, p in far)
    assert derr < 0.01, derr
    return "max |x0+u-x| %.2g, max move %.3f, distance error %.2g" % (err, moved, derr)

@check("file names with quotes, backslashes, tabs, invalid UTF-8 give valid JSON", have_case)
def _():
    assert env["RC_ODD"] in ("0", "10"), "exit " + env["RC_ODD"]  # 2 iterations: 10, not converged
    got = summary("outodd")["inputs"]["template"]
    assert got == 'we"ird\\ \ufffdt\u00e9\t.mesh', repr(got)

@check("--json prints valid NDJSON (gzip inputs; --quiet silences stderr)", have_case)
def _():
    assert env["RC_JSON"] == "0", "exit " + env["RC_JSON"]
    assert os.path.getsize("json.err") == 0, open("json.err").read()[:200]
    events = ndjson("json.out")
    prog = [e for e in events if e.get("type") == "progress"]
    fin = events[-1]
    assert fin["event"] == "finished" and fin["type"] == "finished" and fin["exit_code"] == 0, fin
    assert len(prog) == len(events) - 1
    res = fin["result"]
    assert [e["iteration"] for e in prog] == list(range(res["iterations"] + 1))
    for e in prog:
        assert e["event"] == "progress" and set(e) >= {"iteration", "J", "step", "boundary_l2",
            "boundary_max", "min_quality", "elapsed", "accepted", "rejected"}, e
    assert prog[-1]["J"] == res["J_final"]
    s = summary("outjson")
    for k in ("stop_reason", "iterations", "J_initial", "J_final", "boundary_l2", "accepted", "parameters"):
        assert s[k] == res[k], k
    assert s["parameters"]["clamp"] == {"kind": "none", "alpha": 0}, s["parameters"]["clamp"]  # 0: from the scale
    return "%d events" % len(events)

@check("--json reports a failure as one \"failed\" event", have_case)
def _():
    events = ndjson("failed.out")
    assert len(events) == 1, events
    e = events[0]
    assert e["type"] == "failed" and e["exit_code"] == 2 and "vector.sol" in e["message"], e

try:
    import jsonschema, referencing
    have_schema = all(os.path.isfile(os.path.join(env["SM_ROOT_DIR"], "proto", n))
                      for n in ("events.schema.json", "params.schema.json"))
except ImportError:
    have_schema = False
@check("summary.json and the NDJSON events validate against proto's schemas", have_case and have_schema)
def _():
    proto = os.path.join(env["SM_ROOT_DIR"], "proto")
    schemas = [json.load(open(os.path.join(proto, n))) for n in ("events.schema.json", "params.schema.json")]
    registry = referencing.Registry().with_resources(
        [(s["$id"], referencing.Resource.from_contents(s)) for s in schemas])
    def validator(ref):
        return jsonschema.Draft202012Validator({"$ref": ref}, registry=registry)
    events_id = schemas[0]["$id"]
    validator(events_id + "#/$defs/result").validate(summary(E2E))
    ev = validator(events_id)
    lines = ndjson("json.out") + ndjson("cancel.out") + ndjson("failed.out")
    for e in lines:
        ev.validate(e)
    return "summary and %d events" % len(lines)

@check("SIGINT stops the run, writes the outputs, exits 5", have_case)
def _():
    assert env["RC_CANCEL"] == "5", "exit " + env["RC_CANCEL"]
    s = summary("outcancel")
    assert s["status"] == "cancelled" and s["stop_reason"] == "cancelled" and s["exit_code"] == 5, s["status"]
    rows = list(csv.reader(open("outcancel/history.csv")))[1:]
    assert len(rows) == s["iterations"] + 1
    assert os.path.getsize("outcancel/result.mesh") > 0
    fin = ndjson("cancel.out")[-1]
    assert fin["event"] == "finished" and fin["status"] == "cancelled", fin
    assert fin["result"]["stop_reason"] == "cancelled" and fin["exit_code"] == 5
    return "after %d iterations" % s["iterations"]

@check("examples/2d reaches boundary_l2 <= 1e-3 with no inverted element", bool(env.get("EX_TEMPLATE")))
def _():
    assert env["RC_EX"] == "0", "exit " + env["RC_EX"]
    s = summary("outex")
    assert s["boundary_l2"] <= 1e-3, "boundary_l2 %g" % s["boundary_l2"]
    assert s["inverted_elements"] == 0
    def area(xy, tr):
        (ax, ay), (bx, by), (cx, cy) = (xy[i] for i in tr)
        return (bx - ax) * (cy - ay) - (by - ay) * (cx - ax)
    x0, t0 = mesh(env["EX_TEMPLATE"])
    x1, t1 = mesh("outex/result.mesh")
    assert t0 == t1, "topology changed"
    flipped = sum(1 for tr in t0 if area(x0, tr) * area(x1, tr) <= 0)
    assert flipped == 0, "%d inverted elements" % flipped
    return "%s, %s after %d iterations, boundary_l2 %.2g, %ss" % (env["EX_CLAMP"],
        s["stop_reason"], s["iterations"], s["boundary_l2"], env["EX_SECONDS"])

for name, fn in checks:
    try:
        note = fn()
        print("PASS\t%s%s" % (name, " (%s)" % note if note else ""))
    except Exception as e:
        tb = traceback.extract_tb(e.__traceback__)[-1]
        print("FAIL\t%s\tline %d: %s: %s" % (name, tb.lineno, type(e).__name__, str(e)[:300]))
PY
HAVE_CASE=$have_case SM_ROOT_DIR=$ROOT RC_ODD=${rc_odd:-} RC_JSON=${rc_json:-} RC_CANCEL=${rc_cancel:-} \
    EX_TEMPLATE=$ex_template RC_EX=${rc_ex:-} EX_SECONDS=${ex_seconds:-} EX_CLAMP="${clamp[*]:-}" \
    python3 verify.py >verify.log 2>&1
[ -s verify.log ] || not_ok "content checks ran (python3)" "no output from verify.py"
while IFS=$'\t' read -r verdict name reason; do
    case $verdict in
    PASS) ok "$name" ;;
    FAIL) not_ok "$name" "$reason" ;;
    *) not_ok "content checks ran" "$verdict $name $reason" ;;
    esac
done <verify.log
grep -q "examples/2d" verify.log ||
    skip "examples/2d not present (template.mesh, background.mesh, background.sol)"
if [ "$have_case" = 1 ] && ! grep -q "schemas" verify.log; then
    skip "python3 jsonschema or proto/*.schema.json missing: schema check"
fi

echo "1..$n"
