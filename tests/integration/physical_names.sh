#!/usr/bin/env bash
# Gmsh $PhysicalNames kept in the summary (issue 9): a template made by
# the real gmsh as .msh 4.1 with named physical groups gets
# template.physical_names [{dim, tag, name}] in summary.json, the same
# from `shapematch run` and from the daemon (GET /v1/jobs/{id}/results);
# a Medit template has none.
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
reports_clean && ok "no sanitizer report" || not_ok "no sanitizer report"
stop_daemon
echo "1..$n"
