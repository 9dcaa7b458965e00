#!/usr/bin/env bash
# run.sh: weight 1 seconds 40 asan 1
# The web app's alignment, landmarks, warp and named clamps in real
# Chromium (issues 22, 24 and 27; web_tools.mjs, driven by npm
# playwright-core like web_app).  One daemon.  In the app: the landmark
# files' hints, both-or-neither and align-none refused before a request,
# the daemon's 422 for one landmark point in 2D shown next to its field;
# examples/2d's template moved by 30 degrees and 100 diameters
# (tests/cli/align_inputs.py) submitted with align rigid and its landmark
# files: the alignment event shown while it runs, then summary.json's
# block (matrix as the summary's, near the known motion), the job
# converged.  On that finished job, warp: template vertices pasted go to
# the result's vertices, back again with inverse, a far point flagged
# outside, the CSV downloaded, the template mesh warped onto the result
# mesh, a malformed line's 400 shown.  A Gmsh template whose core disk is
# a named group: the clamp field takes "core" (the job ends successful)
# and an unknown name shows the daemon's 422 listing the names.
# A screenshot of the job panel in build/test-logs/web-tools-warp.png.  Release variant only,
# as web_app (the daemon's side of each is in daemon_align, daemon_warp
# and physical_names, every variant).
source "$(dirname "$0")/lib.sh"

browser_only "the daemon side is covered by daemon_align, daemon_warp and physical_names in every variant"
EX=$ROOT/examples/2d
if ! python3 "$ROOT/tests/cli/align_inputs.py" "$EX" "$WORK"; then
    not_ok "align inputs"
    exit 1
fi
printf 'x,y\n40.1,-29.7\n' >"$WORK/lm_one.csv"
printf '0.5,0.5\n' >"$WORK/lm_one_target.csv"
# the named template: a disk with a core disk of its own physical group,
# and the box's analytic distance to the circle of radius 0.8
mkdir -p "$WORK/case"
cp "$ROOT/tests/lib/case/box.geo" "$WORK/case/"
cp "$ROOT/tests/lib/case/sphere_sdf.awk" "$WORK/case/sdf.awk"
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
if ! (cd "$WORK/case" && gmsh -2 box.geo -format mesh -o box.mesh -v 0 &&
    awk -v R=0.8 -f sdf.awk box.mesh >box.sol &&
    gmsh -2 cored.geo -format msh41 -o cored.msh -v 0) >"$WORK/case/gmsh.log" 2>&1; then
    not_ok "gmsh builds the named template and the box" "$(tail -5 "$WORK/case/gmsh.log")"
    exit 1
fi
start_daemon tools --workers 2 || { not_ok "the daemon starts"; exit 1; }
ok "the daemon starts"
LOGS=$ROOT/build/test-logs
mkdir -p "$LOGS"
rm -f "$LOGS"/web-tools-*.png
node_checks "the browser driver runs" "$ROOT/tests/integration/web_tools.mjs" "$BASE" "$EX" "$WORK" "$LOGS"
check "screenshot web-tools-warp.png saved" [ -s "$LOGS/web-tools-warp.png" ]
check "no sanitizer reports" reports_clean
stop_daemon
echo "1..$n"
