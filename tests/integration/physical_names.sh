#!/usr/bin/env bash
# Gmsh $PhysicalNames kept in the summary (issue 9): a template made by
# the real gmsh as .msh 4.1 with named physical groups gets
# template.physical_names [{dim, tag, name}] in summary.json, the same
# from `shapematch run` and from the daemon (GET /v1/jobs/{id}/results);
# a Medit template has none.  Clamps by name through the daemon (issue
# 27): params with clamp.refs ["core"] on a Gmsh template whose core disk
# is a named group run as refs [its tag] (the same boundary RMS, the job
# keeps the number); an unknown name, a name of the wrong dimension for
# free_boundary, and a name on a Medit template are 422s naming the item
# and listing the names the template has.
source "$(dirname "$0")/lib.sh"

if ! make_case; then
    not_ok "gmsh made the test case" "$(tail -5 "$WORK/case/gmsh.log")"
    exit 1
fi
cat >"$WORK/case/named.geo" <<'GEO'
SetFactory("OpenCASCADE");
Disk(1) = {0, 0, 0, 0.5};
Physical Surface("plate", 5) = {1};
Physical Curve("rim edge", 2) = {1};
Mesh.CharacteristicLengthMax = 0.08;
GEO
if (cd "$WORK/case" && gmsh -2 named.geo -format msh41 -o named.msh -v 0) >>"$WORK/case/gmsh.log" 2>&1; then
    ok "gmsh made a .msh template with physical names"
else
    not_ok "gmsh made a .msh template" "$(tail -5 "$WORK/case/gmsh.log")"
    exit 1
fi
TPL=$WORK/case/named.msh
want='[{"dim":1,"name":"rim edge","tag":2},{"dim":2,"name":"plate","tag":5}]'
names() { jq -cS '.template.physical_names // [] | sort_by(.dim, .tag)' "$1"; }

"$BIN/shapematch" run --template "$TPL" --target-mesh "$BOX" --target-sol "$BOXSOL" \
    --clamp-ball 0,0,0.1 --max-iter 5 --quiet -o "$WORK/run" >/dev/null 2>"$WORK/run.err"
got=$(names "$WORK/run/summary.json" 2>&1)
if [ "$got" = "$want" ]; then
    ok "run: summary.json lists the template's physical names"
else
    not_ok "run: physical names in summary.json" "got $got" "$(cat "$WORK/run.err")"
fi
"$BIN/shapematch" run --template "$DISK" --target-mesh "$BOX" --target-sol "$BOXSOL" \
    --clamp-ball 0,0,0.1 --max-iter 5 --quiet -o "$WORK/medit" >/dev/null 2>&1
check "run: a Medit template has no physical_names" \
    test "$(jq '.template | has("physical_names")' "$WORK/medit/summary.json")" = false

if ! start_daemon names --workers 1; then
    not_ok "the daemon starts"
    exit 1
fi
id=$(submit "$TPL" "$BOX" "$BOXSOL" "$(quick_params 5)")
if [ -n "$id" ] && wait_final "$id" 60 && state_is "$id" successful; then
    hcurl "${AUTH[@]}" "$BASE/v1/jobs/$id/results" >"$WORK/daemon.json"
    got=$(names "$WORK/daemon.json" 2>&1)
    if [ "$got" = "$want" ]; then
        ok "daemon: the results list the template's physical names"
    else
        not_ok "daemon: physical names in the results" "got $got"
    fi
else
    not_ok "daemon: the .msh job ends successful" "$(cat "$WORK/submit.out")"
fi

# ------------------------------------------------ clamps by physical name
cat >"$WORK/case/cored.geo" <<'GEO'
SetFactory("OpenCASCADE");
Disk(1) = {0, 0, 0, 0.5};
Disk(2) = {0, 0, 0, 0.12};
BooleanFragments{ Surface{1}; Delete; }{ Surface{2}; Delete; }
Physical Surface("core", 7) = {2};
Physical Surface("body", 8) = {3};
Physical Curve("rim", 4) = {1};
Mesh.CharacteristicLengthMax = 0.06;
GEO
if ! (cd "$WORK/case" && gmsh -2 cored.geo -format msh41 -o cored.msh -v 0) >>"$WORK/case/gmsh.log" 2>&1; then
    not_ok "gmsh made the cored template" "$(tail -5 "$WORK/case/gmsh.log")"
