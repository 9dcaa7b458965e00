#!/usr/bin/env bash
# `shapematch sdf --image` end to end on label maps made at test time by
# tests/cli/image_shapes.py (a sphere and an ellipsoid rasterised on an
# oblique, anisotropic grid, written as NIfTI-1/-2, NRRD and MetaImage in
# their variants): every format gives the same distances; a RAS-space
# NRRD the same as its LPS twin; --image-space ras the mirrored frame;
# the distance near the boundary against the exact sphere beats the
# voxel-centre EDT's by half; the EDT against scipy's when scipy is
# installed; a template matched onto the image's target; bad inputs and
# options fail with the documented exit codes.
source "$(dirname "$0")/../lib/cli.sh"
check_rc() { if [ "$1" = 0 ]; then ok "$2"; else not_ok "$2" "${3:-}"; fi; }
SHAPES="$ROOT/tests/cli/image_shapes.py"
# Debian's python3, where python3-numpy and python3-scipy are installed
# (a python3 earlier on the PATH may lack them)
PY=/usr/bin/python3
[ -x "$PY" ] || PY=python3

"$PY" "$SHAPES" write "$WORK" sphere >/dev/null
check_rc $? "image_shapes.py wrote the sphere in every format"

sdf() { # name [options...]: sdf of WORK/name into WORK/out-name.d (a directory: -o x.nii would be an image)
    local f=$1
    shift
    "$BIN" sdf --image "$WORK/$f" -o "$WORK/out-$f.d" "$@" >/dev/null 2>"$WORK/$f.err"
}

sdf s1.nii --edt-out "$WORK/edt-lps.nrrd"
check_rc $? "sdf --image NIfTI-1 (sform)" "$(head -c 400 "$WORK/s1.nii.err")"
grep -q "every nonzero voxel: 1921 voxels, 1 component(s), world box (LPS)" "$WORK/s1.nii.err"
check_rc $? "the summary names the voxels, components and world box" "$(cat "$WORK/s1.nii.err")"

# every other encoding of the same array in the same place: same bits
for f in s1.nii.gz s2.nii raw.nrrd gz.nrrd ras.nrrd be16.nrrd det.nhdr raw.mha z.mha det.mhd; do
    sdf "$f" && cmp -s "$WORK/out-$f.d/background.sol" "$WORK/out-s1.nii.d/background.sol" &&
        cmp -s "$WORK/out-$f.d/background.mesh" "$WORK/out-s1.nii.d/background.mesh"
    check_rc $? "$f gives the same background and distances as s1.nii" "$(head -c 300 "$WORK/$f.err")"
done
# the qform's rotation comes from a float32 quaternion: equal to rounding
sdf q1.nii && "$PY" "$SHAPES" solcmp "$WORK/out-q1.nii.d/background.sol" \
    "$WORK/out-s1.nii.d/background.sol" 1e-3 >"$WORK/q1.cmp" 2>&1
check_rc $? "NIfTI qform agrees with the sform" "$(cat "$WORK/q1.cmp" "$WORK/q1.nii.err")"
# a float image is a level set of its values (no smoothing): as --smooth 0
sdf f32.mha && "$BIN" sdf --image "$WORK/s1.nii" --smooth 0 -o "$WORK/s0" 2>/dev/null &&
    cmp -s "$WORK/out-f32.mha.d/background.sol" "$WORK/s0/background.sol"
check_rc $? "float32 MetaImage at level 0.5 equals the mask unsmoothed"

# accuracy near the boundary (|d| < 2 voxels) against the exact sphere,
# and the voxel-centre EDT's on the same band: at most half of it
edt_rms=$("$PY" "$SHAPES" edt "$WORK/edt-lps.nrrd" sphere | tail -1)
"$PY" "$SHAPES" check "$WORK" sphere lps "$WORK/out-s1.nii.d/background.mesh" \
    "$WORK/out-s1.nii.d/background.sol" "$("$PY" -c "print($edt_rms / 2)")" >"$WORK/acc" 2>&1
check_rc $? "distance near the sphere: rms at most half the voxel-centre EDT's ($edt_rms)" \
    "$(cat "$WORK/acc")"
echo "# $(cat "$WORK/acc"); voxel-centre EDT rms $edt_rms"

