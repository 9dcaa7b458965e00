#!/usr/bin/env bash
# POST /v1/jobs/{id}/warp on a real daemon (docs/warp.md): on a finished
# disk job, the CSV answer is byte for byte `shapematch warp --result` on
# the fetched results, and `shapematch warp --job ID` gives the same
# file, as do a mesh, a surface (in its own format or format=vtu) and a
# field sent to the daemon; the template's vertices go onto the result's (checked against
# result.mesh); inverse(forward(x)) = x through JSON; a malformed CSV line
# is named (400), a body over --max-upload is 413, a running job 409, an
# unknown job and another tenant's job 404, the query's direction
# checked; no sanitizer report.
source "$(dirname "$0")/lib.sh"

if ! make_case; then
    not_ok "gmsh builds the test meshes" "$(tail -5 "$WORK/case/gmsh.log")"
    exit 1
fi
printf 'tok-alice-0123456789 alice\ntok-bob-0123456789 bob\n' >"$WORK/tokens"
start_daemon warp --workers 2 --max-upload 400K --kill-grace 1 --tokens-file "$WORK/tokens" ||
    { not_ok "the daemon starts"; exit 1; }
AUTH=(-H 'Authorization: Bearer tok-alice-0123456789')
export SHAPEMATCH_TOKEN=tok-alice-0123456789
ok "the daemon starts"
SM=$BIN/shapematch
J=$(submit "$DISK" "$BOX" "$BOXSOL" "$(quick_params 20)")
R=$(submit "$FINE" "$BOX" "$BOXSOL" "$(endless_params)")
if [ -n "$J" ] && [ -n "$R" ] && wait_state "$J" successful 60; then
    ok "a disk job finished (and an endless one submitted)"
else
    not_ok "the jobs" "$(cat "$WORK/submit.out")" "$(job_state "$J")"
    exit 1
fi
"$SM" fetch -q --server "$BASE" --format mesh,sol -o "$WORK/res" "$J" 2>"$WORK/fetch.err"
# random points over the disk's box and beyond (the disk has radius 0.5)
python3 - "$WORK/p.csv" <<'PY'
import random, sys
r = random.Random(3)
with open(sys.argv[1], "w") as f:
    f.write("x,y\n")
    for _ in range(2000):
        f.write("%.17g,%.17g\n" % (r.uniform(-0.6, 0.6), r.uniform(-0.6, 0.6)))
PY
CSV=(-H 'Content-Type: text/csv')
code=$(hcurl "${AUTH[@]}" -o "$WORK/fwd.csv" -w '%{http_code}' "${CSV[@]}" --data-binary "@$WORK/p.csv" \
    "$BASE/v1/jobs/$J/warp")
"$SM" warp -q --result "$WORK/res" --points "$WORK/p.csv" -o "$WORK/cli.csv"
if [ "$code" = 200 ] && cmp -s "$WORK/fwd.csv" "$WORK/cli.csv"; then
    ok "CSV forward: byte for byte the CLI's answer on the fetched result"
else
    not_ok "CSV forward" "code $code" "$(diff "$WORK/fwd.csv" "$WORK/cli.csv" | head -5)"
fi
if "$SM" warp -q --job "$J" --server "$BASE" --points "$WORK/p.csv" -o "$WORK/job.csv" &&
    cmp -s "$WORK/job.csv" "$WORK/cli.csv"; then
    ok "shapematch warp --job ID --server gives the same file"
else
    not_ok "warp --job" "$(diff "$WORK/job.csv" "$WORK/cli.csv" | head -5)"
fi
nin=$(awk -F, 'NR > 1 && $3 == 1' "$WORK/fwd.csv" | wc -l)
nout=$(awk -F, 'NR > 1 && $3 == 0' "$WORK/fwd.csv" | wc -l)
if [ "$nin" -gt 1000 ] && [ "$nout" -gt 100 ]; then
    ok "points inside ($nin) and outside ($nout) flagged"
else
    not_ok "inside flags" "$nin inside, $nout outside"
fi

# the template's vertices (DISK) onto result.mesh's, through JSON
python3 - "$DISK" "$WORK/verts.json" <<'PY'
import json, sys
t = open(sys.argv[1]).read().split()
i = t.index("Vertices")
n = int(t[i + 1])
dim = int(t[t.index("Dimension") + 1])
pts = [[float(x) for x in t[i + 2 + (dim + 1) * k:i + 2 + (dim + 1) * k + 2]] for k in range(n)]
json.dump({"points": pts}, open(sys.argv[2], "w"))
PY
code=$(hcurl "${AUTH[@]}" -o "$WORK/verts.out" -w '%{http_code}' -H 'Content-Type: application/json' \
    --data-binary "@$WORK/verts.json" "$BASE/v1/jobs/$J/warp")
