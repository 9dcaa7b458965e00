#!/usr/bin/env bash
# run.sh: weight 1 seconds 20
# The web app's target reader (web/target.js: Medit ASCII, STL, OBJ, gzip;
# the zero level set by marching triangles and tetrahedra) in Node, against
# analytic circles and spheres and malformed files (web_target.mjs).  The
# browser half (the overlay drawn over a job) is in web_app.  Release
# variant only: nothing of the build is involved.
source "$(dirname "$0")/lib.sh"

if [ "$VARIANT" != release ]; then
    skip "the target reader is JavaScript: run in the release variant only"
    echo "1..$n"
    exit 0
fi
node_checks "the node driver runs" "$ROOT/tests/integration/web_target.mjs"
echo "1..$n"