# end to end: a ball of radius 8.5 (gmsh) matched onto the image's sphere
# of radius 10; boundary RMS against the exact sphere at most half the
# voxel-centre EDT's
cat >"$WORK/ball.geo" <<'GEO'
SetFactory("OpenCASCADE");
Sphere(1) = {4, 39, 9, 8.5};
Mesh.MeshSizeFromPoints = 0;
GEO
gmsh "$WORK/ball.geo" -3 -format msh41 -clmax 2.5 -nt 1 -v 1 -o "$WORK/ball.msh" >/dev/null 2>&1
"$BIN" run --template "$WORK/ball.msh" --target-mesh "$WORK/out-s1.nii.d/background.mesh" \
    --target-sol "$WORK/out-s1.nii.d/background.sol" --clamp-ball 4,39,9,4.5 --max-iter 100 --quiet \
    -o "$WORK/run" >/dev/null 2>"$WORK/run.err"
rc=$?
[ $rc = 10 ] && rc=0 # not converged still writes the result
"$PY" - "$WORK/run/result.mesh" "$edt_rms" >"$WORK/e2e" 2>&1 <<'PY'
import math, sys
tok = open(sys.argv[1]).read().split()
i = tok.index('Vertices')
x = [[float(tok[i + 2 + 4 * v + c]) for c in range(3)] for v in range(int(tok[i + 1]))]
j = tok.index('Triangles')
b = {int(tok[j + 2 + 4 * t + c]) - 1 for t in range(int(tok[j + 1])) for c in range(3)}
e = [math.dist(x[v], (4, 39, 9)) - 10 for v in b]
rms = math.sqrt(sum(v * v for v in e) / len(e))
print('boundary rms %.4f max %.4f over %d vertices' % (rms, max(map(abs, e)), len(e)))
sys.exit(0 if rms <= float(sys.argv[2]) / 2 else 1)
PY
check_rc $((rc | $?)) "a ball matched onto the image: boundary rms at most half the EDT's" \
    "rc $rc: $(cat "$WORK/e2e") $(head -c 300 "$WORK/run.err")"
echo "# end to end: $(cat "$WORK/e2e")"

# --image-space ras: the same distances in the mirrored frame
sdf s1.nii --image-space ras --edt-out "$WORK/edt-ras.nrrd"
"$PY" "$SHAPES" check "$WORK" sphere ras "$WORK/out-s1.nii.d/background.mesh" \
    "$WORK/out-s1.nii.d/background.sol" 0.3 >"$WORK/ras" 2>&1
check_rc $? "--image-space ras: the distance of the sphere mirrored in x and y" "$(cat "$WORK/ras")"
"$PY" "$SHAPES" check "$WORK" sphere lps "$WORK/out-s1.nii.d/background.mesh" \
    "$WORK/out-s1.nii.d/background.sol" 0.3 >/dev/null 2>&1
check_rc $((!$?)) "--image-space ras output is not the LPS sphere (the flip matters)"
"$PY" - "$WORK/edt-lps.nrrd" "$WORK/edt-ras.nrrd" >"$WORK/flip" 2>&1 <<'PY'
import sys
sys.path.insert(0, __import__('os').environ.get('SHAPES_DIR', '.'))
def read(p):
    raw = open(p, 'rb').read()
    head, data = raw.split(b'\n\n', 1)
    h = dict(l.split(': ', 1) for l in head.decode().split('\n')[1:])
    dirs = [[float(t) for t in v.strip('()').split(',')] for v in h['space directions'].split()]
    org = [float(t) for t in h['space origin'].strip('()').split(',')]
    return h['space'], dirs, org, data
sa, da, oa, va = read(sys.argv[1])
sb, db, ob, vb = read(sys.argv[2])
assert (sa, sb) == ('left-posterior-superior', 'right-anterior-superior'), (sa, sb)
f = [-1, -1, 1]
assert all(db[c][r] == f[r] * da[c][r] for c in range(3) for r in range(3)), (da, db)
assert all(ob[r] == f[r] * oa[r] for r in range(3)), (oa, ob)
assert va == vb
print('ok')
PY
check_rc $? "--edt-out: RAS grid = LPS grid with x, y negated, same values" "$(cat "$WORK/flip")"

# the signed EDT (of the unsmoothed mask) against brute force on a sample
# of voxels, and against scipy's distance_transform_edt on all of them
"$BIN" sdf --image "$WORK/raw.nrrd" --smooth 0 -o "$WORK/s0b" --edt-out "$WORK/edt0.nrrd" 2>/dev/null
"$PY" "$SHAPES" edtbrute "$WORK/edt0.nrrd" "$WORK/raw.nrrd" >"$WORK/brute" 2>&1
check_rc $? "signed EDT equals brute force on sampled voxels" "$(cat "$WORK/brute")"
echo "# $(cat "$WORK/brute")"
if "$PY" -c 'import scipy.ndimage' 2>/dev/null; then
    "$PY" - "$WORK/edt0.nrrd" "$WORK/raw.nrrd" >"$WORK/scipy" 2>&1 <<'PY'