msg=$(python3 - "$WORK/verts.out" "$WORK/res/result.mesh" <<'PY'
import json, math, sys
got = json.load(open(sys.argv[1]))
t = open(sys.argv[2]).read().split()
i = t.index("Vertices")
n = int(t[i + 1])
want = [[float(x) for x in t[i + 2 + 3 * k:i + 4 + 3 * k]] for k in range(n)]
worst = max(math.dist(a, b) for a, b in zip(got["points"], want))
ok = len(got["points"]) == n and worst <= 1e-12 and all(f == 1 for f in got["inside"])
print("%d vertices, max distance %.3g" % (n, worst))
sys.exit(0 if ok else 1)
PY
)
prc=$?
if [ "$code" = 200 ] && [ "$prc" = 0 ]; then
    ok "JSON: the template's vertices land on result.mesh's ($msg)"
else
    not_ok "template vertices" "code $code" "$msg"
fi

# inverse(forward(x)) = x for the inside points, the direction in the query
awk -F, 'NR > 1 && $3 == 1 { print $1 "," $2 }' "$WORK/fwd.csv" >"$WORK/fwd-in.csv"
awk -F, 'NR > 1 && $3 == 1 { print NR - 1 }' "$WORK/fwd.csv" >"$WORK/in-lines"
code=$(hcurl "${AUTH[@]}" -o "$WORK/back.csv" -w '%{http_code}' "${CSV[@]}" --data-binary "@$WORK/fwd-in.csv" \
    "$BASE/v1/jobs/$J/warp?direction=inverse")
msg=$(python3 - "$WORK/p.csv" "$WORK/in-lines" "$WORK/back.csv" <<'PY'
import math, sys
pts = [list(map(float, l.split(","))) for l in open(sys.argv[1]).read().split()[1:]]
idx = [int(l) - 1 for l in open(sys.argv[2]).read().split()]
back = [list(map(float, l.split(",")[:2])) for l in open(sys.argv[3]).read().split()[1:]]
worst = max(math.dist(pts[i], b) for i, b in zip(idx, back))
print("%d points, max |inverse(forward(x)) - x| %.3g" % (len(back), worst))
sys.exit(0 if len(back) == len(idx) and worst <= 1e-9 else 1)
PY
)
prc=$?
if [ "$code" = 200 ] && [ "$prc" = 0 ]; then ok "inverse(forward(x)) = x ($msg)"; else not_ok "inverse" "code $code" "$msg"; fi

# a mesh and a field through the daemon: the CLI's files, byte for byte
code=$(hcurl "${AUTH[@]}" -o "$WORK/disk-warped.mesh" -w '%{http_code}' \
    -H 'Content-Type: application/x-medit-mesh' --data-binary "@$DISK" "$BASE/v1/jobs/$J/warp")
"$SM" warp -q --result "$WORK/res" --mesh "$DISK" -o "$WORK/disk-cli.mesh"
if [ "$code" = 200 ] && cmp -s "$WORK/disk-warped.mesh" "$WORK/disk-cli.mesh"; then
    ok "a mesh (Medit) warped by the daemon: the CLI's file"
else
    not_ok "mesh over HTTP" "code $code" "$(head -c 300 "$WORK/disk-warped.mesh")"
fi
awk 'BEGIN { print "MeshVersionFormatted 2\nDimension 2\nSolAtVertices" }
     $1 == "Vertices" { getline n; print n "\n1 2"; for (i = 0; i < n; i++) { getline; print -$2, $1 } }
     END { print "End" }' "$WORK/res/result.mesh" >"$WORK/v.sol"
code=$(hcurl "${AUTH[@]}" -o "$WORK/v-warped.sol" -w '%{http_code}' \
    -H 'Content-Type: application/x-medit-sol' --data-binary "@$WORK/v.sol" \
    "$BASE/v1/jobs/$J/warp?normalize=true")
"$SM" warp -q --result "$WORK/res" --normalize --field "$WORK/v.sol" -o "$WORK/v-cli.sol"
if [ "$code" = 200 ] && cmp -s "$WORK/v-warped.sol" "$WORK/v-cli.sol"; then
    ok "a vector field warped by the daemon (normalize): the CLI's file"
else
    not_ok "field over HTTP" "code $code" "$(head -c 300 "$WORK/v-warped.sol")"
