#!/usr/bin/env bash
# The image-frame warning: a label map written by nibabel (its affine is
# RAS, as every NIfTI nibabel writes) and a template given in the same
# world coordinates.  Read as LPS (the default) the label is mirrored in
# x and y, the template fits the other frame far better: warning
# image-frame naming --image-space ras, in summary.json too, and with
# --align the note that the alignment would turn the template onto the
# mirrored label; with --image-space ras, no warning.
source "$(dirname "$0")/../lib/cli.sh"
check_rc() { if [ "$1" = 0 ]; then ok "$2"; else not_ok "$2" "${3:-}"; fi; }
PY=/usr/bin/python3
[ -x "$PY" ] || PY=python3
export OMP_NUM_THREADS=1

# a ball of radius 10 mm about RAS (30, 20, 10), on a 2 mm grid whose
# corner is at RAS (10, 0, -10): nibabel's own affine and writer
"$PY" - "$WORK/label.nii.gz" <<'PY'
import sys
import numpy as np
import nibabel as nib
affine = np.diag([2.0, 2.0, 2.0, 1.0])
affine[:3, 3] = [10.0, 0.0, -10.0]
i, j, k = np.meshgrid(np.arange(20), np.arange(20), np.arange(20), indexing="ij")
x, y, z = 10 + 2 * i, 2 * j, -10 + 2 * k
data = ((x - 30) ** 2 + (y - 20) ** 2 + (z - 10) ** 2 <= 100).astype(np.uint8)
nib.save(nib.Nifti1Image(data, affine), sys.argv[1])
PY
check_rc $? "nibabel wrote the label map"
cat >"$WORK/ball.geo" <<'GEO'
SetFactory("OpenCASCADE");
Sphere(1) = {30, 20, 10, 9};
Mesh.MeshSizeFromPoints = 0;
GEO
gmsh "$WORK/ball.geo" -3 -format msh41 -clmax 3 -nt 1 -v 1 -o "$WORK/ball.msh" >/dev/null 2>&1
check_rc $? "gmsh meshed the template ball in the same world"

run() { local name=$1; shift; "$BIN" run --template "$WORK/ball.msh" --target-image "$WORK/label.nii.gz" \
    --clamp-ball 30,20,10,6 --max-iter 1 "$@" -o "$WORK/$name" >/dev/null 2>"$WORK/$name.err"; }

run lps
grep -q "^shapematch: warning: image-frame: .*give --image-space ras" "$WORK/lps.err" &&
    [ "$(jq '[.warnings[] | select(.code == "image-frame")] | length' "$WORK/lps/summary.json")" = 1 ]
check_rc $? "read as LPS: image-frame, naming --image-space ras" "$(head -c 600 "$WORK/lps.err")"

run lps_align --align rigid
grep -q "image-frame: .*give --image-space ras (params image_space); --align aligns onto the mirrored label$" "$WORK/lps_align.err"
check_rc $? "with --align: the warning says the alignment would mirror it" \
    "$(head -c 600 "$WORK/lps_align.err")"

run ras --image-space ras
[ -s "$WORK/ras/summary.json" ] && ! grep -q "image-frame" "$WORK/ras.err" &&
    [ "$(jq '[.warnings[] | select(.code == "image-frame")] | length' "$WORK/ras/summary.json")" = 0 ]
check_rc $? "--image-space ras: no image-frame warning" "$(head -c 600 "$WORK/ras.err")"
