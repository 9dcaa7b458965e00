#!/usr/bin/env bash
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
node "$ROOT/tests/integration/web_target.mjs" >"$WORK/node.out" 2>"$WORK/node.err"
rc=$?
while IFS= read -r line; do
    desc=$(jq -r .desc <<<"$line" 2>/dev/null) || continue
    if [ "$(jq -r .ok <<<"$line")" = true ]; then
        ok "$desc"
    else
        not_ok "$desc" "$(jq -r .detail <<<"$line")"
    fi
done <"$WORK/node.out"
[ "$rc" = 0 ] || not_ok "the node driver runs" "exit $rc" "$(tail -20 "$WORK/node.err")"
echo "1..$n"
