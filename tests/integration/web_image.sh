#!/usr/bin/env bash
# run.sh: weight 1 seconds 20 asan 1
# The web form's label-map target in real Chromium (web_image.mjs): the
# target_image input and the label/level/image_space fields, a job
# through the form, a dropped image routed to its input, an empty label's
# 422 in the form.  Release variant only: the daemon side is
# daemon_image's, in both variants.
source "$(dirname "$0")/lib.sh"

browser_only "daemon_image covers the daemon in both"
PY=/usr/bin/python3
[ -x "$PY" ] || PY=python3
"$PY" "$ROOT/tests/cli/image_shapes.py" write "$WORK" sphere >/dev/null
cat >"$WORK/ball.geo" <<'GEO'
SetFactory("OpenCASCADE");
Sphere(1) = {4, 39, 9, 8.5};
Mesh.MeshSizeFromPoints = 0;
GEO
gmsh "$WORK/ball.geo" -3 -format msh41 -clmax 3 -nt 1 -v 1 -o "$WORK/ball.msh" >/dev/null 2>&1
start_daemon web --workers 1 || { not_ok "the daemon starts"; exit 1; }
node_checks "the browser driver runs" "$ROOT/tests/integration/web_image.mjs" "$BASE" "$WORK/ball.msh" "$WORK/s1.nii" \
   
echo "1..$n"
