#!/usr/bin/env bash
# A 256^3 label map to a signed distance on the generated background, the
# whole command (`shapematch sdf --image`: read, select, smooth, EDT,
# surface, background, distance, write), and on the image's own grid
# (`sdf --image -o OUT.nii`, what ITK's filter computes) against ITK's
# SignedMaurerDistanceMapImageFilter (build/release/itk_maurer, built by
# `make bench` against Debian's libinsighttoolkit5-dev) and scipy's
# distance_transform_edt on the same array (both signs, as ours), each
# ratio in the same run.  Issue 23's goals: <= 1.5 s on the project's
# 2-core machine, peak memory <= 3x the image as float32; issue 35's:
# within 1.5x of ITK's time (ours being the more accurate: exact within a
# band of the surface, ITK's the voxel-centre distance).
# The label: an ellipsoid of semi-axes 100, 80, 60 voxels (1 x 1 x 1.5 mm)
# written as NRRD (gzip) by a row-wise generator (no numpy needed).
set -euo pipefail
cd "$(dirname "$0")/.."
BIN=${SM_BIN:-build/release}
N=${IMAGE_BENCH_N:-256}
W=$(mktemp -d "${TMPDIR:-/tmp}/sm-image-bench.XXXXXX")
trap 'rm -rf "$W"' EXIT
PY=/usr/bin/python3 # Debian's, with python3-numpy and python3-scipy
[ -x "$PY" ] || PY=python3
"$PY" - "$W/label.nrrd" "$N" <<'PY'
import gzip, math, sys
path, n = sys.argv[1], int(sys.argv[2])
a, b, c = 100 * n / 256, 80 * n / 256, 60 * n / 256 / 1.5   # in voxels
rows = []
for k in range(n):
    for j in range(n):
        q = 1 - ((j - n / 2 + 0.3) / b) ** 2 - ((k - n / 2 + 0.2) / c) ** 2
        if q <= 0:
            rows.append(bytes(n))
            continue
        h = a * math.sqrt(q)
        lo = max(0, math.ceil(n / 2 - 0.1 - h))
        hi = min(n, math.floor(n / 2 - 0.1 + h) + 1)
        rows.append(bytes(lo) + b'\x01' * (hi - lo) + bytes(n - hi))
data = b''.join(rows)
with open(path, 'wb') as f:
    f.write(('NRRD0004\ntype: uchar\ndimension: 3\nspace: left-posterior-superior\n'
             'sizes: %d %d %d\nspace directions: (1,0,0) (0,1,0) (0,0,1.5)\n'
             'endian: little\nencoding: gzip\nspace origin: (0,0,0)\n\n' % (n, n, n)).encode())
    f.write(gzip.compress(data, 1))
print('label: %d voxels of %d^3' % (sum(r.count(1) for r in rows), n))
PY
echo "== label map ${N}^3 -> signed distance (goal: <= 1.5 s, peak <= 3x the image as float32 = $((N * N * N * 12 / 1048576)) MB) =="
/usr/bin/time -f "shapematch sdf --image (whole command): %e s wall, %U s user, peak %M KB" \
    "$BIN/shapematch" sdf --image "$W/label.nrrd" -o "$W/out" 2>&1 | sed 's/^/  /'
OMP_NUM_THREADS=1 /usr/bin/time -f "  the same on one thread: %e s wall" \
    "$BIN/shapematch" sdf --image "$W/label.nrrd" -o "$W/out1" 2>&1 | tail -1
echo "== on the image's grid, against ITK's SignedMaurerDistanceMap (goal: within 1.5x) =="
# the label uncompressed for both (ITK's NRRD reader and ours read the same bytes)
"$PY" - "$W/label.nrrd" "$W/raw.nrrd" <<'PY'
import gzip, sys
raw = open(sys.argv[1], 'rb').read()
head, data = raw.split(b'\n\n', 1)
open(sys.argv[2], 'wb').write(head.replace(b'encoding: gzip', b'encoding: raw') + b'\n\n' +
                              gzip.decompress(data))
PY
best() { # the best wall seconds of 3 runs of CMD...
    local b="" t0 t1
    for _ in 1 2 3; do
        t0=$(date +%s.%N)
        "$@" >/dev/null 2>&1 || { echo "failed: $*" >&2; return 1; }
        t1=$(date +%s.%N)
        b=$(awk -v a="$t0" -v z="$t1" -v b="$b" 'BEGIN { t = z - a; print (b == "" || t < b) ? t : b }')
    done
    echo "$b"
}
ours=$(best "$BIN/shapematch" sdf --image "$W/raw.nrrd" -o "$W/ours.nii")
echo "  shapematch sdf --image -o OUT.nii (whole command, best of 3): $ours s (load $(cut -d' ' -f1-3 /proc/loadavg))"
if [ -x "$BIN/itk_maurer" ]; then
    itk=$(best "$BIN/itk_maurer" "$W/raw.nrrd" "$W/itk.nrrd")
    filter=$("$BIN/itk_maurer" "$W/raw.nrrd")
    awk -v o="$ours" -v i="$itk" -v f="$filter" 'BEGIN {
      printf("  ITK SignedMaurerDistanceMap (read, filter, write; best of 3): %.2f s (the filter alone %.2f s)\n", i, f)
      printf("  ratio ours/ITK: %.2f (goal <= 1.5)\n", o / i) }'
else
    echo "  (no build/release/itk_maurer: make bench builds it with Debian's libinsighttoolkit5-dev)"
fi
if "$PY" -c 'import scipy.ndimage' 2>/dev/null; then
    "$PY" - "$W/label.nrrd" "$N" <<'PY'
import gzip, sys, time
import numpy as np
from scipy import ndimage
raw = open(sys.argv[1], 'rb').read()
n = int(sys.argv[2])
m = np.frombuffer(gzip.decompress(raw.split(b'\n\n', 1)[1]), 'u1').reshape(n, n, n) != 0
t = time.perf_counter()
d = np.where(m, -ndimage.distance_transform_edt(m, sampling=(1.5, 1, 1)),
             ndimage.distance_transform_edt(~m, sampling=(1.5, 1, 1)))
print('  scipy distance_transform_edt, both signs, whole %d^3 grid: %.2f s' % (n, time.perf_counter() - t))
PY
else
    echo "  (python3-scipy not installed: no scipy figure; make deps installs it)"
fi