import sys
import numpy as np
from scipy import ndimage
def nrrd(p):
    raw = open(p, 'rb').read()
    head, data = raw.split(b'\n\n', 1)
    h = dict(l.split(': ', 1) for l in head.decode().split('\n')[1:] if ': ' in l)
    n = [int(t) for t in h['sizes'].split()]
    dirs = np.array([[float(t) for t in v.strip('()').split(',')] for v in h['space directions'].split()])
    org = np.array([float(t) for t in h['space origin'].strip('()').split(',')])
    return n, h, dirs, org, data
n, h, dirs, org, data = nrrd(sys.argv[1])
edt = np.frombuffer(data, '<f4').reshape(n[::-1])
n0, h0, dirs0, org0, data0 = nrrd(sys.argv[2])
img = np.frombuffer(data0, 'u1').reshape(n0[::-1])
# the crop's first voxel in the image's indices
off = np.linalg.solve(dirs0.T, org - org0)
o = np.rint(off).astype(int)
mask = np.zeros(n[::-1], bool)
src = [slice(max(0, o[a]), min(n0[a], o[a] + n[a])) for a in (2, 1, 0)]
dst = [slice(s.start - o[a], s.stop - o[a]) for s, a in zip(src, (2, 1, 0))]
mask[tuple(dst)] = img[tuple(src)] != 0
sp = [np.linalg.norm(dirs[a]) for a in (2, 1, 0)]
want = np.where(mask, -ndimage.distance_transform_edt(mask, sampling=sp),
                ndimage.distance_transform_edt(~mask, sampling=sp))
err = np.abs(edt - want).max()
print('max difference from scipy %.3g over %d voxels' % (err, edt.size))
sys.exit(0 if err < 1e-4 else 1)
PY
    check_rc $? "signed EDT equals scipy's distance_transform_edt" "$(cat "$WORK/scipy")"
else
    skip "signed EDT equals scipy's distance_transform_edt" "python3-scipy not installed"
fi

# an ellipsoid: several labels, the label chosen
"$PY" "$SHAPES" write "$WORK" ellipsoid >/dev/null
"$BIN" sdf --image "$WORK/raw.nrrd" --label 1 -o "$WORK/ell" 2>"$WORK/ell.err" >/dev/null
check_rc $? "sdf --label 1 on the ellipsoid" "$(cat "$WORK/ell.err")"

# errors: empty label, bad options, a detached file outside the folder
"$BIN" sdf --image "$WORK/raw.nrrd" --label 7 -o "$WORK/no" >/dev/null 2>"$WORK/e1"
rc=$?
[ $rc = 2 ] && grep -q "label-empty" "$WORK/e1"
check_rc $? "an empty label is an input error (exit 2)" "rc $rc: $(cat "$WORK/e1")"
"$BIN" sdf --image "$WORK/raw.nrrd" --image-space xyz -o "$WORK/no" >/dev/null 2>&1
check_rc $(($? != 1)) "--image-space other than lps/ras is a usage error (exit 1)"
sed 's|data file: det.raw.gz|data file: ../etc/passwd|' "$WORK/det.nhdr" >"$WORK/up.nhdr"
"$BIN" sdf --image "$WORK/up.nhdr" -o "$WORK/no" >/dev/null 2>"$WORK/e2"
rc=$?
[ $rc = 2 ] && grep -q "without '..'" "$WORK/e2"
check_rc $? "a detached data file outside the header's folder is refused" "rc $rc: $(cat "$WORK/e2")"
"$PY" -c 'import sys; v = bytearray(512); v[292] = 1
sys.stdout.buffer.write(b"NRRD0004\ntype: uint8\ndimension: 3\nsizes: 8 8 8\nencoding: raw\n\n" + v)' \
    >"$WORK/one.nrrd"
"$BIN" sdf --image "$WORK/one.nrrd" -o "$WORK/no" >/dev/null 2>"$WORK/e4"
rc=$?
[ $rc = 2 ] && grep -q "vanished under the smoothing" "$WORK/e4" &&
    "$BIN" sdf --image "$WORK/one.nrrd" --smooth 0 -o "$WORK/one" >/dev/null 2>&1
