#!/usr/bin/env bash
# Truly 2D label maps as the target of a 2D template (issue 38 item 2):
# a disk of radius 0.32 rasterised on an oblique, anisotropic 2D grid
# (tests/cli/image2d.py) as NIfTI-1 with dim[0] = 2, NRRD dimension 2
# and MetaImage NDims 2.  `run --target-image` moves the 2D example's
# disk of radius 0.25 onto it: its boundary within half the largest
# spacing of the exact circle (RMS within a quarter), the three formats
# giving the same result bit for bit; summary.json names the image; a
# 3D image for a 2D template and a 2D image for a 3D template are
# refused with messages naming what was found.
source "$(dirname "$0")/../lib/cli.sh"
check_rc() { if [ "$1" = 0 ]; then ok "$2"; else not_ok "$2" "${3:-}"; fi; }
PY=/usr/bin/python3
[ -x "$PY" ] || PY=python3
IMG="$ROOT/tests/cli/image2d.py"
export OMP_NUM_THREADS=1

"$PY" "$IMG" write "$WORK" >/dev/null
check_rc $? "image2d.py wrote the disk as 2D NIfTI, NRRD and MetaImage"

RUN=(--template "$ROOT/examples/2d/template.mesh" --clamp-ball 0.5,0.5,0.04 --quiet)
for f in disk.nii disk.nrrd disk.mha; do
    "$BIN" run "${RUN[@]}" --target-image "$WORK/$f" -o "$WORK/run_$f" >/dev/null 2>"$WORK/err"
    check_rc $? "run --target-image $f (2D)" "$(cat "$WORK/err")"
done
grep -q "target image .*disk.nii: NIfTI-1, 66 x 52 x 1 uint8" "$WORK/err" ||
    grep -q "target image .*disk.mha: MetaImage, 66 x 52 x 1 uint8" "$WORK/err"
check_rc $? "stderr has the image summary" "$(cat "$WORK/err")"
grep -q "label-touches-border" "$WORK/err"
check_rc $(( $? == 0 ? 1 : 0 )) "a disk inside the image does not touch its border" "$(cat "$WORK/err")"
read -r emax erms < <("$PY" "$IMG" radius "$WORK/run_disk.nii/result.mesh")
"$PY" -c "import sys; sys.exit(0 if $emax <= 0.0234375 / 2 and $erms <= 0.0234375 / 4 else 1)"
check_rc $? "the result's boundary is on the circle of radius 0.32 (max $emax, RMS $erms; spacing 0.0234)"
for f in disk.nrrd disk.mha; do
    cmp -s "$WORK/run_disk.nii/result.mesh" "$WORK/run_$f/result.mesh"
    check_rc $? "$f gives disk.nii's result bit for bit"
done
"$PY" - "$WORK/run_disk.nii/summary.json" <<'PY'
import json, sys
s = json.load(open(sys.argv[1]))
t = s["target_image"]
assert t["format"] == "NIfTI-1" and t["dims"] == [66, 52, 1], t
assert t["voxels"] > 800 and t["components"] == 1 and not t["touches_border"], t
assert s["inputs"]["target_image"].endswith("disk.nii") and "target_surface" not in s, s["inputs"]
PY
check_rc $? "summary.json names the 2D image and its label"

"$BIN" run "${RUN[@]}" --target-image "$WORK/disk3.nii" -o "$WORK/no" >/dev/null 2>"$WORK/err"
rc=$?
grep -q "disk3.nii: a 3D NIfTI-1 image (66 x 52 x 3 voxels): a 2D template needs a 2D image" "$WORK/err"
check_rc $(( rc == 2 && $? == 0 ? 0 : 1 )) "a 3D image for a 2D template: named, exit 2 (rc $rc)" "$(cat "$WORK/err")"
"$BIN" run --template "$ROOT/examples/3d/template.mesh" --clamp-ball 0.5,0.5,0.5,0.05 \
    --target-image "$WORK/disk.nrrd" -o "$WORK/no" >/dev/null 2>"$WORK/err"
rc=$?
grep -q "disk.nrrd: a 2D NRRD image (66 x 52 voxels): it is the target of a 2D template" "$WORK/err"
check_rc $(( rc == 2 && $? == 0 ? 0 : 1 )) "a 2D image for a 3D template: named, exit 2 (rc $rc)" "$(cat "$WORK/err")"

echo "1..$n"
[ "$failed" = 0 ]
