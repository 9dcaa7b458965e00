#!/usr/bin/env bash
# result.vtu carries the boundary facets with their references: a strict
# XML read-back (tests/lib/vtu.py: ElementTree, base64 and zlib; VTK's and
# meshio's readers are tried by tests/cli/vtu_files.sh) of the 2D example's
# result checks every array against the others and finds the template's
# 100 boundary edges (ref 1) and 16 clamp edges (ref 10) as VTK_LINE cells
# after the 778 triangles.
source "$(dirname "$0")/../lib/cli.sh"
EX=$ROOT/examples/2d
# five iterations do not converge: exit 10, every output written
"$BIN" run --template "$EX/template.mesh" --target-mesh "$EX/background.mesh.gz" \
    --target-sol "$EX/background.sol.gz" --clamp-ball "$(tr -d ' \n' <"$EX/clamp")" \
    --max-iter 5 --quiet -o "$WORK/out" >"$WORK/err" 2>&1
rc=$?
if [ $rc != 0 ] && [ $rc != 10 ]; then
    echo "not ok - the 2D example runs"; sed 's/^/# /' "$WORK/err"; exit 0
fi
python3 - "$WORK/out/result.vtu" "$ROOT/tests/lib" <<'PY'
import sys, xml.etree.ElementTree as ET
from collections import Counter
sys.path.insert(0, sys.argv[2])
import vtu
def check(ok, what, why=""):
    print("%s - %s%s" % ("ok" if ok else "not ok", what, "" if ok or not why else "\n# " + why))
try:
    root = ET.parse(sys.argv[1]).getroot()
except ET.ParseError as e:
    check(False, "result.vtu is well-formed XML", str(e)); sys.exit(0)
check(root.tag == "VTKFile" and root.get("type") == "UnstructuredGrid", "a VTK UnstructuredGrid file")
pieces = root.findall("./UnstructuredGrid/Piece")
check(len(pieces) == 1, "one piece")
piece = pieces[0]
npts, ncells = int(piece.get("NumberOfPoints")), int(piece.get("NumberOfCells"))
arrays = vtu.read(sys.argv[1])[1]
def arr(path, name=None):
    return arrays.get(name or path)
pts = arr("Points"); conn = arr("Cells", "connectivity"); offs = arr("Cells", "offsets")
types = arr("Cells", "types"); ref = arr("CellData", "ref"); cdim = arr("CellData", "cell_dim")
check(len(pts) == 3 * npts and all(len(a) == ncells for a in (offs, types, ref, cdim)),
      "every array has NumberOfPoints / NumberOfCells entries (%d points, %d cells)" % (npts, ncells))
check(all(b > a for a, b in zip([0] + offs, offs)) and offs[-1] == len(conn)
      and all(0 <= v < npts for v in conn), "offsets increase to the connectivity's length, indices in range")
sizes = [int(b - a) for a, b in zip([0] + offs, offs)]
kinds = Counter((int(t), s, int(d)) for t, s, d in zip(types, sizes, cdim))
check(kinds == Counter({(5, 3, 2): 778, (3, 2, 1): 116}),
      "778 triangles (cell_dim 2), then 116 VTK_LINE facets (cell_dim 1)", str(kinds))
first_facet = next(i for i, d in enumerate(cdim) if d == 1)
check(all(d == 1 for d in cdim[first_facet:]) and first_facet == 778, "facets after the elements")
frefs = Counter(int(r) for r, d in zip(ref, cdim) if d == 1)
check(frefs == Counter({1: 100, 10: 16}), "facet refs: 100 boundary edges (1), 16 clamp edges (10)", str(frefs))
check(set(int(r) for r, d in zip(ref, cdim) if d == 2) == {1, 2}, "element refs 1 and 2 kept")
PY