check_rc $? "a one-voxel label: smoothed away (exit 2, says so), kept with --smooth 0" \
    "rc $rc: $(cat "$WORK/e4")"
head -c 400 "$WORK/s1.nii" >"$WORK/cut.nii"
"$BIN" sdf --image "$WORK/cut.nii" -o "$WORK/no" >/dev/null 2>"$WORK/e3"
rc=$?
[ $rc = 2 ] && grep -q "cut.nii: byte" "$WORK/e3"
check_rc $? "a truncated NIfTI names the byte (exit 2)" "rc $rc: $(cat "$WORK/e3")"


# detached data files (issue 37): only a regular file in the header's
# folder, reached through no symbolic link; the voxels allocated only
# once the data is known to hold them.  Before: the FIFO hung forever, the
# symbolic links were followed (the image outside was read), the 32 GiB
# declarations reached malloc (release: "out of memory", ASan: abort).
mkdir -p "$WORK/det" "$WORK/det2" "$WORK/outside"
"$PY" -c 'import sys; v = bytearray(512); v[292] = 1; sys.stdout.buffer.write(v)' >"$WORK/outside/x.raw"
mhd() { # FILE DATA-NAME: an 8 x 8 x 8 uint8 MetaImage header naming DATA-NAME
    printf 'ObjectType = Image\nNDims = 3\nDimSize = 8 8 8\nElementType = MET_UCHAR\nElementDataFile = %s\n' "$2" >"$1"
}
refused() { # DESC MESSAGE HEADER: sdf fails with exit 2 and MESSAGE, within 20 s
    local rc
    timeout 20 "$BIN" sdf --image "$3" --smooth 0 -o "$WORK/no" >/dev/null 2>"$WORK/e5"
    rc=$?
    [ $rc = 2 ] && grep -q "$2" "$WORK/e5"
    check_rc $? "$1 (exit 2, '$2')" "rc $rc: $(head -c 400 "$WORK/e5")"
}
cp "$WORK/outside/x.raw" "$WORK/det/plain.raw"
mhd "$WORK/det/plain.mhd" plain.raw
"$BIN" sdf --image "$WORK/det/plain.mhd" --smooth 0 -o "$WORK/det-out" >/dev/null 2>"$WORK/e5"
check_rc $? "a detached data file beside its header is read" "$(cat "$WORK/e5")"
mkfifo "$WORK/det/fifo.raw"
mhd "$WORK/det/fifo.mhd" fifo.raw
refused "a FIFO named as the data file is refused at once" "is not a regular file" "$WORK/det/fifo.mhd"
ln -s ../outside/x.raw "$WORK/det/link.raw"
mhd "$WORK/det/link.mhd" link.raw
refused "a symbolic link beside the header to a file outside is refused" "is a symbolic link" "$WORK/det/link.mhd"
ln -s /dev/zero "$WORK/det/zero.raw"
mhd "$WORK/det/zero.mhd" zero.raw
refused "a symbolic link to a device is refused" "is a symbolic link" "$WORK/det/zero.mhd"
ln -s ../outside "$WORK/det2/sub"
mhd "$WORK/det2/sub.mhd" sub/x.raw
refused "a data file under a symbolic link to a folder outside is refused" "passes through a symbolic link" "$WORK/det2/sub.mhd"
mkdir "$WORK/det/dir.raw"
mhd "$WORK/det/dir.mhd" dir.raw
refused "a folder named as the data file is refused" "is not a regular file" "$WORK/det/dir.mhd"
# 2048 x 2048 x 1024 float64 = 32 GiB declared over 10 bytes: refused from
# the file's size, nothing allocated (raw, gzip, attached and detached)
hdr32() { printf 'NRRD0004\ntype: double\ndimension: 3\nsizes: 2048 2048 1024\nencoding: %s\n%s\n' "$1" "$2"; }
{ hdr32 raw ""; printf 0123456789; } >"$WORK/big.nrrd"
{ hdr32 gzip ""; printf 0123456789; } >"$WORK/bigz.nrrd"
hdr32 raw "data file: big.raw" >"$WORK/det/big.nhdr"
printf 0123456789 >"$WORK/det/big.raw"
refused "a 32 GiB raw declaration over 10 bytes" "voxels need 34359738368 (truncated?)" "$WORK/big.nrrd"
refused "a 32 GiB gzip declaration over 10 bytes" "inflate to at most 10320 bytes" "$WORK/bigz.nrrd"
refused "a 32 GiB declaration over a 10-byte data file" "voxels need 34359738368 (truncated?)" "$WORK/det/big.nhdr"
