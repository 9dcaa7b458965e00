#!/usr/bin/env bash
# `make demo`: match the bundled 2D example with the local CLI and leave
# the results in demo-out/.
set -euo pipefail
cd "$(dirname "$0")/.."
BIN=${SM_BIN:-build/release}
EX=examples/2d
OUT=${DEMO_OUT:-demo-out}
pick() { for f in "$EX/$1" "$EX/$1.gz"; do [ -f "$f" ] && { echo "$f"; return; }; done; echo "missing $EX/$1" >&2; exit 2; }

echo "shapematch demo: template $(pick template.mesh) -> target given by $(pick background.sol)"
"$BIN/shapematch" run \
    --template "$(pick template.mesh)" \
    --target-mesh "$(pick background.mesh)" \
    --target-sol "$(pick background.sol)" \
    --clamp-ball "$(cat $EX/clamp)" \
    --max-iter 300 --tol-boundary 1e-4 \
    -o "$OUT"
echo
echo "results in $OUT/:"
ls -l "$OUT" | tail -n +2 | awk '{printf "  %-18s %8d bytes\n", $NF, $5}'
python3 - "$OUT/summary.json" <<'PY' 2>/dev/null || grep -E '"(stop_reason|iterations|boundary_l2)"' "$OUT/summary.json"
import json, sys
s = json.load(open(sys.argv[1]))
print("summary: %s after %d iterations, boundary error %.3g" % (
    s.get("stop_reason"), s.get("iterations"), s.get("boundary_l2", s.get("boundary_error_l2", float("nan")))))
PY
echo "open $OUT/result.vtu in ParaView, or $OUT/result.mesh in Medit/Gmsh"
