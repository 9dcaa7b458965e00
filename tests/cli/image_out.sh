#!/usr/bin/env bash
# `shapematch sdf --image -o OUT.nii.gz|.nii|.nrrd|.mha`: the signed
# distance on the image's own grid, with its geometry, checked
# independently (tests/cli/image_out_check.py: nibabel reads the NIfTI,
# the NRRD and MetaImage headers parsed in Python, the values against the
# exact sphere of image_shapes.py, better than half the voxel-centre
# EDT's error near the surface); the summary's world box is the box of
# the label's voxel centres (numpy), not of the index box's corners.
source "$(dirname "$0")/../lib/cli.sh"
check_rc() { if [ "$1" = 0 ]; then ok "$2"; else not_ok "$2" "${3:-}"; fi; }
PY=/usr/bin/python3
[ -x "$PY" ] || PY=python3
CHECK="$ROOT/tests/cli/image_out_check.py"

"$PY" "$ROOT/tests/cli/image_shapes.py" write "$WORK" sphere >/dev/null
check_rc $? "image_shapes.py wrote the oblique, anisotropic sphere"

"$BIN" sdf --image "$WORK/s1.nii" -o "$WORK/d.nii.gz" 2>"$WORK/nii.err"
check_rc $? "sdf --image -o d.nii.gz" "$(cat "$WORK/nii.err")"
"$BIN" sdf --image "$WORK/s1.nii" -o "$WORK/dir" --edt-out "$WORK/edt.nrrd" 2>/dev/null
"$PY" "$CHECK" nifti "$WORK/s1.nii" "$WORK/d.nii.gz" "$WORK/edt.nrrd" >"$WORK/acc" 2>&1
check_rc $? "nibabel: the image's affine and qform; the distance near the sphere at most half \
the voxel-centre EDT's error, within a voxel everywhere" "$(cat "$WORK/acc")"
echo "# $(cat "$WORK/acc")"

for f in d.nrrd d.mha d.nii; do
    "$BIN" sdf --image "$WORK/s1.nii" -o "$WORK/$f" 2>"$WORK/$f.err"
    check_rc $? "sdf --image -o $f" "$(cat "$WORK/$f.err")"
done
for f in d.nrrd d.mha; do
    "$PY" "$CHECK" same "$WORK/d.nii.gz" "$WORK/$f" >"$WORK/$f.same" 2>&1
    check_rc $? "$f: the same geometry and float32 values as the NIfTI" "$(cat "$WORK/$f.same")"
done
cmp -s <(gzip -dc "$WORK/d.nii.gz") "$WORK/d.nii"
check_rc $? ".nii.gz is the .nii gzipped"
# each written image reads back through our own readers (a float image:
# the voxels >= level, here the outside, a shape with a boundary)
for f in d.nrrd d.mha d.nii.gz; do
    "$BIN" sdf --image "$WORK/$f" --level 0 -o "$WORK/back-$f" >/dev/null 2>"$WORK/back.err" &&
        grep -q "34 x 30 x 22 float32, spacing 1 x 1.25 x 1.75" "$WORK/back.err"
    check_rc $? "$f reads back as a 34 x 30 x 22 float32 image" "$(cat "$WORK/back.err")"
done

# --image-space ras: distances are lengths, the file keeps its own frame
"$BIN" sdf --image "$WORK/s1.nii" --image-space ras -o "$WORK/ras.nrrd" 2>/dev/null &&
    "$PY" - "$WORK/d.nrrd" "$WORK/ras.nrrd" <<'PYEOF'
import sys
a, b = (open(p, 'rb').read().split(b'\n\n', 1) for p in sys.argv[1:])
import numpy as np
assert a[0] == b[0], 'headers differ'
x, y = np.frombuffer(a[1], '<f4'), np.frombuffer(b[1], '<f4')
assert np.max(np.abs(x - y)) < 1e-4, np.max(np.abs(x - y))
PYEOF
check_rc $? "--image-space ras writes the same geometry and distances"

# the world box of the label's voxel centres
"$PY" "$CHECK" box "$WORK/s1.nii" "$WORK/nii.err" >"$WORK/box" 2>&1
check_rc $? "the printed world box is the box of the label's voxel centres (numpy)" "$(cat "$WORK/box")"

# refusals
"$BIN" sdf --image "$WORK/s1.nii" -o "$WORK/x.nii.gz" --edt-out "$WORK/e.nrrd" 2>"$WORK/e1"
rc=$?
[ "$rc" = 1 ] && grep -q -- "--edt-out goes with -o DIR" "$WORK/e1"
check_rc $? "--edt-out with -o an image is a usage error (exit 1)" "rc $rc: $(cat "$WORK/e1")"
"$BIN" sdf --image "$WORK/s1.nii" --label 7 -o "$WORK/x.nii.gz" 2>"$WORK/e2"
rc=$?
[ "$rc" = 2 ] && grep -q "label-empty" "$WORK/e2" && [ ! -e "$WORK/x.nii.gz" ]
check_rc $? "an empty label: exit 2, label-empty, no file" "rc $rc: $(cat "$WORK/e2")"
"$BIN" sdf --image "$WORK/s1.nii" -o "$WORK/no/such/dir/x.nii" 2>"$WORK/e3"
rc=$?
[ "$rc" = 4 ] && grep -q "x.nii" "$WORK/e3"
check_rc $? "an unwritable output: exit 4 naming it" "rc $rc: $(cat "$WORK/e3")"
exit $((failed > 0))