fi
CORED=$WORK/case/cored.msh
named=$(submit "$CORED" "$BOX" "$BOXSOL" '{"clamp": {"kind": "elements", "refs": ["core"]}, "max_iter": 5}')
numbered=$(submit "$CORED" "$BOX" "$BOXSOL" '{"clamp": {"kind": "elements", "refs": [7]}, "max_iter": 5}')
if [ -n "$named" ] && [ -n "$numbered" ] && wait_final "$named" 60 && wait_final "$numbered" 60 &&
    state_is "$named" successful && state_is "$numbered" successful; then
    hcurl "${AUTH[@]}" "$BASE/v1/jobs/$named/results" >"$WORK/named.json"
    hcurl "${AUTH[@]}" "$BASE/v1/jobs/$numbered/results" >"$WORK/numbered.json"
    a=$(jq -c '[.boundary_rms, .iterations]' "$WORK/named.json")
    b=$(jq -c '[.boundary_rms, .iterations]' "$WORK/numbered.json")
    if [ -n "$a" ] && [ "$a" = "$b" ] && [ "$(jq '.iterations' "$WORK/named.json")" -ge 1 ]; then
        ok "daemon: clamp.refs [\"core\"] runs as refs [7], core's tag (boundary RMS, iterations $a)"
    else
        not_ok "daemon: named clamp as numbered" "named $a numbered $b"
    fi
else
    not_ok "daemon: a clamp by name is accepted and runs" "$(cat "$WORK/submit.out")"
fi
# refused: 422, the item named, the names listed
refused() { # PARAMS TEMPLATE EXPECTED_DETAIL EXPECTED_NAME
    local code
    code=$(hcurl "${AUTH[@]}" -o "$WORK/refused.json" -w '%{http_code}' -F "template=@$2" \
        -F "target_mesh=@$BOX" -F "target_sol=@$BOXSOL" -F "params=$1" "$BASE/v1/jobs")
    [ "$code" = 422 ] && [ "$(jq -r .detail "$WORK/refused.json")" = "$3" ] &&
        [ "$(jq -r '."invalid-params"[0].name' "$WORK/refused.json")" = "$4" ]
}
if refused '{"clamp": {"kind": "elements", "refs": [8, "cor"]}}' "$CORED" \
    'params.clamp.refs[1]: the template has no physical group named "cor" of elements (its names of elements: "core" (7), "body" (8))' \
    'params.clamp.refs[1]'; then
    ok "daemon: an unknown clamp name is a 422 naming params.clamp.refs[1] and listing the names of elements"
else
    not_ok "daemon: unknown clamp name" "$(cat "$WORK/refused.json")"
fi
if refused '{"clamp": {"kind": "elements", "refs": ["core"]}, "free_boundary": ["body"]}' "$CORED" \
    'params.free_boundary[0]: the template has no physical group named "body" of facets (its names of facets: "rim" (4))' \
    'params.free_boundary[0]'; then
    ok "daemon: free_boundary takes names of facets only (a 422 listing them)"
else
    not_ok "daemon: free_boundary name of elements" "$(cat "$WORK/refused.json")"
fi
if refused '{"clamp": {"kind": "elements", "refs": ["core"]}}' "$DISK" \
    'params.clamp.refs[0]: the template has no physical names, so no group named "core" (names come from a Gmsh .msh file'"'"'s $PhysicalNames; give the references as numbers)' \
    'params.clamp.refs[0]'; then
    ok "daemon: a name on a Medit template is a 422 saying it has no physical names"
else
    not_ok "daemon: name on a Medit template" "$(cat "$WORK/refused.json")"
fi
reports_clean && ok "no sanitizer report" || not_ok "no sanitizer report"
stop_daemon
echo "1..$n"