fi
# a surface (here a VTK legacy polyline, the 2D job's kind of surface):
# answered in its own format, or as format=vtu, each the CLI's file
python3 - "$WORK/circle.vtk" <<'PY'
import math, sys
n = 64
pts = "".join("%.17g %.17g 0\n" % (0.4 * math.cos(2 * math.pi * k / n),
                                    0.4 * math.sin(2 * math.pi * k / n)) for k in range(n))
lines = "".join("2 %d %d\n" % (k, (k + 1) % n) for k in range(n))
open(sys.argv[1], "w").write("# vtk DataFile Version 3.0\ncircle\nASCII\nDATASET POLYDATA\n"
                             "POINTS %d double\n%sLINES %d %d\n%s" % (n, pts, n, 3 * n, lines))
PY
for fmt in vtk vtu; do
    q=""
    [ "$fmt" = vtu ] && q="?format=vtu"
    code=$(hcurl "${AUTH[@]}" -o "$WORK/circle-http.$fmt" -D "$WORK/circle.h" -w '%{http_code}' \
        -H 'Content-Type: application/x-vtk' --data-binary "@$WORK/circle.vtk" \
        "$BASE/v1/jobs/$J/warp$q")
    "$SM" warp -q --result "$WORK/res" --mesh "$WORK/circle.vtk" -o "$WORK/circle-cli.$fmt"
    media=$(tr -d '\r' <"$WORK/circle.h" | awk -F': ' 'tolower($1) == "content-type" { print $2 }')
    if [ "$code" = 200 ] && cmp -s "$WORK/circle-http.$fmt" "$WORK/circle-cli.$fmt" &&
        [ "$media" = "application/x-$fmt" ]; then
        ok "a surface (VTK polyline) answered as .$fmt ($media): the CLI's file"
    else
        not_ok "surface over HTTP as .$fmt" "code $code, $media" \
            "$(head -c 300 "$WORK/circle-http.$fmt")"
    fi
done
# errors, as problem+json
problem() { # DESC STATUS DETAIL-PART CURL-ARGS...
    local desc=$1 want=$2 part=$3 code
    shift 3
    code=$(hcurl "${AUTH[@]}" -o "$WORK/p.json" -w '%{http_code} %{content_type}' "$@")
    if [ "$code" = "$want application/problem+json" ] &&
        jq -e --arg p "$part" --argjson s "$want" '.status == $s and (.detail | contains($p))' \
            "$WORK/p.json" >/dev/null; then
        ok "$desc: $want"
    else
        not_ok "$desc" "$code" "$(head -c 300 "$WORK/p.json")"
    fi
}
printf 'MeshVersionFormatted 2\nDimension 2\nVertices\n2\n0 0 0\n' >"$WORK/broken.mesh"
problem "a malformed mesh: the reader's message" 400 "the body" \
    -H 'Content-Type: application/x-medit-mesh' --data-binary "@$WORK/broken.mesh" \
    "$BASE/v1/jobs/$J/warp"
printf 'x,y\n0,0\n0.1,0.1\n0.2;0.2\n' >"$WORK/bad.csv"
problem "a malformed CSV line is named" 400 "line 4" "${CSV[@]}" --data-binary "@$WORK/bad.csv" \
    "$BASE/v1/jobs/$J/warp"
problem "a bad direction" 400 "direction" "${CSV[@]}" --data-binary $'0,0\n' \
    "$BASE/v1/jobs/$J/warp?direction=sideways"
problem "a volume mesh asked as STL" 422 "is a volume mesh: write it as .mesh, .meshb or .vtu" \
    -H 'Content-Type: application/x-medit-mesh' --data-binary "@$DISK" \
    "$BASE/v1/jobs/$J/warp?format=stl"
problem "an unknown format" 400 "format: expected mesh, vtu" \
    -H 'Content-Type: model/stl' --data-binary "@$DISK" "$BASE/v1/jobs/$J/warp?format=step"
printf 'solid s\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\nendloop\nendfacet\nendsolid s\n' >"$WORK/tri.stl"
problem "a 3D surface on the 2D map" 422 "the body is 3D and the map is 2D" \
    -H 'Content-Type: model/stl' --data-binary "@$WORK/tri.stl" "$BASE/v1/jobs/$J/warp"
problem "garbage as a surface: both readers' messages" 400 "neither a mesh" \
    -H 'Content-Type: model/obj' --data-binary 'not a surface' "$BASE/v1/jobs/$J/warp"
problem "strict: a point outside refused, its CSV line named" 422 \
    "line 4: point (3, 3) is outside" "${CSV[@]}" \
    --data-binary $'x,y\n0,0\n\n3,3\n' "$BASE/v1/jobs/$J/warp?strict=true"
