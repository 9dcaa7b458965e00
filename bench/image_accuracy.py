#!/usr/bin/env python3
"""bench/image_sdf.sh's accuracy table: each signed distance on the 256^3
ellipsoid label's grid against the exact distance to the ellipsoid the
label was rasterised from (semi-axes 100, 80, 60 mm about the generator's
centre; the closest point by Newton's method on the Lagrange multiplier,
converged to rounding), in three regions: within one largest spacing of
the surface (1.5 mm), within three (4.5 mm), and the whole grid.

    image_accuracy.py N LABEL.nrrd OURS.nii [ITK.nrrd]

Also times scipy's distance_transform_edt (both signs, the voxel-centre
distance) on the same mask and scores it.  Needs Debian's python3-numpy
(and python3-scipy for the scipy row)."""
import gzip
import sys
import time

import numpy as np


def read(path, n):
    raw = open(path, 'rb').read()
    if path.endswith('.nii'):
        off = int(np.frombuffer(raw[108:112], '<f4')[0])
        return np.frombuffer(raw[off:], '<f4').reshape(n, n, n)
    head, data = raw.split(b'\n\n', 1)
    if b'encoding: gzip' in head:
        data = gzip.decompress(data)
    return np.frombuffer(data, head_type(head)).reshape(n, n, n)


def head_type(head):
    return '<f4' if b'type: float' in head else 'u1'


def exact_ellipsoid(n):
    """Signed distance (negative inside) at every voxel centre, [k, j, i]."""
    e = np.array([100.0, 80.0, 60.0]) * n / 256
    c = np.array([n / 2 - 0.1, n / 2 - 0.3, (n / 2 - 0.2) * 1.5])
    out = np.empty((n, n, n))
    i = np.arange(n)
    for k in range(n):
        jj, ii = np.meshgrid(i, i, indexing='ij')
        y = np.abs(np.stack([ii - c[0], jj - c[1], np.full(ii.shape, k * 1.5 - c[2])], -1))
        inside = ((y / e) ** 2).sum(-1) <= 1
        # F(t) = sum (e y / (t + e^2))^2 - 1 decreases, convex, on t > -e_min^2;
        # Newton from the left of its root (F >= 0 there) rises to it
        t = np.maximum((e * y).max(-1) - e.max() ** 2, e[2] * y[..., 2] - e[2] ** 2)
        for _ in range(60):
            q = e * y / (t[..., None] + e ** 2)
            f = (q ** 2).sum(-1) - 1
            df = -2 * (q ** 2 / (t[..., None] + e ** 2)).sum(-1)
            step = f / df
            t = t - step
            if np.all(np.abs(step) <= 1e-12 * (1 + np.abs(t))):
                break
        x = e ** 2 * y / (t[..., None] + e ** 2)
        d = np.linalg.norm(x - y, axis=-1)
        out[k] = np.where(inside, -d, d)
    return out


def score(name, d, exact):
    row = []
    for lim in (1.5, 4.5, np.inf):
        m = np.abs(exact) <= lim
        err = d[m].astype(float) - exact[m]
        row.append('%.3f / %.3f' % (np.sqrt(np.mean(err ** 2)), np.abs(err).max()))
    print('  %-34s %-16s %-16s %-16s' % (name, *row))


def main():
    n = int(sys.argv[1])
    raw = open(sys.argv[2], 'rb').read()
    mask = np.frombuffer(gzip.decompress(raw.split(b'\n\n', 1)[1]), 'u1').reshape(n, n, n) != 0
    t0 = time.perf_counter()
    exact = exact_ellipsoid(n)
    print('== accuracy against the exact ellipsoid (rms / max error, mm; computed in %.0f s) =='
          % (time.perf_counter() - t0))
    print('  %-34s %-16s %-16s %-16s' % ('', '|d| <= 1.5 mm', '|d| <= 4.5 mm', 'whole grid'))
    score('ours (sdf --image -o OUT.nii)', read(sys.argv[3], n), exact)
    if len(sys.argv) > 4:
        score('ITK SignedMaurerDistanceMap', read(sys.argv[4], n), exact)
    try:
        from scipy import ndimage
    except ImportError:
        print('  (python3-scipy not installed: no scipy row)')
        return
    t0 = time.perf_counter()
    d = np.where(mask, -ndimage.distance_transform_edt(mask, sampling=(1.5, 1, 1)),
                 ndimage.distance_transform_edt(~mask, sampling=(1.5, 1, 1)))
    took = time.perf_counter() - t0
    score('scipy distance_transform_edt', d, exact)
    print('  scipy distance_transform_edt, both signs, whole %d^3 grid: %.2f s' % (n, took))


if __name__ == '__main__':
    main()