problem "strict JSON: the point's index named" 422 "points[1]: point (3, 3) is outside" \
    -H 'Content-Type: application/json' \
    --data-binary '{"points": [[0, 0], [3, 3]], "strict": true}' "$BASE/v1/jobs/$J/warp"
# --outside: flag (null in JSON, nan in CSV), skip (left out, counted),
# the names checked; inside keeps one flag per point given
code=$(hcurl "${AUTH[@]}" -o "$WORK/flag.json" -w '%{http_code}' -H 'Content-Type: application/json' \
    --data-binary '{"points": [[0, 0], [3, 3]], "outside": "flag"}' "$BASE/v1/jobs/$J/warp")
if [ "$code" = 200 ] && jq -e '.points[1] == null and (.points[0] | length) == 2 and
        .inside == [1, 0] and .outside == 1' "$WORK/flag.json" >/dev/null; then
    ok "outside flag (JSON member): the outside point null, inside [1, 0]"
else
    not_ok "outside flag" "$code" "$(head -c 300 "$WORK/flag.json")"
fi
code=$(hcurl "${AUTH[@]}" -o "$WORK/skip.json" -w '%{http_code}' -H 'Content-Type: application/json' \
    --data-binary '{"points": [[3, 3], [0, 0]]}' "$BASE/v1/jobs/$J/warp?outside=skip")
if [ "$code" = 200 ] && jq -e '(.points | length) == 1 and .inside == [0, 1] and .skipped == 1' \
        "$WORK/skip.json" >/dev/null; then
    ok "outside=skip (query): one point answered, skipped 1"
else
    not_ok "outside skip" "$code" "$(head -c 300 "$WORK/skip.json")"
fi
code=$(hcurl "${AUTH[@]}" -o "$WORK/flag.csv" -w '%{http_code}' "${CSV[@]}" \
    --data-binary $'x,y\n3,3\n0,0\n' "$BASE/v1/jobs/$J/warp?outside=flag")
if [ "$code" = 200 ] && [ "$(sed -n 2p "$WORK/flag.csv")" = "nan,nan,0" ]; then
    ok "outside=flag, CSV: nan,nan,0"
else
    not_ok "outside flag CSV" "$code" "$(head -c 300 "$WORK/flag.csv")"
fi
problem "a bad outside name" 400 "outside: expected extrapolate, flag or skip" "${CSV[@]}" \
    --data-binary $'0,0\n' "$BASE/v1/jobs/$J/warp?outside=drop"
problem "a bad outside member" 400 "outside: expected" -H 'Content-Type: application/json' \
    --data-binary '{"points": [[0, 0]], "outside": 3}' "$BASE/v1/jobs/$J/warp"
problem "outside for a mesh" 400 "is for points" -H 'Content-Type: application/x-medit-mesh' \
    --data-binary "@$DISK" "$BASE/v1/jobs/$J/warp?outside=skip"
head -c 500000 /dev/zero | tr '\0' '\n' >"$WORK/big.csv"
problem "a body over --max-upload" 413 "--max-upload" "${CSV[@]}" --data-binary "@$WORK/big.csv" \
    "$BASE/v1/jobs/$J/warp"
# chunked, without a Content-Length: refused once the body passes the limit
problem "a chunked body over --max-upload" 413 "--max-upload" "${CSV[@]}" \
    -H 'Transfer-Encoding: chunked' --data-binary "@$WORK/big.csv" "$BASE/v1/jobs/$J/warp"
wait_state "$R" running 30 >/dev/null
problem "a running job has no map" 409 "is running" "${CSV[@]}" --data-binary $'0,0\n' \
    "$BASE/v1/jobs/$R/warp"
problem "an unknown job" 404 "no job" "${CSV[@]}" --data-binary $'0,0\n' \
    "$BASE/v1/jobs/0123456789abcdef0123456789abcdef/warp"
AUTH=(-H 'Authorization: Bearer tok-bob-0123456789')
problem "another tenant's job" 404 "no job" "${CSV[@]}" --data-binary $'0,0\n' \
    "$BASE/v1/jobs/$J/warp"
AUTH=(-H 'Authorization: Bearer tok-alice-0123456789')
code=$(hcurl "${AUTH[@]}" -o /dev/null -w '%{http_code}' "$BASE/v1/jobs/$J/results")
[ "$code" = 200 ] && ok "the daemon answers after all this" || not_ok "daemon alive" "$code"
hcurl "${AUTH[@]}" -o /dev/null -X DELETE "$BASE/v1/jobs/$R"
stop_daemon
if reports_clean; then ok "no sanitizer report"; else not_ok "sanitizer reports"; fi
echo "1..$n"
